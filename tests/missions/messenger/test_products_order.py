"""Products in time order (issue 10 item 2), day splitting, averages, UTC columns.

Expected values come from constructed cases (a fast -> slow rate switch with Table 1-like
lags written out by hand, duplicate epochs tagged by their input index), brute-force
loops, cdflib's TT2000 breakdown, and the SCLK forward conversion.
"""

from collections import Counter

import cdflib
import numpy as np
import pytest
import xarray as xr

from fluxcal.geometry.kernels import KernelPool
from fluxcal.missions.messenger import products

NS = 1_000_000_000


@pytest.fixture(autouse=True)
def _lsk():
    with KernelPool([]):  # the package's generic LSK for UTC fields
        yield

T0 = 391_780_867_184_000_000  # a TT2000 in 2012


def _day(epoch: np.ndarray, extra_frames=("mso",)) -> xr.Dataset:
    """A calibrated-day-like dataset whose values encode the input index."""
    n = epoch.size
    idx = np.arange(n, dtype=float)
    data = {
        "et": ("time", epoch.astype(float) * 1e-9),
        "met_corrected": ("time", 1e8 + idx),
        "quality": ("time", np.full(n, 100)),
        "pos_mso": (("time", "component"), np.stack([idx, -idx, 2 * idx], axis=1)),
    }
    for f in extra_frames:
        data[f"b_{f}"] = (("time", "component"), np.stack([idx, idx + 0.5, -idx], axis=1))
    return xr.Dataset(data, coords={"epoch": ("time", epoch)})


def test_fast_to_slow_switch_is_sorted_and_counted():
    # 20 Hz with a net lag of 0.05 s, then 1 Hz with a net lag of 1.683 s (the slow
    # setting's lag is larger, so its first corrected times fall before the last fast ones)
    rec_fast = T0 + np.arange(200) * 50_000_000
    rec_slow = rec_fast[-1] + NS + np.arange(10) * NS
    epoch = np.concatenate([rec_fast - 50_000_000, rec_slow - 1_683_000_000])
    ordered, report = products.order_day(_day(epoch), ["mso"])
    out = ordered["epoch"].values
    assert (np.diff(out) > 0).all()
    # brute force: samples earlier than the latest epoch before them
    latest, moved = epoch[0], 0
    for t in epoch[1:]:
        moved += t < latest
        latest = max(latest, t)
    assert report.reordered == moved > 0
    assert report.duplicates == 0 and report.samples == epoch.size
    # every variable travels with its epoch: the input index of each output row
    index = ordered["met_corrected"].values - 1e8
    np.testing.assert_array_equal(epoch[index.astype(int)], out)
    np.testing.assert_array_equal(ordered["b_mso"].values[:, 0], index)
    np.testing.assert_array_equal(ordered["pos_mso"].values[:, 1], -index)


def test_duplicates_keep_the_first_and_are_counted():
    epoch = T0 + np.array([0, 50, 100, 100, 150, 150, 150, 120], dtype=np.int64) * 1_000_000
    ordered, report = products.order_day(_day(epoch), ["mso"])
    assert report.duplicates == 3 and report.reordered == 1
    np.testing.assert_array_equal(ordered["epoch"].values - T0,
                                  np.array([0, 50, 100, 120, 150]) * 1_000_000)
    # the first sample recorded at each epoch is kept (input indices 2 and 4)
    np.testing.assert_array_equal(ordered["met_corrected"].values - 1e8, [0, 1, 2, 7, 4])
    assert report.label_keywords() == {"FLUXCAL_REORDERED_SAMPLES": 1,
                                       "FLUXCAL_DUPLICATES_DROPPED": 3}


def test_in_order_day_is_not_copied():
    epoch = T0 + np.arange(100, dtype=np.int64) * 50_000_000
    day = _day(epoch)
    ordered, report = products.order_day(day, ["mso"])
    assert report.reordered == report.duplicates == 0
    assert np.shares_memory(ordered["b_mso"].values, day["b_mso"].values)


def test_duplicates_are_logged(caplog):
    epoch = T0 + np.array([0, 0, 1], dtype=np.int64)
    day = _day(epoch).assign(et_recorded=("time", np.full(3, 3.9e8)))
    with caplog.at_level("WARNING"):
        products.order_day(day, ["mso"])
    assert "1 duplicate epoch" in caplog.text


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_average_std_at_40000_nT(sign):
    """b_std is two-pass: 0.01 nT spread on 40,000 nT (issue 10: was 1.4 % off)."""
    rng = np.random.default_rng(3)
    n = 1200 * 5
    epoch = T0 + np.arange(n, dtype=np.int64) * 50_000_000
    b = sign * 40_000.0 + rng.uniform(-0.01, 0.01, size=(n, 3))
    prod = xr.Dataset(
        {"b": (("time", "b_component"), b), "quality": ("time", np.full(n, 100)),
         "latitude": ("time", np.zeros(n)),
         "azimuth": ("time", np.where(np.arange(n) % 2, 179.999, -179.999))},
        coords={"epoch": ("time", epoch)})
    avg = products.average(prod, 60, T0)
    exact = b.astype(np.longdouble).reshape(-1, 1200, 3)
    ref = np.sqrt(((exact - exact.mean(axis=1, keepdims=True)) ** 2).mean(axis=1))
    # ~1e-12 nT absolute rounding of the deviations against a 0.006 nT standard deviation
    np.testing.assert_allclose(avg["b_std"].values, ref.astype(float), rtol=1e-9)
    assert (avg["count"].values == 1200).all()
    # the centre is exact; the azimuth is averaged across the +-180 deg wrap, not to 0
    np.testing.assert_array_equal(avg["epoch"].values, T0 + np.arange(5) * 60 * NS + 30 * NS)
    np.testing.assert_allclose(np.abs(avg["azimuth"].values), 180.0, atol=1e-9)


