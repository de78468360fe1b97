"""Issue 34, item 2: a refusal never advises an option that then writes a table failing it.

The ``--error-goal`` a MESSENGER fit refusal advises (`fit_merit.advised_goal`, entry
24-advice) is the least goal at which the same tables, judged as ``fit_days`` judges that
goal (`fit.judged_at`), are written with the regulated temperature inside the range they
state.  Expected values here come from brute force over the constructed resamples, never
from the code under test.
"""

from __future__ import annotations

import dataclasses
import re

import numpy as np
import pytest

from fluxcal.errors import FitRefusedError
from fluxcal.missions.messenger.calibration_data import load_calibration
from fluxcal.missions.messenger.fit import judged_at
from fluxcal.missions.messenger.fit_merit import advised_goal, assess, check_merit
from fluxcal.missions.messenger.fit_variance import (
    MOMENT_EDGES_C,
    N_PARAMETERS,
    law_parameters,
    law_values,
    offset_moments,
)
from tests.missions.messenger.test_fit_variance import START, _variance_result

#: The regulated sensor temperature (C; sec. 7, eq. 2).
REGULATED_C = -50.0


@pytest.fixture(scope="module")
def shipped():
    return load_calibration(str(START))


def _goal_for(band_nt: float) -> float:
    """The least goal (0.01 nT steps) whose law band limit, half the goal, admits ``band_nt``
    (entry 23: the limit is 0.05 nT at the goal 0.1 nT)."""
    return float(np.ceil(round(band_nt * 2.0 * 100, 6)) / 100)


def test_the_band_refusal_advises_the_goal_that_states_the_regulated_temperature(shipped):
    # resampled laws pivoting about 0 C: intercepts scatter by 1.25 counts, slopes by
    # 0.0223 counts/C, so the band is least near 0 C (about 0.06 nT on z) and 0.08 nT
    # at -50 C.  The least goal admitting any bin (about 0.12 nT) would state the law
    # near 0 C only, without the regulated -50 C where the heater holds the sensor; the
    # advice is the goal whose half admits the -50..-49 C bin, and at it the table is
    # written with -50 C inside its range
    base = _variance_result(shipped, np.zeros(N_PARAMETERS))
    law = law_parameters(base.calibration)
    rng = np.random.default_rng(34)
    k = 4000
    b_law = np.repeat(law[None], k, axis=0)
    b_law[:, :, 0] += 1.25 * rng.standard_normal((k, 3))
    b_law[:, :, 1] += 0.0223 * rng.standard_normal((k, 3))
    rel = base.calibration.constants["relaxation"]
    boot = {"law": b_law, "d0": np.repeat(np.asarray(base.calibration.duty_cycle_d0)[None], k, 0),
            "tau": np.full(k, float(rel["tau_s"])), "dt": np.full(k, float(rel["delay_s"]))}
    temp = rng.uniform(-60.0, 40.0, 6000)
    zero = np.zeros(temp.size)
    base.variance.offset_moments = offset_moments(temp, zero, zero, zero)
    res = dataclasses.replace(base, bootstrap=boot, waveform_error=None)
    assess(res)
    # brute force: each 1-C bin's band (nT) at its samples' mean temperature, the
    # resamples' rms through Table 4's fine diagonal, the worst axis
    m_diag = np.abs(np.diag(np.asarray(res.calibration.matrices[0])))
    idx = np.searchsorted(MOMENT_EDGES_C, temp, side="right") - 1
    bins = np.unique(idx)
    t_mean = np.array([temp[idx == b].mean() for b in bins])
    spread = law_values(b_law, t_mean) - law_values(law, t_mean)[None]
    band = np.sqrt((spread ** 2).mean(axis=0)) * m_diag  # (bins, axes)
    guess = _goal_for(band.max(axis=1).min())
    regulated = _goal_for(band[MOMENT_EDGES_C[bins] == REGULATED_C].max())
    assert regulated > guess + 0.02  # the case this test is about
    assert not res.merit["law_determined"]
    # the least goal alone: the law stated near 0 C, without -50 C
    assert not judged_at(res, guess).stated_ranges.contains(REGULATED_C)
    with pytest.raises(FitRefusedError) as info:
        check_merit(res, rejudge=judged_at)
    msg = str(info.value)
    assert re.search(rf"--error-goal {regulated:g} \(the law's limit is 0\.5 of the goal; "
                     r"written into every table header; judged at", msg), msg
    goal, judged = advised_goal(res, guess, judged_at)
    assert goal == pytest.approx(regulated)
    assert judged.stated_ranges.contains(REGULATED_C)
    check_merit(judged)  # written at the advised goal
    # followed as the command line would (a fresh judgement at that goal): the same
    again = judged_at(res, regulated)
    assert again.stated_ranges == judged.stated_ranges
    np.testing.assert_allclose(again.merit["total_nt"], judged.merit["total_nt"])
    assert res.merit["goal_nt"] == pytest.approx(0.1)  # ``res`` itself is left as it was
    # without a re-judgement the refusal names its own numbers' goal (the old advice)
    with pytest.raises(FitRefusedError, match=rf"--error-goal {guess:g} \("):
        check_merit(res)
