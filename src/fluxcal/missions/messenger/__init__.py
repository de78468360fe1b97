"""MESSENGER MAG: EDR -> CDR (MESSENGER MAG EDR-to-CDR Processing v2i) and its fits.

The mission on the contract (`fluxcal.missions.messenger.mission`); its piece of the
one-call API is `fluxcal.missions.messenger.api` (`fluxcal.calibrate`).  ``__all__``
lists the public modules; the command line, demos, simulators and forward models are
internal.
"""

__all__ = [
    "api",
    "archive_products",
    "calibration_data",
    "chain",
    "defects",
    "edr",
    "fit",
    "fit_passes",
    "identity",
    "levels",
    "mission",
    "options",
    "products",
    "readers",
    "routes",
]
