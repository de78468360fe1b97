"""LEVEL_K cleans the vectors of each mode, including those overlapping the mode before.

Forward model (issue 23, item 2): a heater square wave of 0.5-1.5 nT (15 s on / 15 s off)
on a red-noise background, sampled at 20 Hz in two filter modes whose time shifts differ
(sec. 4.2.3.5): the first 8.2 s of the second mode's vectors overlap the end of the first
mode's.  Before: those overlap vectors (and the stretch they cut) were left with the whole
step in them.
"""

import numpy as np

from fluxcal.missions.rosetta import cleaning_levels as cl
from tests.cleaning._synthetic import red_noise, rotating_field
from tests.cleaning.test_rosetta_cleaning import FS, START, _dataset, lsk  # noqa: F401

SHIFT_S = 8.2  # Normal-mode primary shift (s) against 0 for the next mode


def _two_modes(lsk, order, seed=7):  # noqa: F811
    from fluxcal.geometry.time import utc_to_tt2000

    rng = np.random.default_rng(seed)
    t0 = int(utc_to_tt2000(np.array([START]), lsk)[0])
    n1, n2 = 6300, 6000  # mode 2 starts at 315 s: its overlap lies in an on-phase
    t1 = np.arange(n1) / FS + SHIFT_S  # mode 1 stamps shifted by 8.2 s
    t2 = n1 / FS + np.arange(n2) / FS  # mode 2 starts at the next stamp, no shift
    t = np.concatenate([t1, t2])
    sid = np.concatenate([np.full(n1, 2), np.full(n2, 3)])
    bg = rotating_field(t, period=3600.0) + red_noise(t.size, FS, 1e-3, rng, floor=1e-5)
    levels = rng.uniform(0.5, 1.5, int(t.max() // 30) + 2)
    sq = np.where((t % 30) >= 15, levels[(t // 30).astype(int)], 0.0)
    d = np.array([1.0, 2.0, -1.0]) / np.sqrt(6)
    k = np.argsort(t, kind="stable") if order == "time" else np.arange(t.size)
    epoch = t0 + np.round(t[k] * 1e9).astype(np.int64)
    ds = _dataset(epoch, (bg + sq[:, None] * d)[k], sid=sid[k], level="B")
    overlap = (sid[k] == 3) & (t[k] < t1[-1])
    return ds, bg[k], overlap


def test_overlap_vectors_are_cleaned(lsk):  # noqa: F811
    # products are in time order (the level functions require it): the overlap interleaves
    ds, bg, overlap = _two_modes(lsk, "time")
    assert overlap.sum() == int(SHIFT_S * FS) - 1
    out = cl.level_k(ds)
    err = np.linalg.norm(out["b"].values - bg, axis=1)
    assert out.attrs["heater_unchanged_vectors"] == 0
    assert np.sqrt(np.mean(err[overlap] ** 2)) < 0.1
    assert np.sqrt(np.mean(err**2)) < 0.1