@pytest.mark.parametrize("chunk", [None, 7])  # 7: many chunk boundaries, a short last one
def test_utc_columns_against_cdflib_breakdown(monkeypatch, chunk):
    if chunk is not None:
        monkeypatch.setattr(products, "UTC_CHUNK", chunk)
    rng = np.random.default_rng(5)
    # 2004-2015 including the leap seconds of 2005-12-31, 2008-12-31, 2012-06-30
    epoch = rng.integers(150_000_000 * NS, 480_000_000 * NS, size=2000)
    leaps = [cdflib.cdfepoch.compute_tt2000([y, m, d, 23, 59, 59, 999, 999, 999])
             for y, m, d in ((2005, 12, 31), (2008, 12, 31), (2012, 6, 30))]
    epoch = np.concatenate([epoch, np.array(leaps, dtype=np.int64) + 1,
                            np.array(leaps, dtype=np.int64) - 1]).astype(np.int64)
    cols = products.utc_columns(epoch)
    ref = np.array(cdflib.cdfepoch.breakdown_tt2000(epoch))  # y m d H M S ms us ns
    np.testing.assert_array_equal(cols["year"].values, ref[:, 0])
    doy = (np.array([np.datetime64(f"{y:04d}-{m:02d}-{d:02d}") for y, m, d in ref[:, :3]])
           - np.array([np.datetime64(f"{y:04d}-01-01") for y in ref[:, 0]])).astype(int) + 1
    np.testing.assert_array_equal(cols["doy"].values, doy)
    np.testing.assert_array_equal(cols["hour"].values, ref[:, 3])
    np.testing.assert_array_equal(cols["minute"].values, ref[:, 4])
    # printed SS.sss: seconds and truncated milliseconds
    text = np.char.mod("%06.3f", cols["second"].values)
    expect = np.char.add(np.char.add(np.char.zfill(ref[:, 5].astype(str), 2), "."),
                         np.char.zfill(ref[:, 6].astype(str), 3))
    np.testing.assert_array_equal(text, expect)


def test_product_names():
    assert products.product_name("mbf", "11095", 8) == "MAGMBFSCI11095_V08"
    assert products.product_name("mso", "11095", 1, 5) == "MAGMSOSCIAVG11095_05_V01"
    with pytest.raises(ValueError):
        products.product_name("mso", "11095", 100)


def test_split_days_at_utc_midnight_of_the_recorded_time():
    from fluxcal.errors import InputFormatError
    from fluxcal.geometry.time import utc_to_et

    utc = ["2012-06-01T23:59:59.90", "2012-06-01T23:59:59.95", "2012-06-02T00:00:00.00",
           "2012-06-02T12:00:00", "2012-06-04T00:00:01"]
    et = utc_to_et(np.array(utc))
    day = xr.Dataset({"et_recorded": ("time", et), "et": ("time", et - 0.2)},
                     coords={"epoch": ("time", np.arange(5, dtype=np.int64))})
    days = products.split_days(day)
    # a day without samples (06-03) gives no dataset; the corrected time does not decide
    assert [d.sizes["time"] for d in days] == [2, 2, 1]
    assert [products.day_code(d)[2] for d in days] == ["12153", "12154", "12156"]
    with pytest.raises(InputFormatError):
        products.split_days(day.isel(time=[1, 0]))


def test_computed_frame_is_reordered_in_place_like_a_copy():
    """A frame computed for its product is put in time order in its own array (no copy)."""
    epoch = T0 + np.array([0, 50, 100, 100, 150, 150, 150, 120], dtype=np.int64) * 1_000_000
    index, _ = products.time_order(epoch)
    rng = np.random.default_rng(3)
    values = rng.normal(size=(epoch.size, 3))
    expected = values[index]  # numpy fancy indexing: the independent reference
    var = xr.Variable(("time", "component"), values.copy())
    got = products._reorder_owned(var, index, np.empty(epoch.size))
    np.testing.assert_array_equal(got.values, expected)
    assert np.shares_memory(got.values, var.values) and got.values.flags.c_contiguous
    scalar = xr.Variable(("time",), values[:, 0].copy())
    np.testing.assert_array_equal(
        products._reorder_owned(scalar, index, np.empty(epoch.size)).values, expected[:, 0])


@pytest.mark.parametrize("quality", [np.array([222, 100, 100, 0, 212], dtype=np.int16),
                                     np.array([110.0, 110.0, 211.0])])
def test_quality_keywords_count_each_flag(quality):
    # reference: a Python count (the float input takes the code's own np.unique path)
    count = Counter(quality.tolist())
    flags = sorted(count)
    kw = products._quality_keywords(quality)
    assert kw == {"DATA_QUALITY_ID": [f"{int(q):03d}" for q in flags],
                  "FLUXCAL_QUALITY_SAMPLES": [count[q] for q in flags]}
