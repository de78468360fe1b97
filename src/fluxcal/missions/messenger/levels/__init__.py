"""MESSENGER MAG processing levels, each a function ``Dataset -> Dataset``.

One module per step of seed 000; the science dataset (dimension ``time``) produced by
`fluxcal.missions.messenger.readers` goes through, in order:

1. `correct_time` (sec. 5, 9; `levels.time`): per-sample net lag, MET -> ET, TT2000 epoch;
2. `correct_heater_signal` (sec. 6; `levels.heater`): periodic heater signal;
3. `correct_offsets` (sec. 7; `levels.offsets`): temperature and relaxed duty-cycle offsets;
4. `counts_to_field` (sec. 8; `levels.field`): eq. 8 with each sample's range matrix;
5. `add_geometry` (sec. 10, 11; `levels.frames`): frames and positions;
6. `assign_quality` (sec. 12; `levels.quality`);
7. `validate_offsets` (sec. 13; `levels.validation`).

Calibration constants (`MessengerCalibration`) and the SCLK conversion are arguments;
geometry steps need the kernels loaded by the caller (`fluxcal.geometry.kernels.KernelPool`).
This package re-exports every public name of its modules.

References
----------
.. [1] MESSENGER MAG EDR-to-CDR Processing v2i (Korth and Anderson, 2016), sec. 5-13.
"""

from fluxcal.missions.messenger.levels._common import (
    COMPONENT,
    SC_ID,
)
from fluxcal.missions.messenger.levels._common import _date_et as _date_et
from fluxcal.missions.messenger.levels.field import (
    counts_to_field,
)
from fluxcal.missions.messenger.levels.frames import (
    FRAMES,
    MBF_BUILTIN_NOTE,
    POSITION_VARIABLE,
    add_geometry,
    calibration_frames,
    frame_variables,
    mercury_orientation_is_builtin,
    note_mbf_rotation,
    position_frames,
    rtn_from_position,
    rtn_is_sun_pole_two_vector,
    sensor_frame,
    spherical_rtn,
)
from fluxcal.missions.messenger.levels.heater import (
    check_heater_coverage,
    correct_heater_signal,
    find_heater_periods,
)
from fluxcal.missions.messenger.levels.offsets import (
    TEMPERATURE_MARGIN_S,
    correct_offsets,
    correct_offsets_reference,
    interpolate_temperature,
    mark_sunlit,
    offset_model,
    offset_model_reference,
    sunlit_before_v10,
)
from fluxcal.missions.messenger.levels.quality import (
    assign_quality,
    quality_flags,
    quality_flags_reference,
)
from fluxcal.missions.messenger.levels.time import (
    aux_times_et,
    correct_time,
)
from fluxcal.missions.messenger.levels.validation import (
    GAP_SPACINGS,
    offset_step_report,
    validate_offsets,
)

__all__ = [
    "COMPONENT",
    "FRAMES",
    "GAP_SPACINGS",
    "MBF_BUILTIN_NOTE",
    "POSITION_VARIABLE",
    "SC_ID",
    "TEMPERATURE_MARGIN_S",
    "add_geometry",
    "assign_quality",
    "aux_times_et",
    "calibration_frames",
    "check_heater_coverage",
    "correct_heater_signal",
    "correct_offsets",
    "correct_offsets_reference",
    "correct_time",
    "counts_to_field",
    "find_heater_periods",
    "frame_variables",
    "interpolate_temperature",
    "mark_sunlit",
    "mercury_orientation_is_builtin",
    "note_mbf_rotation",
    "offset_model",
    "offset_model_reference",
    "offset_step_report",
    "position_frames",
    "quality_flags",
    "quality_flags_reference",
    "rtn_from_position",
    "rtn_is_sun_pole_two_vector",
    "sensor_frame",
    "spherical_rtn",
    "sunlit_before_v10",
    "validate_offsets",
]
