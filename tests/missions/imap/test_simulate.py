"""IMAP MAG forward model (`fluxcal.missions.imap.simulate`) -> fluxcal's pipeline -> truth.

The simulator writes packets from a known field with its own bit packer (no code shared
with the decoder: ``tests/missions/test_forward_independence.py``); the truth it keeps is
what a correct pipeline must give back:

* L1A counts, ranges, compression flags and widths: **exactly** (integers in, integers out);
* L1A times: within 1 ns of the closed form ``MET epoch + coarse + fine/65536 +
  k/rate`` (both sides round to the nanosecond once: at most one rounding step apart);
* L1B field: within half a count of ``W`` bits through the matrix of the range,
  ``|dB_i| <= 0.5 * 2**(16 - W) * sum_j |M[range]_ij|`` (``W = 16`` uncompressed), the
  only loss being the rounding of the sensor's output to the packet's counts; plus
  1e-9 nT of float arithmetic.  The bound is also shown to be tight (the errors use
  more than 90 % of it), so a wrong rescale or matrix cannot hide below it.

Without ``../shared`` everything here runs on fluxcal's own simulated SCLK kernel,
calibration and XTCE description; with it, the team's XTCE must read the packets the
same way, and with the team's package installed, the team's own L1A must decode them
to the same counts (an outside check of the forward model).
"""

from __future__ import annotations

import datetime
import os
import subprocess
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from fluxcal.errors import InputFormatError
from fluxcal.missions.imap import sim_packets, simulate
from fluxcal.missions.imap.chain import process
from tests.missions.imap.conftest import XTCE

START = "2025-10-17T06:00:00"
LSK = XTCE.parents[1] / "kernels" / "generic" / "naif0012.tls"


@pytest.fixture(scope="module")
def support(tmp_path_factory) -> dict[str, Path]:
    """fluxcal's simulated SCLK kernel, calibration CDF and XTCE (no team file)."""
    return simulate.write_support(tmp_path_factory.mktemp("imap_support"))


def _run(tmp_path: Path, support: dict[str, Path], widths: tuple[int, ...], **kw):
    data, truth, stats = simulate.simulate_day(START, kw.pop("hours", 0.05),
                                               kw.pop("burst_minutes", 1.0), widths=widths,
                                               **kw)
    path = tmp_path / "sim.pkts"
    path.write_bytes(data)
    return path, truth, stats


def _check_l1a(ds, t) -> None:
    np.testing.assert_array_equal(ds["counts"].values, t.counts)
    np.testing.assert_array_equal(ds["range"].values, t.ranges)
    np.testing.assert_array_equal(ds["compression"].values, t.compression)
    np.testing.assert_array_equal(ds["compression_width"].values, t.width)
    assert np.abs(ds["epoch"].values - t.epoch).max() <= 1


def _check_l1b(ds, t, sensor: str) -> float:
    err = np.abs(ds["b"].values - t.b_nt)
    bound = simulate.quantisation_bound(t, sensor)
    assert np.all(err <= bound + 1e-9), float((err / bound).max())
    assert np.abs(ds["epoch"].values - t.epoch_b).max() <= 1
    return float((err / bound).max())


@pytest.mark.parametrize("widths", [(0,), (16,), (18,), (13,), (8, 20), (0, 16, 18, 13)])
def test_round_trip_every_width_both_modes(tmp_path, support, widths):
    path, truth, stats = _run(tmp_path, support, widths)
    l1a = process([path], level="l1a", kernels=support["kernels"], xtce=support["xtce"])
    l1b = process([path], level="l1b", calib=support["calib"], kernels=support["kernels"],
                  xtce=support["xtce"])
    assert set(l1a) == set(truth) == {("norm", "mago"), ("norm", "magi"),
                                       ("burst", "mago"), ("burst", "magi")}
    used = []
    for key, t in truth.items():
        assert set(np.unique(t.width)) == set(widths)
        _check_l1a(l1a[key], t)
        used.append(_check_l1b(l1b[key], t, key[1]))
    # the bound is tight: the rounding of the counts uses most of it
    assert max(used) > 0.9


def test_range_changes_inside_packets_and_the_60_bit_switch(tmp_path, support):
    path, truth, stats = _run(tmp_path, support, (18,))
    t = truth[("burst", "mago")]
    # ranges change inside one packet (same sequence count)
    per_packet = [np.unique(t.ranges[t.sequence == s]).size for s in np.unique(t.sequence)]
    assert max(per_packet) == 2
    # at W = 18 a range change is a jump of ~12000 counts: codes over 60 bits, so the
    # rest of those packets' vectors are written plain, and read back
    assert stats["plain_in_compressed"] > 0
    l1a = process([path], level="l1a", kernels=support["kernels"], xtce=support["xtce"])
    for key, tk in truth.items():
        _check_l1a(l1a[key], tk)


