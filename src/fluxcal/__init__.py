"""fluxcal: calibration of spacecraft fluxgate-magnetometer telemetry.

Turns raw magnetometer telemetry (ADC counts, clock ticks, heater bits, thermistor
voltages) into calibrated magnetic-field products in physical frames.  Implements the
MESSENGER MAG EDR-to-CDR procedure and the Rosetta RPC-MAG step-by-step calibration.
"""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("fluxcal")
except PackageNotFoundError:  # pragma: no cover - running from a source tree
    __version__ = "0.0.0+unknown"

__all__ = ["__version__"]
