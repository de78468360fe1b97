"""Rosetta wiring of the cleaning blocks: levels H, I, J, K, L, the wheel reader, the CLI.

(Kept under tests/cleaning/ because the cleaning issue owns it; it exercises
``fluxcal.missions.rosetta.cleaning_levels``, ``reaction_wheels`` and ``clean_cli``.)
"""

from pathlib import Path

import numpy as np
import pytest
import typer
import xarray as xr
from typer.testing import CliRunner

from fluxcal.cleaning.pca import two_sensor_pca
from fluxcal.errors import FluxcalError, InputFormatError
from fluxcal.geometry.kernels import KernelPool
from fluxcal.geometry.time import leapseconds, utc_to_tt2000
from fluxcal.missions.rosetta import cleaning_levels as cl
from fluxcal.missions.rosetta.clean_cli import clean, clean_files, read_intervals
from fluxcal.missions.rosetta.reaction_wheels import ReactionWheelTable, read_reaction_wheels
from fluxcal.products import read_fluxcal_product
from tests.cleaning._synthetic import red_noise, rotating_field

FS = 20.0
START = "2014-08-01T00:00:00"


@pytest.fixture(scope="module")
def lsk():
    with KernelPool():
        yield leapseconds()


def _dataset(epoch, b, *, sid=None, level="C", sensor="OB"):
    n = epoch.size
    data = {
        "b": (("time", "component"), b, {"units": "nT"}),
        "quality": ("time", np.zeros(n, np.int16), {"units": "1"}),
        "obt": ("time", 3.6e8 + (epoch - epoch[0]) / 1e9, {"units": "s"}),
        "temperature": ("time", np.full(n, 290.0), {"units": "K"}),
    }
    if level in ("C", "G", "H", "I", "L"):
        data["position"] = (
            ("time", "component"),
            np.tile([1e8, 2e7, 1e6], (n, 1)),
            {"units": "km"},
        )
    if sid is not None:
        data["sid"] = ("time", sid.astype(np.int16), {"units": "1"})
    return xr.Dataset(
        data,
        coords={"epoch": ("time", epoch, {"units": "ns"}), "component": ["x", "y", "z"]},
        attrs={"level": level, "sensor": sensor},
    )


def _wheel_case(lsk, n=24000, seed=0):
    """20 Hz field with two drifting wheel lines and a LAP line; a 1 Hz mode at the end."""
    rng = np.random.default_rng(seed)
    t0 = int(utc_to_tt2000(np.array([START]), lsk)[0])
    t = np.arange(n) / FS
    bg = rotating_field(t) + red_noise(n, FS, 1e-3, rng, floor=1e-5)
    tab_t = np.arange(-32.0, t[-1] + 64, 16.0)
    rates = np.column_stack(
        [23.7 + 0.05 * np.sin(tab_t / 300), 31.2 + 0.04 * np.cos(tab_t / 200)]
        + [np.full(tab_t.size, np.nan)] * 2  # wheels 3 and 4: rate unknown
    )
    phase = [2 * np.pi * np.cumsum(np.interp(t, tab_t, rates[:, j])) / FS for j in range(2)] + [
        2 * np.pi * 2.5 * t
    ]
    lines = np.stack([np.cos(p) for p in phase], axis=1) @ np.array(
        [[0.6, 0.5, 0.62], [0.3, -0.8, 0.5], [0.0, 0.7, -0.7]]
    )
    # a 1 Hz stretch (other mode) after a gap
    t_slow = t[-1] + 60 + np.arange(600) * 1.0
    epoch = t0 + np.round(np.concatenate([t, t_slow]) * 1e9).astype(np.int64)
    b = np.concatenate([bg + lines, rotating_field(t_slow)])
    sid = np.concatenate([np.full(n, 2), np.full(600, 7)])
    table = ReactionWheelTable(epoch=t0 + np.round(tab_t * 1e9).astype(np.int64), frequencies=rates)
    return _dataset(epoch, b, sid=sid), bg, phase, table, tab_t, rates, t0


def test_level_h_removes_wheel_and_lap_lines(lsk):
    ds, bg, phase, table, *_ = _wheel_case(lsk)
    out = cl.level_h(ds, table, [2.5])
    n = bg.shape[0]
    y = out["b"].values[:n]
    for p in phase:
        z = np.exp(-1j * p)
        a_in = 2 * np.abs(np.mean(ds["b"].values[:n] * z[:, None], axis=0))
        a_out = 2 * np.abs(np.mean(y * z[:, None], axis=0))
        # >= 20 dB drop of the coherent line amplitude (issue 5); measured ~ 50 dB
        assert np.linalg.norm(a_out) < 0.1 * np.linalg.norm(a_in)
    assert np.sqrt(np.mean((y - bg) ** 2)) < 0.05
    # the 1 Hz mode is passed through unchanged with a note
    np.testing.assert_array_equal(out["b"].values[n:], ds["b"].values[n:])
    assert "sid 7" in out.attrs["line_removal_notes"]
    assert "passed through unchanged" in out.attrs["line_removal_notes"]
    assert out.attrs["level"] == "H" and out["b"].attrs["units"] == "nT"
    # reproducible
    np.testing.assert_array_equal(cl.level_h(ds, table, [2.5])["b"].values, out["b"].values)