def test_no_range_changes_and_magi_primary(tmp_path, support):
    sim = simulate.simulate(simulate.met_of_utc(START), 64, plan=simulate.BURST,
                            widths=(0, 16), range_changes=False, primary="magi")
    path = tmp_path / "magi_primary.pkts"
    path.write_bytes(sim.packets)
    l1a = process([path], level="l1a", kernels=support["kernels"], xtce=support["xtce"])
    # MAGi primary: 64 vectors/s of MAGi, 8 of MAGo
    assert sim.truth[("burst", "magi")].counts.shape[0] == 8 * sim.truth[
        ("burst", "mago")].counts.shape[0]
    for key, t in sim.truth.items():
        assert np.unique(t.ranges).size == 1
        _check_l1a(l1a[key], t)


def _zeckendorf_value(bits: str) -> int:
    fib = [1, 2]
    while len(fib) < len(bits):
        fib.append(fib[-1] + fib[-2])
    return sum(f for f, b in zip(fib, bits[:-1], strict=False) if b == "1")


def test_fibonacci_codes_by_brute_force():
    n = np.arange(1, 3000)
    pattern, length = sim_packets.fibonacci_code(n)
    for value, p, m in zip(n, pattern, length, strict=True):
        bits = format(int(p), f"0{int(m)}b")
        assert bits.endswith("11") and "11" not in bits[:-1], bits
        assert _zeckendorf_value(bits) == value
    np.testing.assert_array_equal(sim_packets.zigzag(np.array([0, -1, 1, -2, 2, -3])),
                                  [0, 1, 2, 3, 4, 5])


@given(st.lists(st.tuples(st.integers(0, 2**34 - 1), st.integers(0, 34)), max_size=40))
def test_pack_bits_is_the_bit_string(fields):
    values = [v & ((1 << w) - 1) for v, w in fields]
    widths = [w for _, w in fields]
    pad = (-sum(widths)) % 8
    text = "".join(format(v, f"0{w}b") if w else "" for v, w in zip(values, widths,
                                                                     strict=True)) + "0" * pad
    got = sim_packets.pack_bits(np.array(values + [0], dtype=np.int64),
                                np.array(widths + [pad], dtype=np.int64))
    assert got == int(text, 2).to_bytes(len(text) // 8, "big") if text else got == b""


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow,
                                                                  HealthCheck.function_scoped_fixture])
@given(width=st.sampled_from([0, 8, 13, 16, 18, 20]), seed=st.integers(0, 2**31 - 1),
       step=st.sampled_from([1, 50, 3000, 2**17]))
def test_decoder_reads_random_extreme_vectors(support, width, seed, step):
    """Random walks of any step, clipped to the W-bit limits (both signs), random ranges."""
    from fluxcal.missions.imap.packets import read_packets
    from fluxcal.missions.imap.vectors import decode_vectors

    rng = np.random.default_rng(seed)
    w = width or 16
    lo, hi = -(2 ** (w - 1)), 2 ** (w - 1) - 1
    n, p, s = 3, 16, 4
    sections = []
    for v in (p, s):
        walk = np.cumsum(rng.integers(-step, step + 1, size=(n, v, 3)), axis=1)
        walk[:, 0] = rng.integers(lo, hi + 1, size=(n, 3))
        sections.append(sim_packets.Section(np.clip(walk, lo, hi),
                                            rng.integers(0, 4, size=(n, v))))
    header = {name: 0 for name, _ in sim_packets.HEADER}
    header.update(SEC_HDR_FLG=1, PKT_APID=1068, SEQ_FLGS=3, SRC_SEQ_CTR=np.arange(n),
                  PUS_SSUBTYPE=1, PRI_VECSEC=3, SEC_VECSEC=1, PUS_VERSION=1)
    data, _ = sim_packets.packets(header, sections[0], sections[1], width)
    dec = decode_vectors(read_packets(data, xtce=support["xtce"]))
    for side, sec in enumerate(sections):
        rows = dec.secondary == bool(side)
        np.testing.assert_array_equal(dec.counts[rows], sec.counts.reshape(-1, 3))
        np.testing.assert_array_equal(dec.range[rows], sec.ranges.reshape(-1))


def test_team_xtce_reads_the_simulated_packets_alike(tmp_path, support):
    if not XTCE.is_file():
        pytest.skip(f"the IMAP team's XTCE is not at {XTCE}")
    path, truth, _ = _run(tmp_path, support, (0, 16, 18, 13), hours=0.02,
                          burst_minutes=0.5)
    l1a = process([path], level="l1a", kernels=support["kernels"], xtce=XTCE)
    for key, t in truth.items():
        _check_l1a(l1a[key], t)


