"""fluxcal: calibration of spacecraft fluxgate-magnetometer telemetry.

Turns raw magnetometer telemetry (ADC counts, clock ticks, heater bits, thermistor
voltages) into calibrated magnetic-field products in physical frames.  Implements the
MESSENGER MAG EDR-to-CDR procedure and the Rosetta RPC-MAG step-by-step calibration, and
IMAP MAG from raw packets.  One call: `calibrate` (any registered mission; its wrappers
`calibrate_messenger`, `calibrate_rosetta`, `calibrate_imap`) and `read_product`
(`fluxcal.api`).
"""

__all__ = ["__version__", "calibrate", "calibrate_imap", "calibrate_messenger",
           "calibrate_rosetta", "read_product"]

#: The one-call API (`fluxcal.api`), imported on first use: ``import fluxcal`` stays light.
_API = ("calibrate", "calibrate_imap", "calibrate_messenger", "calibrate_rosetta",
        "read_product")


def __getattr__(name: str) -> object:
    # ``__version__`` is looked up on first use (PEP 562): importing importlib.metadata
    # and scanning the installed distributions is not needed for ``fluxcal --help``.
    if name == "__version__":
        from fluxcal.version import software_version

        return software_version()
    if name in _API:
        from fluxcal import api

        return getattr(api, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    # the lazy names too: ``fluxcal.<TAB>`` completes the API (PEP 562)
    return sorted({*globals(), *__all__})
