"""Generic calibration building blocks: counts to nT, offsets, gains, timing, fits.

Pure functions on arrays and Datasets that name no mission; the missions compose them
(MESSENGER MAG EDR-to-CDR Processing v2i; RO-IGEP-TR0028, seed 003).  ``__all__`` lists
the public modules (the API reference documents those).
"""

__all__ = [
    "averaging",
    "binned_stats",
    "constrained_fits",
    "counts",
    "gain_matrix",
    "heater_error",
    "heater_signal",
    "matrices",
    "mirror_mode_offsets",
    "offset_steps",
    "offsets",
    "rate_latency",
    "relaxation",
    "segment_trends",
    "solar_wind_offsets",
    "stated_ranges",
    "step_scan",
    "store",
    "thermal",
    "timeshift",
    "variance_offsets",
]