def _team_python() -> str | None:
    """A Python that imports ``imap_processing`` (FLUXCAL_TEAM_PYTHON, /work/venv-imap)."""
    for exe in (os.environ.get("FLUXCAL_TEAM_PYTHON", ""), "/work/venv-imap/bin/python"):
        if exe and Path(exe).is_file() and subprocess.run(
                [exe, "-c", "import imap_processing.mag.l1a.mag_l1a"],
                capture_output=True, timeout=120).returncode == 0:
            return exe
    return None


_TEAM_SCRIPT = """
import sys, numpy as np, spiceypy, cdflib, xarray as xr
from pathlib import Path
spiceypy.furnsh(sys.argv[1]); spiceypy.furnsh(sys.argv[2])
from imap_processing.mag.l1a.mag_l1a import mag_l1a
from imap_processing.mag.l1b.mag_l1b import mag_l1b
day = np.datetime64("2025-10-17", "ns")
c = cdflib.CDF(sys.argv[4])
cal = xr.Dataset({n: (("epoch", "row", "col", "range"), c.varget(n)[None])
                  for n in ("MFOTOURFO", "MFITOURFI")}
                 | {n: (("epoch",), np.atleast_1d(c.varget(n))) for n in ("OTS", "ITS")},
                 coords={"epoch": [day]})
out = {}
for ds in mag_l1a(Path(sys.argv[3])):
    if "vectors" in ds:
        key = ds.attrs["Logical_source"].split("_")[-1]
        out[key + "_vectors"] = ds["vectors"].values
        out[key + "_flags"] = ds["compression_flags"].values
        out[key + "_b"] = mag_l1b(ds, day, cal)["vectors"].values
np.savez(sys.argv[5], **out)
"""


def test_the_teams_l1a_and_l1b_read_the_simulated_packets(tmp_path, support):
    """The team's own L1A and L1B (imap-processing, in its own interpreter) get the truth.

    L1A: counts, ranges and compression flags exactly; L1B with fluxcal's simulated
    calibration file: the field within the same half-count bound as fluxcal's.
    """
    exe = _team_python()
    if exe is None or not LSK.is_file():
        pytest.skip("the IMAP team's package (imap-processing) or ../shared's LSK is "
                    "missing: set FLUXCAL_TEAM_PYTHON to a Python that has it")
    path, truth, _ = _run(tmp_path, support, (0, 16, 18, 13), hours=0.05, burst_minutes=1)
    out = tmp_path / "team.npz"
    res = subprocess.run([exe, "-c", _TEAM_SCRIPT, str(LSK), str(support["kernels"]),
                          str(path), str(support["calib"]), str(out)], capture_output=True,
                         text=True, timeout=900)
    assert res.returncode == 0, res.stderr[-2000:]
    team = np.load(out)
    for (mode, sensor), t in truth.items():
        v, flags = team[f"{mode}-{sensor}_vectors"], team[f"{mode}-{sensor}_flags"]
        np.testing.assert_array_equal(v[:, :3], t.counts)
        np.testing.assert_array_equal(v[:, 3], t.ranges)
        np.testing.assert_array_equal(flags[:, 0], t.compression)
        np.testing.assert_array_equal(flags[:, 1], t.width)
        b = team[f"{mode}-{sensor}_b"][:, :3]
        assert np.all(np.abs(b - t.b_nt) <= simulate.quantisation_bound(t, sensor) + 1e-9)


def test_cli_simulate_then_calibrate(tmp_path):
    from fluxcal.cli import app

    sim = tmp_path / "sim"
    res = CliRunner().invoke(app, ["simulate", "imap", "--out", str(sim), "--hours", "0.02",
                                   "--burst-minutes", "0.5", "--widths", "0,18"])
    assert res.exit_code == 0, res.output
    assert "run: fluxcal imap calibrate" in res.output
    truth = {p.stem: p for p in (sim / "truth").glob("*.csv")}
    assert set(truth) == {"20251017_norm-mago", "20251017_norm-magi", "20251017_burst-mago",
                          "20251017_burst-magi"}
    out = tmp_path / "out"
    packets = sim / simulate.packet_file_name(datetime.date(2025, 10, 17))
    res = CliRunner().invoke(app, [
        "imap", "calibrate", "--input", str(packets),
        "--kernels", str(sim / simulate.SCLK_NAME), "--calib", str(sim / simulate.CALIB_NAME),
        "--xtce", str(sim / simulate.XTCE_NAME), "--out", str(out)])
    assert res.exit_code == 0, res.output
    assert len(list(out.glob("imap_mag_l1b_*_20251017_v001.cdf"))) == 4
    res = CliRunner().invoke(app, ["simulate", "imap", "--out", str(sim), "--widths", "3"])
    # fluxcal.cli.main prints this one line and exits 2
    assert isinstance(res.exception, InputFormatError) and "--widths" in str(res.exception)


