"""Generic removal of spacecraft disturbances from magnetometer series.

Pure array functions (any magnetometer; arrays and parameters in, arrays out):

- `minimum_variance` (MVA: eigenvalues, eigenvectors, ratio),
- `remove_spectral_lines` (aliased reaction-wheel / fixed instrument lines),
- `remove_heater_steps`, `remove_labelled_offsets` (square-wave heater disturbances),
  `pool_heater_signs` (which level is heater-off, from several stretches),
  `states_from_steps`, `intervals_from_states` (heater states and labelled intervals
  from a strongly disturbed sensor: stage 1 of the assisted method),
- `two_sensor_pca` (external field versus sensor-local noise of two sensors),
- `resample_two_sensors` (two series onto a common time base, gap-aware linear
  interpolation; `common_time_base`, `interpolate_linear`).

The levels H-L of seed 003 built on them are in that mission's folder (``cleaning_levels``).

References
----------
.. [1] RO-IGEP-TR0028 (seed 003), sec. 4.9-4.13.
"""

from fluxcal.cleaning.heater_pooling import pool_heater_signs
from fluxcal.cleaning.heater_states import (
    HeaterStates,
    intervals_from_states,
    states_from_steps,
)
from fluxcal.cleaning.minimum_variance import MinimumVarianceResult, minimum_variance
from fluxcal.cleaning.pca import TwoSensorPCAResult, two_sensor_pca
from fluxcal.cleaning.resample import (
    TwoSensorResample,
    common_time_base,
    interpolate_linear,
    resample_two_sensors,
)
from fluxcal.cleaning.spectral_lines import (
    LineRemovalResult,
    default_bandwidth,
    fold_frequency,
    interpolated_lines,
    remove_spectral_lines,
)
from fluxcal.cleaning.steps import (
    LabelledOffsetResult,
    StepRemovalResult,
    heater_off_segments,
    moving_variance,
    remove_heater_steps,
    remove_labelled_offsets,
)

__all__ = [
    "HeaterStates",
    "LabelledOffsetResult",
    "LineRemovalResult",
    "MinimumVarianceResult",
    "StepRemovalResult",
    "TwoSensorPCAResult",
    "TwoSensorResample",
    "common_time_base",
    "default_bandwidth",
    "fold_frequency",
    "heater_off_segments",
    "pool_heater_signs",
    "interpolate_linear",
    "intervals_from_states",
    "interpolated_lines",
    "minimum_variance",
    "moving_variance",
    "remove_heater_steps",
    "remove_labelled_offsets",
    "remove_spectral_lines",
    "resample_two_sensors",
    "states_from_steps",
    "two_sensor_pca",
]
