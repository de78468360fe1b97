"""A whole simulated day (mostly 1 Hz with 20 Hz bursts) through the pipeline."""

import numpy as np

from fluxcal.geometry.kernels import KernelPool
from fluxcal.geometry.time import SclkKernel
from fluxcal.missions.messenger.calibration_data import load_calibration
from fluxcal.missions.messenger.chain import calibrate
from fluxcal.missions.messenger.simulate import SimulationConfig, simulate
from fluxcal.missions.messenger.synthetic_kernels import write_messenger_like_kernels


def test_full_day(tmp_path):
    cfg = SimulationConfig(
        start_utc="2013-03-01T00:00:00",
        duration_s=86400.0,
        rate_segments=[(0.0, 6), (0.10, 10), (0.11, 6), (0.40, 8), (0.42, 10), (0.43, 6),
                       (0.80, 9), (0.81, 6)],
        coarse_intervals=[(0.105, 0.108), (0.6, 0.61)],
    )
    mk = write_messenger_like_kernels(tmp_path, cfg.start_utc, 86400.0 + 3000.0,
                                      plus_y_sunward=[(30000.0, 40000.0)])
    cal = load_calibration(cfg.start_utc)
    with KernelPool(mk):
        sim = simulate(cfg, cal, SclkKernel.from_pool(-236))
        ds = calibrate(sim["science"], sim["heater"], sim["temperature"], cal)
    truth = sim["truth"]
    assert set(np.unique(ds["rate"].values)) == {6, 8, 9, 10}
    assert ds.attrs["duty_cycle_changes"] > 50  # 1000-s schedule over a day
    fine = truth["range"].values == 0
    err = ds["b_mso"].values - truth["b_mso"].values
    # issue 3 tolerances: fine 0.05 nT rms / 0.1 nT max per axis, coarse 1.6 nT max
    assert np.all(np.sqrt((err[fine] ** 2).mean(axis=0)) < 0.05)
    assert np.all(np.abs(err[fine]).max(axis=0) < 0.1)
    assert np.all(np.abs(err[~fine]).max(axis=0) < 1.6)
    assert set(np.unique(ds["quality"].values // 100)) == {1, 2}
