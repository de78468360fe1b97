"""IMAP MAG L1A and L1B against the team's outputs (mag_l1a_test_output.csv, T010)."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest
import spiceypy

from fluxcal.errors import InputFormatError
from fluxcal.geometry.time import utc_to_tt2000
from fluxcal.missions.imap import l1a, l1b
from fluxcal.missions.imap.calibration import load_calibration
from fluxcal.missions.imap.packets import read_packets
from tests.missions.imap.conftest import T010, T010_L1A


def _rows(path: Path) -> dict[str, np.ndarray]:
    with path.open(newline="") as fh:
        rows = list(csv.DictReader(fh))
    return {k: np.array([r[k] for r in rows]) for k in rows[0]}


def test_l1a_from_packets_matches_the_team_exactly(imap_data: Path, clock) -> None:
    out = l1a.from_packets(read_packets(imap_data / "mag_l1_test_data.pkts"), clock)
    team = _rows(imap_data / "mag_l1a_test_output.csv")
    for side, sensor in (("pri", "mago"), ("sec", "magi")):
        ds = out[("norm", sensor)]
        assert ds.sizes["time"] == team["sequence"].size == 96
        for j, axis in enumerate("xyz"):
            np.testing.assert_array_equal(ds["counts"].values[:, j],
                                          team[f"{axis}_{side}"].astype(np.int64))
        np.testing.assert_array_equal(ds["range"].values, team[f"rng_{side}"].astype(int))
        np.testing.assert_array_equal(ds["coarse"].values, team[f"{side}_coarse"].astype(int))
        np.testing.assert_array_equal(ds["fine"].values, team[f"{side}_fine"].astype(int))
        np.testing.assert_array_equal(ds["sequence"].values, team["sequence"].astype(int))


def test_l1a_times_follow_the_sclk_kernel(imap_data: Path, clock) -> None:
    out = l1a.from_packets(read_packets(imap_data / "mag_l1_test_data.pkts"), clock)
    ds = out[("norm", "mago")]
    first = ds["vector_index"].values == 0
    coarse, fine = ds["coarse"].values[first], ds["fine"].values[first]
    # the SPICE toolkit's own conversion of the same clock readings (float ET: ~0.1 us)
    et = np.array([spiceypy.sct2e(-43, float(c) * 50000 + f * 50000 / 65536)
                   for c, f in zip(coarse.tolist(), fine.tolist(), strict=True)])
    tt = np.array([spiceypy.unitim(e, "TDB", "TT") for e in et])
    np.testing.assert_allclose(ds["epoch"].values[first] / 1e9, tt, rtol=0, atol=2e-7)
    # vectors 2 per second within a packet, exactly 0.5 s apart (clock rate 1 here)
    steps = np.diff(ds["epoch"].values.reshape(-1, 16), axis=1)
    assert np.all(steps == 500_000_000)


def test_l1a_csv_route_and_l1b_match_t010(imap_data: Path, clock) -> None:
    cal = load_calibration(imap_data / "imap_calibration_mag_20240229_v01.cdf")
    out = l1a.read_l1a_csv(T010_L1A, clock)
    for sensor in ("mago", "magi"):
        team = _rows(T010 / f"mag-l1a-l1b-t010-{sensor}-out.csv")
        ds = l1b.calibrate(out[("norm", sensor)], cal)
        b = np.stack([team[a].astype(float) for a in "xyz"], axis=1)
        assert np.abs(ds["b"].values - b).max() <= 1e-9
        np.testing.assert_array_equal(ds["range"].values, team["range"].astype(int))
        np.testing.assert_array_equal(ds["compression_width"].values,
                                      team["compression_width"].astype(int))
        # the team's times are printed to the microsecond
        dt = utc_to_tt2000(team["t"]) - ds["epoch"].values
        fine = ds["fine"].values
        if sensor == "mago":  # the exact clock reading, coarse + fine/65536 s
            assert np.all(np.abs(dt) <= 500)
        else:  # MAGi: the team divides the fine time by 65535 (docs/decisions/imap.md)
            team_offset = np.rint(fine * 1e9 / 65535) - np.rint(fine * 1e9 / 65536)
            assert np.all(team_offset > 15_000)
            assert np.all(np.abs(dt - team_offset) <= 500)


def test_l1b_matrices_read_from_the_cdf(imap_data: Path) -> None:
    cal = load_calibration()  # the shipped copy
    import cdflib

    raw = cdflib.CDF(str(imap_data / "imap_calibration_mag_20240229_v01.cdf"))
    np.testing.assert_array_equal(cal.matrices["mago"][2], raw.varget("MFOTOURFO")[:, :, 2])
    np.testing.assert_array_equal(cal.matrices["magi"][0], raw.varget("MFITOURFI")[:, :, 0])
    assert cal.time_shift_ns == {"mago": 0, "magi": 0}


def test_csv_layout_errors_name_file_line_and_field(tmp_path: Path, clock) -> None:
    bad = tmp_path / "vectors.csv"
    bad.write_text("sequence\n1\n")
    with pytest.raises(InputFormatError, match="MAGScience"):
        l1a.read_l1a_csv(bad, clock)
    text = T010_L1A.read_text().replace("x_pri", "xx")
    named = tmp_path / T010_L1A.name
    named.write_text(text)
    with pytest.raises(InputFormatError, match="line 1, field 'x_pri'"):
        l1a.read_l1a_csv(named, clock)
    short = tmp_path / "MAGScience-normal-(1,1)-8s-20250206-12h05.csv"
    short.write_text(T010_L1A.read_text())
    with pytest.raises(InputFormatError, match="line 10, field 'pri_coarse'"):
        l1a.read_l1a_csv(short, clock)
