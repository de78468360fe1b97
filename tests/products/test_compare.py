"""``fluxcal compare``: two products with a known injected difference.

Expected values are closed forms of the injection (offsets of both signs per quality
flag, a time shift of either sign, samples removed from one side, extra samples on the
other), checked on the printed report.  The matcher is checked against a brute-force
nearest-neighbour search written independently (all pairs, one loop per A sample).
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
from hypothesis import given, settings
from hypothesis import strategies as st

from fluxcal.cli import main
from fluxcal.products import write_product
from fluxcal.products.compare import match, parse_tolerance

N = 600
T0 = 392_040_000_000_000_000  # 2012-06-02T...
STEP = 50_000_000  # 20 Hz
DROPPED = np.array([3, 100, 101, 102, 377, 598, 599])  # removed from B
C_Q0, C_Q1 = 2.5, 1.25  # B - A on x for quality 0 (+) and 1 (-); quality 2 unchanged


def _product(b: np.ndarray, epoch: np.ndarray, quality: np.ndarray, frame: str = "MSO"
             ) -> xr.Dataset:
    return xr.Dataset(
        {"b": (("time", "component"), b, {"units": "nT", "coordinate_system": frame}),
         "quality": ("time", quality, {"units": "1"})},
        coords={"epoch": ("time", epoch.astype(np.int64)), "component": ["x", "y", "z"]},
        attrs={"creation_time": "2026-01-01T00:00:00Z"})


def _pair(tmp_path: Path, shift_ns: int, fmt: str = "nc", frame_b: str = "MSO"
          ) -> tuple[Path, Path]:
    rng = np.random.default_rng(11)
    epoch = T0 + np.arange(N, dtype=np.int64) * STEP
    quality = np.arange(N) % 3
    b = rng.normal(0.0, 300.0, (N, 3))
    b_b = b.copy()
    b_b[:, 0] += np.where(quality == 0, C_Q0, np.where(quality == 1, -C_Q1, 0.0))
    keep = np.setdiff1d(np.arange(N), DROPPED)
    # B: shifted, some samples missing, and 4 samples an hour later (only in B)
    extra_t = epoch[-1] + 3_600_000_000_000 + np.arange(4) * STEP
    e_b = np.concatenate([epoch[keep] + shift_ns, extra_t])
    bb = np.concatenate([b_b[keep], rng.normal(0, 1, (4, 3))])
    qb = np.concatenate([quality[keep], np.zeros(4, int)])
    a_path = write_product(_product(b, epoch, quality), tmp_path / "A", (fmt,))[0]
    b_path = write_product(_product(bb, e_b, qb, frame_b), tmp_path / "B", (fmt,))[0]
    return a_path, b_path


def _numbers(report: str, header: str) -> dict[str, list[float]]:
    """Rows ``name mean rms max N`` of the block after ``header`` in the report."""
    block = report.split(header, 1)[1].splitlines()[1:]
    out = {}
    for line in block:
        parts = line.split()
        if parts[:1] == ["A"]:  # the column header
            continue
        if len(parts) != 5 or parts[0] == "quality":
            break
        out[parts[0]] = [float(p) for p in parts[1:]]
    return out


@pytest.mark.parametrize("shift_ms", [3, -3])
def test_statistics_equal_the_injected_difference(tmp_path: Path, capsys, shift_ms: int
                                                  ) -> None:
    a, b = _pair(tmp_path, shift_ms * 1_000_000)
    code = main(["compare", str(a), str(b), "--tolerance", "10ms", "--out", str(tmp_path)])
    out = capsys.readouterr().out
    assert code == 0, out
    matched = N - DROPPED.size
    assert f"{matched} matched, {DROPPED.size} only in A, 4 only in B" in out
    # the time difference A - B is minus the injected shift (printed with 6 decimals, ms)
    assert f"time A - B (ms): mean {-shift_ms:.6f}, max |dt| {abs(shift_ms):.6f}" in out
    q = np.setdiff1d(np.arange(N), DROPPED) % 3
    n0, n1, n2 = (int((q == k).sum()) for k in range(3))
    # A - B on x: -C_Q0 (quality 0), +C_Q1 (quality 1), 0 (quality 2): closed forms
    mean = (-C_Q0 * n0 + C_Q1 * n1) / matched
    rms = np.sqrt((C_Q0**2 * n0 + C_Q1**2 * n1) / matched)
    # printed with 6 decimals: agree to half a unit of the last digit
    tol = 5e-7 + 1e-12
    overall = _numbers(out, "all samples")
    np.testing.assert_allclose(overall["x"], [mean, rms, C_Q0, matched], atol=tol)
    np.testing.assert_allclose(overall["y"], [0, 0, 0, matched], atol=tol)
    np.testing.assert_allclose(overall["z"], [0, 0, 0, matched], atol=tol)
    for flag, value, n in (("0", -C_Q0, n0), ("1", C_Q1, n1), ("2", 0.0, n2)):
        stats = _numbers(out, f"quality {flag} (flag of A)")
        np.testing.assert_allclose(stats["x"], [value, abs(value), abs(value), n], atol=tol)
    png = tmp_path / "compare_A_vs_B.png"
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert f"plot: {png}" in out


def test_tolerance_smaller_than_the_shift_matches_nothing(tmp_path: Path, capsys) -> None:
    a, b = _pair(tmp_path, 3_000_000)
    assert main(["compare", str(a), str(b), "--tolerance", "2ms", "--out",
                 str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert f"0 matched, {N} only in A, {N - DROPPED.size + 4} only in B" in out
    assert "no pair matched" in out


def test_cdf_products(tmp_path: Path, capsys) -> None:
    pytest.importorskip("cdflib")
    a, b = _pair(tmp_path, 0, fmt="cdf")
    assert main(["compare", str(a), str(b), "--out", str(tmp_path)]) == 0
    assert f"{N - DROPPED.size} matched" in capsys.readouterr().out


def test_different_frames_are_refused_unless_forced(tmp_path: Path, capsys) -> None:
    a, b = _pair(tmp_path, 0, frame_b="RTN")
    assert main(["compare", str(a), str(b), "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "MSO" in err and "RTN" in err and "--force" in err
    assert main(["compare", str(a), str(b), "--force", "--out", str(tmp_path)]) == 0


def test_bad_inputs_exit_2_with_one_line(tmp_path: Path, capsys) -> None:
    a, _ = _pair(tmp_path, 0)
    assert main(["compare", str(a), str(tmp_path / "missing.nc")]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "missing.nc" in err
    assert main(["compare", str(a), str(a), "--tolerance", "soon"]) == 2
    assert "--tolerance" in capsys.readouterr().err
    bad = tmp_path / "BAD.LBL"
    bad.write_text("PDS_VERSION_ID = PDS3\r\nOBJECT = TABLE\r\nEND\r\n")
    assert main(["compare", str(a), str(bad)]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "BAD.LBL" in err


def test_archived_table_against_netcdf_of_the_same_data(tmp_path: Path, capsys) -> None:
    """fluxcal's CDR table (UTC to the truncated ms, 3 decimals) against exact netCDF."""
    from fluxcal.missions.messenger.products import table_columns

    rng = np.random.default_rng(5)
    epoch = T0 + np.arange(N, dtype=np.int64) * STEP + 123_456  # not on whole ms
    ds = xr.Dataset(
        {"met": ("time", 2.4e8 + np.arange(N) * 0.05, {"units": "s"}),
         "position": (("time", "position_component"), rng.normal(0, 3e3, (N, 3)),
                      {"units": "km"}),
         "b": (("time", "b_component"), rng.normal(0, 300, (N, 3)),
               {"units": "nT", "coordinate_system": "MSO"}),
         "quality": ("time", np.zeros(N, int), {"units": "1"})},
        coords={"epoch": ("time", epoch), "b_component": ["B_X", "B_Y", "B_Z"],
                "position_component": ["X", "Y", "Z"]},
        attrs={"creation_time": "2026-01-01T00:00:00Z"})
    tab = ds.assign(_utc_fields(epoch))
    write_product(tab, tmp_path / "MAGMSOSCI12154_V01", ("tab",), table_columns("mso", False),
                  {"COORDINATE_SYSTEM_NAME": "MSGR_MSO"})
    nc = write_product(ds, tmp_path / "fluxcal", ("nc",))[0]
    assert main(["compare", str(tmp_path / "MAGMSOSCI12154_V01.TAB"), str(nc), "--out",
                 str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert f"{N} matched, 0 only in A, 0 only in B" in out
    assert "frame MSO" in out
    # the table's time is the epoch truncated to the ms: A - B in (-1 ms, 0]
    dt = re.search(r"mean (-?[\d.]+), max \|dt\| ([\d.]+)", out)
    assert dt is not None and -1.0 < float(dt.group(1)) <= 0 and float(dt.group(2)) < 1.0
    stats = _numbers(out, "all samples")
    for comp in ("B_X", "B_Y", "B_Z"):  # F11.3: within half a unit of the 3rd decimal
        assert stats[comp][2] <= 5e-4 + 1e-9


def _utc_fields(epoch: np.ndarray) -> dict[str, tuple]:
    """YEAR DAY_OF_YEAR HOUR MINUTE SECOND (ms truncated) by cdflib, not fluxcal."""
    import cdflib

    f = np.asarray(cdflib.cdfepoch.breakdown_tt2000(epoch)).reshape(-1, 9)
    days = (f[:, 0] - 1970).astype("M8[Y]").astype("M8[D]")
    dates = np.array([f"{y:04d}-{m:02d}-{d:02d}" for y, m, d in f[:, :3]], dtype="M8[D]")
    doy = (dates - days).astype(int) + 1
    return {"year": ("time", f[:, 0]), "doy": ("time", doy), "hour": ("time", f[:, 3]),
            "minute": ("time", f[:, 4]), "second": ("time", f[:, 5] + f[:, 6] / 1000.0)}


@pytest.mark.parametrize(("text", "ns"), [("0.01s", 10_000_000), ("10ms", 10_000_000),
                                           ("50us", 50_000), ("100ns", 100), ("2", 2 * 10**9)])
def test_parse_tolerance(text: str, ns: int) -> None:
    assert parse_tolerance(text) == ns


def _brute_force(a: np.ndarray, b: np.ndarray, tol: int) -> set[tuple[int, int]]:
    """Nearest B of each A (earlier B on a tie), within tol; a B kept by its nearest A."""
    cand = {}
    for i, t in enumerate(a.tolist()):
        d = [abs(t - u) for u in b.tolist()]
        if not d:
            continue
        j = min(range(len(d)), key=lambda k: (d[k], k))
        if d[j] <= tol:
            cand.setdefault(j, []).append((d[j], i))
    return {(min(v)[1], j) for j, v in cand.items()}


@settings(max_examples=200, deadline=None)
@given(st.lists(st.integers(0, 2000), max_size=40, unique=True),
       st.lists(st.integers(0, 2000), max_size=40, unique=True),
       st.integers(0, 100))
def test_match_equals_brute_force(a: list[int], b: list[int], tol: int) -> None:
    ea, eb = np.sort(np.array(a, dtype=np.int64)), np.sort(np.array(b, dtype=np.int64))
    ia, ib = match(ea, eb, tol)
    assert set(zip(ia.tolist(), ib.tolist(), strict=True)) == _brute_force(ea, eb, tol)


def test_ambiguous_matches_are_counted() -> None:
    """B holds two samples 300 ns apart (as where two mode segments overlap): counted."""
    from fluxcal.products.compare import compare, format_report

    epoch = T0 + np.arange(10, dtype=np.int64) * STEP
    b = np.zeros((10, 3))
    q = np.zeros(10, int)
    e_b = np.sort(np.concatenate([epoch, [epoch[4] + 300]]))
    b_b = np.zeros((11, 3))
    b_b[5] = 7.0  # the extra sample, farther from A's epoch[4] than B's own epoch[4]
    c = compare(_product(b, epoch, q), _product(b_b, e_b, np.zeros(11, int)), 10_000_000)
    assert c.matched == 10 and c.ambiguous == 1
    assert c.overall[0].max_abs == 0.0  # the nearest (exact) sample was taken
    assert "1 of the matched A samples had more than one B sample" in format_report(c)


def test_plot_draws_a_difference_in_the_last_samples(tmp_path: Path, capsys,
                                                     monkeypatch) -> None:
    """A 300 nT difference in the last 10 of 10,001 pairs is in the plotted line (issue 22)."""
    from fluxcal.products import quicklook

    n = 10_001  # more than 2 x 4000 pairs: the plot draws an envelope, n mod 4000 = 2001
    epoch = T0 + np.arange(n, dtype=np.int64) * STEP
    b = np.random.default_rng(3).normal(0.0, 1.0, (n, 3))
    a_b = b.copy()
    a_b[n - 6, 1] += 300.0
    q = np.zeros(n, int)
    a = write_product(_product(a_b, epoch, q), tmp_path / "A", ("nc",))[0]
    bp = write_product(_product(b, epoch, q), tmp_path / "B", ("nc",))[0]
    figs = []
    save = quicklook.save_png
    monkeypatch.setattr(quicklook, "save_png", lambda fig, path: (figs.append(fig),
                                                                   save(fig, path))[1])
    assert main(["compare", str(a), str(bp), "--out", str(tmp_path / "cmp")]) == 0
    (fig,) = figs
    y = fig.axes[1].get_lines()[0].get_ydata()
    assert len(y) < n and np.max(y) == pytest.approx(300.0)
