"""MESSENGER levels, step 2: heater periods, duty-cycle changes and signal (seed 000 sec. 6).

References
----------
.. [1] MESSENGER MAG EDR-to-CDR Processing v2i (Korth and Anderson, 2016), sec. 6, 7.
"""

from __future__ import annotations

import xarray as xr

from fluxcal.calibration.heater_signal import HeaterPeriods, heater_periods, heater_signal
from fluxcal.calibration.relaxation import (
    DutyCycleChanges,
    duty_cycle_changes,
)
from fluxcal.errors import InputFormatError
from fluxcal.geometry.time import SclkKernel
from fluxcal.missions.messenger.calibration_data import MessengerCalibration
from fluxcal.missions.messenger.levels._common import (
    _date_et,
    _scalar,
    _vector,
)
from fluxcal.missions.messenger.levels.time import aux_times_et


def find_heater_periods(
    heater: xr.Dataset, cal: MessengerCalibration, sclk: SclkKernel
) -> tuple[HeaterPeriods, DutyCycleChanges]:
    """Heater periods and duty-cycle changes (on the ET scale) from the heater stream.

    A heater stream that starts inside heater operation (less than one heater period of
    data before the first rising edge) gives a first change at ``-inf``: that duty cycle
    is taken as steady before the data (`fluxcal.missions.messenger.chain.calibrate`
    warns when that enters a science sample).  A last period cut inside
    its on-phase by the end of the stream keeps the previous period's duty cycle.

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 6, 7.
    """
    t = aux_times_et(heater, sclk)
    h = cal.constants["heater"]
    periods = heater_periods(t, heater["heater"].values, period=h["period_s"], min_on=h["min_on_s"])
    changes = duty_cycle_changes(periods, period=h["period_s"], data_end=float(t[-1]) + 1.0,
                                 data_start=float(t[0]),
                                 evaluation_periods=int(h["evaluation_periods"]))
    return periods, changes


def check_heater_coverage(
    ds: xr.Dataset, heater: xr.Dataset, cal: MessengerCalibration, sclk: SclkKernel
) -> None:
    """Require the heater stream to cover the V10 science samples (within one period).

    Raises
    ------
    InputFormatError
        When V10 samples (heater modelled) lie before the first or after the last heater
        record by more than one heater period.
    """
    et = ds["et"].values
    v10 = et >= _date_et(cal, "heater_mode_v10")
    if not v10.any():
        return
    t = aux_times_et(heater, sclk)
    period = cal.constants["heater"]["period_s"]
    first, last = et[v10].min(), et[v10].max()
    if t.size == 0 or first < t[0] - period or last > t[-1] + period:
        span = f"[{t[0]:.1f}, {t[-1]:.1f}]" if t.size else "empty"
        raise InputFormatError(
            f"the heater stream (ET {span}) does not cover the science samples "
            f"(ET [{first:.1f}, {last:.1f}]) within one heater period; give the heater "
            "files of the whole interval (and of the previous day for the look-back)",
            path=heater.attrs.get("inputs"), field="met",
        )


def correct_heater_signal(
    ds: xr.Dataset, periods: HeaterPeriods, cal: MessengerCalibration
) -> xr.Dataset:
    """Compute the periodic heater signal (fine-range counts) at every sample (sec. 6).

    The signal is applied only from MAG FSW V10 (2007-03-09) on, in heater periods whose
    bit stayed on >= 10 s; it is subtracted in `correct_offsets`.

    Returns
    -------
    xarray.Dataset
        With ``heater_signal`` (counts, fine range) and ``heater_applied`` (bool).

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 6, Appendix Tables 6-8.
    """
    signal, applied = heater_signal(ds["et"].values, periods, cal.heater_signal,
                                    cal.heater_duty_bins_percent,
                                    applies_from=_date_et(cal, "heater_mode_v10"))
    return ds.assign(
        heater_signal=_vector(signal, "counts", "heater signal, fine-range counts (sec. 6)"),
        heater_applied=_scalar(applied, "1", "heater signal subtracted"),
    )