def test_demo_runs_on_the_forward_model_without_the_teams_files(tmp_path, monkeypatch):
    from fluxcal.missions.imap import demo

    monkeypatch.setattr(demo, "shared_folder", lambda: None)
    monkeypatch.setattr(demo, "SIM_HOURS", 0.05)
    text = demo.run_quick_demo(tmp_path)
    assert "simulated packets" in text and "were not found" in text
    share = float(text.split(" % of half a count")[0].rsplit(", ", 1)[1])
    assert 50.0 < share <= 100.0
    assert len(list(tmp_path.glob("imap_mag_l1b_*.cdf"))) == 4


def test_batch_on_simulated_days_uses_the_folders_support_files(tmp_path):
    """``fluxcal batch imap`` over the simulator's batch layout, no file option given."""
    import json

    import cdflib

    from fluxcal.cli import main

    days = [datetime.date(2025, 10, 17), datetime.date(2025, 10, 18)]
    simulate.simulate_days(tmp_path / "in", days, hours=0.02, burst_minutes=0.5)
    assert main(["batch", "imap", "--start", "2025-10-16", "--end", "2025-10-18",
                 "--input", str(tmp_path / "in"), "--out", str(tmp_path / "out"),
                 "--scheduler", "serial", "--quiet"]) == 0
    report = json.loads((tmp_path / "out" / "batch_report_imap.json").read_text())
    assert report["counts"]["done"] == 2 and report["counts"]["no_data"] == 1
    for k, day in enumerate(days):
        _, truth, _ = simulate.simulate_day(f"{day}T00:00:00", 0.02, 0.5, seed=k)
        for (mode, sensor), t in truth.items():
            cdf = cdflib.CDF(str(tmp_path / "out" /
                                 f"imap_mag_l1b_{mode}-{sensor}_{day:%Y%m%d}_v001.cdf"))
            b, epoch = cdf.varget("b"), cdf.varget("epoch")
            assert np.all(np.abs(b - t.b_nt) <= simulate.quantisation_bound(t, sensor)
                          + 1e-9)
            assert np.abs(epoch - t.epoch_b).max() <= 1


def test_a_failed_simulation_leaves_no_file(tmp_path, monkeypatch):
    def full(*args, **kwargs):  # after the support files are written
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(simulate, "simulate_day", full)
    with pytest.raises(OSError):
        simulate.write_simulation(tmp_path / "sim", hours=0.02)
    assert not [p for p in (tmp_path / "sim").rglob("*") if p.is_file()]
    with pytest.raises(OSError):
        simulate.simulate_days(tmp_path / "in", [datetime.date(2025, 10, 17)])
    assert not [p for p in (tmp_path / "in").rglob("*") if p.is_file()]


def _split_packets(data: bytes) -> list[bytes]:
    """Whole packets of a stream by their CCSDS length (written here, not the decoder's)."""
    out, pos = [], 0
    while pos < len(data):
        end = pos + 7 + int.from_bytes(data[pos + 4:pos + 6], "big")
        out.append(data[pos:end])
        pos = end
    return out


def test_gaps_and_a_day_boundary(tmp_path, support):
    """Every third packet lost, data across midnight: the rest comes back, split by UTC day."""
    from fluxcal.missions.imap.products import products
    from fluxcal.products.declared import write_declared

    data, truth, _ = simulate.simulate_day("2025-10-17T23:54:00", 0.2, 1.0, widths=(0, 18))
    packets = _split_packets(data)
    assert b"".join(packets) == data
    kept = [p for k, p in enumerate(packets) if k % 3 != 1]
    lost = {(int.from_bytes(p[:2], "big") & 0x7FF, int.from_bytes(p[2:4], "big") & 0x3FFF)
            for k, p in enumerate(packets) if k % 3 == 1}
    path = tmp_path / "gappy.pkts"
    path.write_bytes(b"".join(kept))
    l1b = process([path], level="l1b", calib=support["calib"], kernels=support["kernels"],
                  xtce=support["xtce"])
    for (mode, sensor), t in truth.items():
        apid = sim_packets.APIDS[mode]
        keep = np.array([(apid, int(s)) not in lost for s in t.sequence])
        assert 0 < keep.sum() < keep.size
        ds = l1b[(mode, sensor)]
        np.testing.assert_array_equal(ds["sequence"].values, t.sequence[keep])
        assert np.all(np.abs(ds["b"].values - t.b_nt[keep])
                      <= simulate.quantisation_bound(t, sensor)[keep] + 1e-9)
    paths = write_declared(products(l1b), tmp_path / "out", lambda product: {})
    days = {p.name.split("_")[-2] for p in paths}
    assert days == {"20251017", "20251018"}
