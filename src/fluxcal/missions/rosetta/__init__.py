"""Rosetta RPC-MAG: LEVEL_A..L, disturbance removal and in-flight fits (RO-IGEP-TR0028).

The mission on the contract (`fluxcal.missions.rosetta.mission`); its piece of the
one-call API is `fluxcal.missions.rosetta.api` (`fluxcal.calibrate`).  ``__all__`` lists
the public modules; the command line, demos, simulators and forward models are internal.
"""

__all__ = [
    "api",
    "archive",
    "archive_products",
    "averaged",
    "calib",
    "cleaning_levels",
    "day_edges",
    "extended_model",
    "fit",
    "hk",
    "identity",
    "io",
    "level_a",
    "level_b",
    "level_c",
    "mission",
    "options",
    "products",
    "reaction_wheels",
    "routes",
]