def test_level_h_without_lines_is_identity(lsk):
    ds, *_ = _wheel_case(lsk, n=3000)
    out = cl.level_h(ds, None, [])
    np.testing.assert_array_equal(out["b"].values, ds["b"].values)
    assert "unchanged" in out.attrs["line_removal_notes"]


def test_level_i_is_one_second_mean(lsk):
    ds, *_ = _wheel_case(lsk, n=2000)
    out = cl.level_i(ds.isel(time=slice(0, 2000)), lsk=lsk)
    # 100 s at 20 Hz starting on a whole second -> 100 averages of 20 vectors each
    assert out.sizes["time"] == 100 and out.attrs["level"] == "I"
    np.testing.assert_allclose(out["b"].values[3], ds["b"].values[60:80].mean(axis=0))
    assert np.all(out["n_samples"].values == 20)


def _heater_case(lsk, n=12000, seed=3, sign=1.0):
    rng = np.random.default_rng(seed)
    t0 = int(utc_to_tt2000(np.array([START]), lsk)[0])
    t = np.arange(n) / FS
    bg = rotating_field(t, period=3600.0) + red_noise(n, FS, 1e-3, rng, floor=1e-5)
    levels = rng.uniform(0.5, 1.5, int(t[-1] // 30) + 2)
    sq = np.where((t % 30) >= 15, levels[(t // 30).astype(int)], 0.0)
    d = sign * np.array([1.0, 2.0, -1.0]) / np.sqrt(6)
    epoch = t0 + np.round(t * 1e9).astype(np.int64)
    return _dataset(epoch, bg + sq[:, None] * d, level="B"), bg, sq, d


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_level_k_automatic(lsk, sign):
    # sign -1: the heater field against the positive maximum-variance axis; before
    # issue 11 the output was biased by the heater field there (1.1-1.2 nT)
    ds, bg, sq, d = _heater_case(lsk, sign=sign)
    out = cl.level_k(ds)
    assert abs(np.mean((out["b"].values - bg) @ d)) < 0.1
    assert "sign" in out.attrs["heater_off_rules"][0]
    assert out.attrs["level"] == "K"
    assert out.attrs["heater_jumps"] == np.count_nonzero(np.diff(sq))
    residual = np.linalg.norm(out["b"].values - bg, axis=1)
    assert np.sqrt(np.mean(residual**2)) < 0.1
    np.testing.assert_allclose(
        out["heater_disturbance"].values, ds["b"].values - out["b"].values, atol=1e-12
    )


def _labelled_heater_case(lsk, n=36000, seed=4):
    """Heater 'on' for 15 s of every 30 s; each on-interval is labelled A or B+C, and
    each label has one fixed offset vector (the seed's method 2: offset per heater set)."""
    rng = np.random.default_rng(seed)
    t0 = int(utc_to_tt2000(np.array([START]), lsk)[0])
    t = np.arange(n) / FS
    bg = rotating_field(t, period=3600.0) + red_noise(n, FS, 1e-3, rng, floor=1e-5)
    offsets = {"A": np.array([0.7, -0.5, 0.4]), "B+C": np.array([-0.3, 0.9, 1.1])}
    epoch = t0 + np.round(t * 1e9).astype(np.int64)
    x = bg.copy()
    intervals = []
    for k, start in enumerate(np.arange(15.0, t[-1] - 15.0, 30.0)):
        label = "B+C" if k % 3 == 0 else "A"
        i0, i1 = int(round(start * FS)), int(round((start + 15.0) * FS))
        intervals.append((int(epoch[i0]), int(epoch[i1]), label))
        x[i0:i1] += offsets[label]
    return _dataset(epoch, x, level="B"), bg, intervals, offsets


def test_level_k_assisted(lsk):
    ds, bg, intervals, offsets = _labelled_heater_case(lsk)
    # known offsets (e.g. from ROMAP classification): the injected signal is removed exactly
    out = cl.level_k_assisted(ds, intervals, offsets)
    np.testing.assert_allclose(out["b"].values, bg, atol=1e-12)
    assert out.attrs["level"] == "K" and out.attrs["heater_intervals"] == len(intervals)
    # offsets estimated from the data: each label's offset is the median over its
    # intervals of (inside mean - mean of 20 reference samples on each side).  Its error
    # is set by the background's wander, computed here from the background alone: the
    # median of m such errors scatters by ~1.25 std / sqrt(m); allow 4 of those
    est = cl.level_k_assisted(ds, intervals)
    assert set(est.attrs["heater_offsets_nT"]) == set(offsets)
    epoch = ds["epoch"].values
    for label, true in offsets.items():
        wander = []
        for a, b, lab in intervals:
            if lab == label:
                i0, i1 = np.searchsorted(epoch, [a, b])
                ref = 0.5 * (bg[i0 - 20 : i0].mean(axis=0) + bg[i1 : i1 + 20].mean(axis=0))
                wander.append(bg[i0 + 1 : i1 - 1].mean(axis=0) - ref)
        bound = 4 * 1.25 * np.std(wander, axis=0) / np.sqrt(len(wander))
        error = np.abs(np.asarray(est.attrs["heater_offsets_nT"][label]) - true)
        assert np.all(error < bound), (label, error, bound)
    residual = np.linalg.norm(est["b"].values - bg, axis=1)
    assert np.sqrt(np.mean(residual**2)) < 0.1  # issue 5: residual < 0.1 nT rms
    np.testing.assert_allclose(
        est["heater_disturbance"].values, ds["b"].values - est["b"].values, atol=1e-12
    )


def test_level_j_three_parts(lsk):
    rng = np.random.default_rng(9)
    t0 = int(utc_to_tt2000(np.array([START]), lsk)[0])
    n = 20000
    epoch = t0 + np.arange(n, dtype=np.int64) * 1_000_000_000 + 500_000_000
    ext = rotating_field(np.arange(n), magnitude=5.0, period=1e6) + rng.normal(size=(n, 3))
    ob = _dataset(epoch, ext + 0.1 * rng.normal(size=(n, 3)), level="G", sensor="OB")
    ib = _dataset(epoch[5:], (ext + 0.4 * rng.normal(size=(n, 3)))[5:], level="G", sensor="IB")
    parts = cl.level_j(ob, ib)
    assert set(parts) == {"EXT", "OB", "IB"}
    assert all(p.sizes["time"] == n - 5 for p in parts.values())
    np.testing.assert_allclose(
        parts["EXT"]["b"].values + parts["IB"]["b"].values, ib["b"].values, atol=1e-9
    )
    psi = np.asarray(parts["EXT"].attrs["pca_noise_variance_nT2"]).reshape(3, 2)
    np.testing.assert_allclose(psi[:, 0], 0.01, atol=0.004)  # 0.1 nT at OB
    np.testing.assert_allclose(psi[:, 1], 0.16, atol=0.01)  # 0.4 nT at IB
    with pytest.raises(InputFormatError, match="common"):
        cl.level_j(ob.isel(time=slice(0, 10)), ib.isel(time=slice(100, 110)))


def test_level_j_identical_tags_is_the_pca_of_the_samples(lsk):
    rng = np.random.default_rng(10)
    t0 = int(utc_to_tt2000(np.array([START]), lsk)[0])
    epoch = t0 + np.arange(3000, dtype=np.int64) * 1_000_000_000 + 500_000_000
    ext = rotating_field(np.arange(3000), magnitude=5.0, period=1e5)
    ob = _dataset(epoch, ext + 0.1 * rng.normal(size=(3000, 3)), level="G", sensor="OB")
    ib = _dataset(epoch, ext + 0.4 * rng.normal(size=(3000, 3)), level="G", sensor="IB")
    parts = cl.level_j(ob, ib)
    ref = two_sensor_pca(ob["b"].values, ib["b"].values)  # the former tag matching
    np.testing.assert_array_equal(parts["EXT"]["b"].values, ref.external)
    np.testing.assert_array_equal(parts["IB"]["b"].values, ref.uncorrelated_b)
    assert parts["EXT"].attrs["pca_interpolated_vectors"] == [0, 0]
    assert parts["EXT"].attrs["pca_dropped_vectors"] == 0


def test_level_j_resamples_shifted_ib_and_drops_gaps(lsk):
    """IB tagged half a second after OB, with a 10 s gap: interpolated, gap dropped."""
    rng = np.random.default_rng(11)
    t0 = int(utc_to_tt2000(np.array([START]), lsk)[0])
    n = 20000
    k = np.arange(n, dtype=float)  # (float: rotating_field's constant z is full_like)
    epoch_ob = t0 + np.arange(n, dtype=np.int64) * 1_000_000_000
    epoch_ib = epoch_ob + 500_000_000
    # a field slow enough that its interpolation error (<= h^2/8 max|B''| = 2e-6 nT
    # for the 5 nT, 2e4 s rotation) is negligible against the 0.1/0.4 nT disturbances
    ext_ob = rotating_field(k, magnitude=5.0, period=2e4)
    ext_ib = rotating_field(k + 0.5, magnitude=5.0, period=2e4)
    noise_ob, noise_ib = 0.1 * rng.normal(size=(n, 3)), 0.4 * rng.normal(size=(n, 3))
    keep = np.ones(n, bool)
    keep[1000:1010] = False  # IB gap 999.5 s -> 1010.5 s
    ob = _dataset(epoch_ob, ext_ob + noise_ob, level="G", sensor="OB")
    ib = _dataset(epoch_ib[keep], (ext_ib + noise_ib)[keep], level="G", sensor="IB")
    parts = cl.level_j(ob, ib)
    ext = parts["EXT"]
    assert ext.attrs["pca_dropped_in_gaps"] == [0, 11]  # OB tags 1000..1010
    assert ext.attrs["pca_dropped_vectors"] == 11 and ext.attrs["pca_max_gap_s"] == [2.0, 2.0]
    assert ext.attrs["pca_outside_overlap"] == [1, 1]  # OB first, IB last tag
    assert ext.attrs["pca_interpolated_vectors"] == [0, n - 12]
    assert ext.attrs["pca_time_base"].startswith("OB time tags")
    assert ext.sizes["time"] == n - 12
    np.testing.assert_array_equal(ext["epoch"].values, np.delete(epoch_ob, [0, *range(1000, 1011)]))
    # the resampled white IB noise keeps half its variance at u = 1/2 (documented
    # limit of linear interpolation): psi_IB ~ 0.16 / 2; the OB one is untouched
    # (sampling std of psi as in test_pca: sqrt(var_e (pa + pb) + pa pb + 2 p^2 / N); 4 of them)
    psi = np.asarray(ext.attrs["pca_noise_variance_nT2"]).reshape(3, 2)
    pa, pb, m = 0.01, 0.16 / 2, ext.sizes["time"]
    var_e = ext_ob.var(axis=0)
    for col, p_true in enumerate((pa, pb)):
        std = np.sqrt((var_e * (pa + pb) + pa * pb + 2 * p_true**2) / m)
        assert np.all(np.abs(psi[:, col] - p_true) < 4 * std), (col, psi[:, col], std)
    sel = np.delete(np.arange(n), [0, *range(1000, 1011)])
    err = np.sqrt(np.mean((ext["b"].values - ext_ob[sel]) ** 2, axis=0))
    # the inverse-variance optimum sqrt(pa pb / (pa + pb)) = 0.094 nT; 5 % for the
    # weights' own sampling error (psi above) -- better than the better sensor alone
    np.testing.assert_allclose(err, np.sqrt(pa * pb / (pa + pb)), rtol=0.05)
    assert np.all(err < 0.1)
    # the position etc. of the OB rows go with the kept times
    np.testing.assert_array_equal(ext["obt"].values, ob["obt"].values[sel])
    # on a regular grid: OB interpolated as well, float variables too
    grid = cl.level_j(ob, ib, step_s=2.0)["EXT"]
    assert grid.attrs["pca_time_base"].startswith("regular grid of 2 s")
    assert np.all(np.diff(grid["epoch"].values) % 2_000_000_000 == 0)
    assert grid["epoch"].values[0] == epoch_ib[0]  # overlap start
    np.testing.assert_allclose(
        grid["obt"].values, 3.6e8 + (grid["epoch"].values - epoch_ob[0]) / 1e9, rtol=0, atol=1e-6
    )
    assert grid["quality"].dtype == ob["quality"].dtype
    with pytest.raises(InputFormatError, match="common"):
        cl.level_j(ob, ib, max_gap_s=0.1)  # nothing can be interpolated


# --- reaction wheel CSV ---------------------------------------------------------------


def test_read_reaction_wheels(tmp_path, lsk):
    p = tmp_path / "rw.csv"
    p.write_text(
        "# wheel rates\ntime_utc,rw1_hz,rw2_hz,rw3_hz,rw4_hz\n"
        "2014-08-01T00:00:00,23.7,31.2,14.4,46.3\n2014-08-01T00:00:16.5,23.8,31.1,,46.2\n"
    )
    table = read_reaction_wheels(p, lsk)
    assert table.epoch.dtype == np.int64
    assert table.epoch[1] - table.epoch[0] == 16_500_000_000
    assert np.isnan(table.frequencies[1, 2]) and table.frequencies[0, 3] == 46.3


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("time,rw1\n", "line 1: header"),
        ("time_utc,rw1_hz,rw2_hz,rw3_hz,rw4_hz\n2014-08-01T00:00:00,1,2,3\n", "line 2: 4 fields"),
        ("time_utc,rw1_hz,rw2_hz,rw3_hz,rw4_hz\n2014-08-01T00:00:00,1,x,3,4\n", "field 'rw2_hz'"),
        ("time_utc,rw1_hz,rw2_hz,rw3_hz,rw4_hz\n2014-08-01T00:00:00,1,2,-3,4\n", ">= 0"),
        (
            "time_utc,rw1_hz,rw2_hz,rw3_hz,rw4_hz\n2014-13-01T00:00:00,1,2,3,4\n",
            "line 2, field 'time_utc'",
        ),
        (
            "time_utc,rw1_hz,rw2_hz,rw3_hz,rw4_hz\n2014-08-01T00:00:10,1,2,3,4\n"
            "2014-08-01T00:00:10,1,2,3,4\n",
            "line 3.*must increase",
        ),
        ("time_utc,rw1_hz,rw2_hz,rw3_hz,rw4_hz\n", "no data rows"),
    ],
)
def test_read_reaction_wheels_errors(tmp_path, lsk, text, match):
    p = tmp_path / "rw.csv"
    p.write_text(text)
    with pytest.raises(InputFormatError, match=match) as err:
        read_reaction_wheels(p, lsk)
    assert str(p) in str(err.value)


def test_wheel_table_must_cover_the_data(lsk):
    ds, _, _, table, *_ = _wheel_case(lsk, n=3000)
    short = ReactionWheelTable(epoch=table.epoch[:1] - 10**13, frequencies=table.frequencies[:1])
    with pytest.raises(InputFormatError, match="covers"):
        cl.level_h(ds, short)


# --- files and command line -----------------------------------------------------------


def _write(ds, out, lsk):
    from fluxcal.missions.rosetta.clean_cli import clean_products
    from fluxcal.missions.rosetta.products import level_products
    from fluxcal.products.declared import write_declared

    level, sensor = ds.attrs["level"], ds.attrs["sensor"]
    if level in "ABC" and "sid" not in ds:
        # calibrated tables are written per filter mode (archive names, issue 10)
        ds = ds.assign(sid=("time", np.full(ds.sizes["time"], 3, np.int16), {"units": "1"}))
    if level in "ABCEFG":
        products = level_products(ds, lsk=lsk)
    else:
        products = [clean_products(ds, level=level, sensor=sensor, lsk=lsk)]
    paths = write_declared(products, out, lambda product: {})  # no provenance
    return {p.suffix: p for p in paths}


def _wheel_csv(path, tab_t, rates, t0, lsk):
    from fluxcal.geometry.time import tt2000_to_utc

    utc = tt2000_to_utc(t0 + np.round(tab_t * 1e9).astype(np.int64), digits=3, lsk=lsk)
    rows = ["time_utc,rw1_hz,rw2_hz,rw3_hz,rw4_hz"]
    for u, r in zip(utc, rates, strict=True):
        rows.append(",".join([str(u)] + ["" if np.isnan(v) else f"{v:.6f}" for v in r]))
    path.write_text("\n".join(rows) + "\n")
    return path


def test_clean_command_h_i_k(tmp_path, lsk):
    ds, bg, phase, _, tab_t, rates, t0 = _wheel_case(lsk, n=8000)
    ds = ds.isel(time=slice(0, 8000))
    files = _write(ds, tmp_path / "in", lsk)
    wheels = _wheel_csv(tmp_path / "rw.csv", tab_t, rates, t0, lsk)
    app = typer.Typer()
    app.command()(clean)
    app.command("noop")(lambda: None)  # keep "clean" a sub-command
    runner = CliRunner()
    out = tmp_path / "out"
    args = ["clean", "--level", "H", "--input", str(files[".cdf"]), "--out", str(out)]
    res = runner.invoke(app, args + ["--wheels", str(wheels), "--lap-lines", "2.5"])
    assert res.exit_code == 0, res.output
    names = sorted(p.name for p in out.iterdir())
    assert names == [
        "RPCMAG_20140801_CLH_OB.LBL",
        "RPCMAG_20140801_CLH_OB.TAB",
        "RPCMAG_20140801_CLH_OB.png",
        "rosetta_rpcmag_clh-ob_20140801_v01.cdf",
    ]
    h = read_fluxcal_product(out / "rosetta_rpcmag_clh-ob_20140801_v01.cdf")
    assert h.attrs["level"] == "H"
    assert np.sqrt(np.mean((h["b"].values - bg[:8000]) ** 2)) < 0.05
    assert (out / "RPCMAG_20140801_CLH_OB.png").read_bytes()[:4] == b"\x89PNG"
    # the table has the LEVEL_C columns (time, obt, position, B, quality)
    first = (out / "RPCMAG_20140801_CLH_OB.TAB").read_text().splitlines()[0].split()
    assert first[0].startswith("2014-08-01T00:00:00") and len(first) == 9

    res = runner.invoke(
        app,
        [
            "clean",
            "--level",
            "I",
            "--input",
            str(out / "rosetta_rpcmag_clh-ob_20140801_v01.cdf"),
            "--out",
            str(out),
        ],
    )
    assert res.exit_code == 0, res.output
    i = read_fluxcal_product(out / "rosetta_rpcmag_cli-ob_20140801_v01.cdf")
    assert i.sizes["time"] == 400 and i.attrs["level"] == "I"

    hds, *_ = _heater_case(lsk, n=6000)
    kin = _write(hds, tmp_path / "kin", lsk)
    res = runner.invoke(
        app, ["clean", "--level", "K", "--input", str(kin[".TAB"]), "--out", str(out)]
    )
    assert res.exit_code == 0, res.output
    assert (out / "RPCMAG_20140801_CLK_OB.png").exists()
    k = read_fluxcal_product(out / "rosetta_rpcmag_clk-ob_20140801_v01.cdf")
    assert k.attrs["heater_jumps"] > 0 and "temperature" in k


def test_clean_level_l_rotation_preserves_magnitude(tmp_path, lsk):
    from fluxcal.missions.rosetta.synthetic_kernels import write_rosetta_like_kernels

    meta = write_rosetta_like_kernels(tmp_path / "k", START, 600.0, margin_s=1200.0)
    hds, *_ = _heater_case(lsk, n=2000)
    kfile = _write(cl.level_k(hds), tmp_path / "kin", lsk)
    res = clean_files("L", [kfile[".cdf"]], tmp_path / "out", kernels=meta)
    lds = res.levels["OB"]
    assert lds.attrs["level"] == "L" and lds.attrs["output_frame"] == "ECLIPJ2000"
    np.testing.assert_allclose(
        np.linalg.norm(lds["b"].values, axis=1),
        np.linalg.norm(cl.level_k(hds)["b"].values, axis=1),
        atol=2e-3,  # products store B with 3 decimals (nT)
    )
    assert "position" in lds and (tmp_path / "out" / "RPCMAG_20140801_CLL_OB.TAB").exists()


def test_level_l_matches_scalar_spice_rotation(tmp_path, lsk):
    """LEVEL_L against one ``spiceypy.pxform`` per sample (the scalar oracle).

    Tolerance 1e-9 relative: the LEVEL_C rotation path SLERPs attitude between nodes
    to 5e-10 rad (`fluxcal.geometry.frames.DEFAULT_TOLERANCE`; SLERP between type 3 CK
    records is what SPICE itself does), a rotation error theta moves a vector by at
    most theta |B|; the oracle's ET comes from SPICE's own ``unitim`` (TT -> TDB), which
    agrees with fluxcal's conversion (a 1 us difference would be ~1e-9 rad only at
    1e-3 rad/s); float rounding adds ~1e-15. Measured: 2.6e-13.
    """
    import spiceypy

    from fluxcal.missions.rosetta.level_c import SPACECRAFT_FRAME
    from fluxcal.missions.rosetta.synthetic_kernels import write_rosetta_like_kernels

    meta = write_rosetta_like_kernels(tmp_path / "k", START, 600.0, margin_s=1200.0)
    hds, *_ = _heater_case(lsk, n=2000)
    kds = cl.level_k(hds)
    with KernelPool(meta):
        lds = cl.level_l(kds, lsk=lsk)
        assert lds["b"].attrs["frame"] == "ECLIPJ2000"
        idx = np.unique(np.linspace(0, kds.sizes["time"] - 1, 60).astype(int))
        epoch = kds["epoch"].values[idx].astype(np.int64)
        # TT2000: TT ns past J2000; whole seconds and the rest kept apart (no float ns)
        tt = (epoch // 1_000_000_000).astype(float) + (epoch % 1_000_000_000) / 1e9
        expected = np.array(
            [
                spiceypy.mxv(
                    spiceypy.pxform(
                        SPACECRAFT_FRAME, "ECLIPJ2000", spiceypy.unitim(t, "TT", "TDB")
                    ),
                    v,
                )
                for t, v in zip(tt, kds["b"].values[idx], strict=True)
            ]
        )
    got = lds["b"].values[idx]
    assert not np.allclose(got, kds["b"].values[idx], atol=1e-3)  # a real rotation
    rel = np.linalg.norm(got - expected, axis=1) / np.linalg.norm(expected, axis=1)
    assert np.max(rel) < 1e-9, np.max(rel)


def test_clean_files_errors(tmp_path, lsk):
    with pytest.raises(FluxcalError, match="unknown level"):
        clean_files("X", [tmp_path / "a.cdf"], tmp_path)
    with pytest.raises(FluxcalError, match="needs 2 input"):
        clean_files("J", [tmp_path / "a.cdf"], tmp_path)
    with pytest.raises(FluxcalError, match="kernels"):
        clean_files("L", [tmp_path / "a.cdf"], tmp_path)
    with pytest.raises(InputFormatError, match="not found"):
        clean_files("H", [tmp_path / "missing.cdf"], tmp_path, lap_lines_hz=[2.5])
    hds, *_ = _heater_case(lsk, n=400)
    files = _write(hds, tmp_path / "b", lsk)  # a LEVEL_B product
    with pytest.raises(InputFormatError, match="LEVEL_B product; LEVEL_H is made from LEVEL_C"):
        clean_files("H", [files[".cdf"]], tmp_path / "out", lap_lines_hz=[2.5])


def test_read_intervals(tmp_path, lsk):
    p = tmp_path / "romap.csv"
    p.write_text("start_utc,stop_utc,label\n2014-08-01T00:00:10,2014-08-01T00:00:20,A\n")
    [(a, b, label)] = read_intervals(p, lsk)
    assert b - a == 10_000_000_000 and label == "A"
    p.write_text("start_utc,stop_utc,label\n2014-08-01T00:00:20,2014-08-01T00:00:10,A\n")
    with pytest.raises(InputFormatError, match="line 2"):
        read_intervals(p, lsk)
    assert isinstance(Path(p), Path)


def test_clean_command_j_writes_three_products(tmp_path, lsk):
    rng = np.random.default_rng(2)
    t0 = int(utc_to_tt2000(np.array([START]), lsk)[0])
    n = 3000
    epoch = t0 + np.arange(n, dtype=np.int64) * 1_000_000_000 + 500_000_000
    ext = rotating_field(np.arange(n), magnitude=5.0, period=1e5) + rng.normal(size=(n, 3))
    ob = _dataset(epoch, ext + 0.1 * rng.normal(size=(n, 3)), level="G", sensor="OB")
    ib = _dataset(epoch, ext + 0.4 * rng.normal(size=(n, 3)), level="G", sensor="IB")
    f_ob, f_ib = _write(ob, tmp_path / "in", lsk), _write(ib, tmp_path / "in", lsk)
    res = clean_files("J", [f_ob[".cdf"], f_ib[".cdf"]], tmp_path / "out")
    assert set(res.levels) == {"EXT", "OB", "IB"}
    for tag in ("EXT", "OB", "IB"):
        back = read_fluxcal_product(
            tmp_path / "out" / f"rosetta_rpcmag_clj-{tag.lower()}_20140801_v01.cdf")
        assert back.attrs["pca_part"] == tag and back.sizes["time"] == n
    # the command with a regular grid and a gap limit (IB shifted by 0.25 s, a 4 s gap)
    ib2 = _dataset(np.delete(epoch, range(100, 103)) + 250_000_000, ib["b"].values[3:],
                   level="G", sensor="IB")  # fmt: skip
    f_ib2 = _write(ib2, tmp_path / "in2", lsk)
    app = typer.Typer()
    app.command()(clean)
    app.command("noop")(lambda: None)
    args = ["clean", "--level", "J", "--input", str(f_ob[".cdf"]), "--input-ib", str(f_ib2[".cdf"])]
    out = tmp_path / "out2"
    res = CliRunner().invoke(app, args + ["--out", str(out), "--step", "1", "--max-gap", "3"])
    assert res.exit_code == 0, res.output
    back = read_fluxcal_product(out / "rosetta_rpcmag_clj-ext_20140801_v01.cdf")
    assert str(back.attrs["pca_time_base"]).startswith("regular grid of 1 s")
    # grid every 1 s from IB's first tag (the overlap start), n - 1 times; IB's gap of
    # 4 s (> 3 samples) holds 3 of them strictly inside, OB has none
    assert list(np.ravel(back.attrs["pca_dropped_in_gaps"])) == [0, 3]
    assert back.sizes["time"] == n - 1 - 3


def test_level_j_refuses_one_sensor_twice(tmp_path, lsk, capsys):
    """Issue 31: the OB product given as both inputs (or as --input-ib) is refused, exit 2.

    Was: a product labelled SENSOR="IB" made from OB data, residuals all 0, exit 0.
    """
    from fluxcal.cli import main

    rng = np.random.default_rng(3)
    t0 = int(utc_to_tt2000(np.array([START]), lsk)[0])
    epoch = t0 + np.arange(600, dtype=np.int64) * 1_000_000_000
    ext = rotating_field(np.arange(600), magnitude=5.0, period=1e4)
    f_ob = _write(_dataset(epoch, ext + rng.normal(size=(600, 3)), level="G", sensor="OB"),
                  tmp_path / "ob", lsk)[".cdf"]
    f_ob2 = _write(_dataset(epoch, ext + rng.normal(size=(600, 3)), level="G", sensor="OB"),
                   tmp_path / "ob2", lsk)[".cdf"]
    f_ib = _write(_dataset(epoch, ext + rng.normal(size=(600, 3)), level="G", sensor="IB"),
                  tmp_path / "ib", lsk)[".cdf"]
    cases = [(f_ob, f_ob, "--input-ib", "both --input (OB) and --input-ib"),
             (f_ob, f_ob2, "--input-ib", "is the OB sensor's product"),
             (f_ib, f_ob, "--input", "is the IB sensor's product")]
    for first, second, option, expect in cases:
        out = tmp_path / "out"
        code = main(["rosetta", "clean", "--level", "J", "--input", str(first),
                     "--input-ib", str(second), "--out", str(out)])
        (line,) = capsys.readouterr().err.strip().splitlines()
        assert code == 2 and line.startswith("fluxcal: error: ") and option in line, line
        assert expect in line, line
        assert not out.exists() or not any(out.iterdir())


def test_fluxcal_rosetta_clean_k_with_romap_intervals(tmp_path, lsk):
    # the registered command (fluxcal.cli.main), method 2 from an interval CSV
    from fluxcal.cli import main
    from fluxcal.geometry.time import tt2000_to_utc

    ds, bg, intervals, offsets = _labelled_heater_case(lsk)
    files = _write(ds, tmp_path / "in", lsk)
    rows = ["start_utc,stop_utc,label"]
    for a, b, label in intervals:
        start, stop = tt2000_to_utc(np.array([a, b]), digits=3, lsk=lsk)
        rows.append(f"{start},{stop},{label}")
    csv_path = tmp_path / "romap.csv"
    csv_path.write_text("\n".join(rows) + "\n")
    out = tmp_path / "out"
    args = ["rosetta", "clean", "--level", "K", "--input", str(files[".cdf"]), "--out", str(out)]
    assert main(args + ["--intervals", str(csv_path)]) == 0
    k = read_fluxcal_product(out / "rosetta_rpcmag_clk-ob_20140801_v01.cdf")
    assert "assisted" in k.attrs["heater_method"]
    assert set(k.attrs["heater_offsets_nT"]) == set(offsets)
    # same as the level function on the same intervals (products store B to 1 pT)
    expected = cl.level_k_assisted(ds, intervals)["b"].values
    np.testing.assert_allclose(k["b"].values, expected, atol=1e-3)
    residual = np.linalg.norm(k["b"].values - bg, axis=1)
    assert np.sqrt(np.mean(residual**2)) < 0.1  # issue 5: residual < 0.1 nT rms
    assert (out / "RPCMAG_20140801_CLK_OB.png").read_bytes()[:4] == b"\x89PNG"
    assert (out / "RPCMAG_20140801_CLK_OB.TAB").is_file()
    # a malformed interval file is a clean error naming the file and line
    csv_path.write_text("start_utc,stop_utc,label\n2014-08-01T00:00:20,2014-08-01T00:00:10,A\n")
    assert main(args + ["--intervals", str(csv_path)]) == 2


# --- LEVEL_F from K and LEVEL_G from L (seed 003 sec. 4.7, 4.8) -------------------------


def _one_second_means(values, per=20):
    """Independent 1 s means: the series starts on a whole UTC second at 20 Hz."""
    v = np.asarray(values, dtype=float)
    return v[: v.shape[0] // per * per].reshape(-1, per, *v.shape[1:]).mean(axis=1)


def test_level_f_from_level_k(lsk):
    hds, *_ = _heater_case(lsk, n=2000, sign=-1.0)
    k = cl.level_k(hds)
    f = cl.level_f(k, lsk=lsk)
    assert f.attrs["level"] == "F" and f.sizes["time"] == 100
    np.testing.assert_allclose(f["b"].values, _one_second_means(k["b"].values), atol=1e-12)
    # time tag: middle of each second after UTC midnight
    t0 = int(utc_to_tt2000(np.array([START]), lsk)[0])
    np.testing.assert_array_equal(f["epoch"].values, t0 + 500_000_000 + np.arange(100) * 10**9)
    with pytest.raises(InputFormatError, match="LEVEL_K"):
        cl.level_f(hds, lsk=lsk)  # LEVEL_B: the pipeline's path, not this one


def test_clean_command_f_and_g(tmp_path, lsk):
    from fluxcal.missions.rosetta.synthetic_kernels import write_rosetta_like_kernels

    meta = write_rosetta_like_kernels(tmp_path / "k", START, 600.0, margin_s=1200.0)
    hds, *_ = _heater_case(lsk, n=2000)
    kfile = _write(cl.level_k(hds), tmp_path / "kin", lsk)
    out = tmp_path / "out"
    f = clean_files("F", [kfile[".cdf"]], out).levels["OB"]
    k = read_fluxcal_product(kfile[".cdf"])
    # tolerance: the K product stores B with 3 decimals
    np.testing.assert_allclose(f["b"].values, _one_second_means(k["b"].values), atol=1e-9)
    # written like F from B (archive columns), its name saying the source level so that
    # it never replaces calibrate's F from B: RPCMAG<yymmdd>_CLF_<sensor>_A<NN>_FROMK
    # (issue 22, docs/decisions/products.md decision 55)
    first = (out / "RPCMAG140801_CLF_OB_A01_FROMK.TAB").read_text().splitlines()[0].split()
    assert not (out / "RPCMAG140801_CLF_OB_A01.TAB").exists()
    assert (out / "rosetta_rpcmag_clf-ob-a01-fromk_20140801_v01.cdf").exists()
    assert len(first) == 6  # TIME.UTC, TIME.OBT, BX, BY, BZ, QUALITY (seed sec. 4.7)

    lres = clean_files("L", [kfile[".cdf"]], out, kernels=meta)
    lfile = [p for p in lres.paths if p.suffix == ".cdf"][0]
    g = clean_files("G", [lfile], out).levels["OB"]
    ldata = read_fluxcal_product(lfile)
    assert g.attrs["level"] == "G" and g.sizes["time"] == 100
    np.testing.assert_allclose(g["b"].values, _one_second_means(ldata["b"].values), atol=1e-9)
    np.testing.assert_allclose(
        g["position"].values, _one_second_means(ldata["position"].values), rtol=1e-12
    )
    first = (out / "RPCMAG140801_CLG_OB_A01_FROML.TAB").read_text().splitlines()[0].split()
    assert len(first) == 9  # with POSITION.X/Y/Z (seed sec. 4.8)
    with pytest.raises(InputFormatError, match="LEVEL_G is made from LEVEL_L"):
        clean_files("G", [kfile[".cdf"]], out)


# --- method 2, stage 1 from a heater-state series (seed 003 sec. 4.12.2) ---------------


def test_clean_k_with_heater_states(tmp_path, lsk):
    from fluxcal.geometry.time import tt2000_to_utc

    ds, bg, intervals, offsets = _labelled_heater_case(lsk)
    files = _write(ds, tmp_path / "in", lsk)
    # the states at each change only: heaters switched on at an interval start, all off
    # at its stop (e.g. lander housekeeping or states derived from ROMAP)
    rows = ["time_utc,A,B,C"]
    for a, b, label in intervals:
        start, stop = tt2000_to_utc(np.array([a, b]), digits=9, lsk=lsk)
        on = ",".join("1" if h in label.split("+") else "0" for h in "ABC")
        rows += [f"{start},{on}", f"{stop},0,0,0"]
    states = tmp_path / "heaters.csv"
    states.write_text("\n".join(rows) + "\n")
    res = clean_files("K", [files[".cdf"]], tmp_path / "out", heater_states=states, plot=False)
    k = res.levels["OB"]
    assert "assisted" in k.attrs["heater_method"]
    assert set(k.attrs["heater_offsets_nT"]) == set(offsets)  # labels "A" and "B+C"
    # the same as the level function on the intervals themselves (inputs stored to 1 pT)
    expected = cl.level_k_assisted(read_fluxcal_product(files[".cdf"]), intervals)["b"].values
    np.testing.assert_allclose(k["b"].values, expected, atol=1e-9)
    residual = np.linalg.norm(k["b"].values - bg, axis=1)
    assert np.sqrt(np.mean(residual**2)) < 0.1  # issue 5: residual < 0.1 nT rms
    states.write_text("time_utc,A\n2014-08-01T00:00:01,2\n")
    with pytest.raises(InputFormatError, match="not 0 or 1"):
        clean_files("K", [files[".cdf"]], tmp_path / "out", heater_states=states)


def test_timeseries_plot_draws_a_spike_in_the_last_samples(tmp_path):
    """The before/after PNG keeps every sample (min/max envelope), the last ones too (issue 22)."""
    import matplotlib.pyplot as plt

    from fluxcal.missions.rosetta import clean_cli

    n = 500_123
    epoch = np.int64(441_000_000_000_000_000) + np.arange(n, dtype=np.int64) * 50_000_000
    b = np.zeros((n, 3))
    b[n - 4, 0] = 300.0  # an odd index: a stride-2 decimation skips it
    ds = xr.Dataset({"b": (("time", "component"), b)}, coords={"epoch": ("time", epoch)})
    figs = []
    real = clean_cli._save
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(plt, "close", lambda fig=None: None)
        mp.setattr(clean_cli, "_save", lambda fig, path: (figs.append(fig), real(fig, path))[1])
        clean_cli.plot_timeseries(ds, ds, tmp_path / "k.png", "K")
    (fig,) = figs
    for line in fig.axes[0].get_lines():
        assert np.max(line.get_ydata()) == 300.0
    plt.close(fig)
