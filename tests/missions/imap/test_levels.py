"""IMAP MAG L1A and L1B against the team's outputs (mag_l1a_test_output.csv, T010).

The team's validation cases T001-T012 are in test_team_cases.py.
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest
import spiceypy

from fluxcal.errors import CalibrationError, InputFormatError
from fluxcal.missions.imap import l1a
from fluxcal.missions.imap.calibration import load_calibration
from fluxcal.missions.imap.packets import read_packets
from tests.missions.imap.conftest import CALIBRATION, T010_L1A, XTCE


def _rows(path: Path) -> dict[str, np.ndarray]:
    with path.open(newline="") as fh:
        rows = list(csv.DictReader(fh))
    return {k: np.array([r[k] for r in rows]) for k in rows[0]}


def test_l1a_from_packets_matches_the_team_exactly(imap_data: Path, clock) -> None:
    out = l1a.from_packets(read_packets(imap_data / "mag_l1_test_data.pkts", xtce=XTCE), clock)
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
    out = l1a.from_packets(read_packets(imap_data / "mag_l1_test_data.pkts", xtce=XTCE), clock)
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


def test_l1b_matrices_read_from_the_cdf(imap_data: Path) -> None:
    import cdflib

    cal = load_calibration(CALIBRATION)
    raw = cdflib.CDF(str(CALIBRATION))
    np.testing.assert_array_equal(cal.matrices["mago"][2], raw.varget("MFOTOURFO")[:, :, 2])
    np.testing.assert_array_equal(cal.matrices["magi"][0], raw.varget("MFITOURFI")[:, :, 0])
    assert cal.time_shift_ns == {"mago": 0, "magi": 0}


def test_l1b_without_a_calibration_says_what_to_give() -> None:
    with pytest.raises(CalibrationError, match="--calib: L1B needs the IMAP MAG team's "
                       "calibration CDF.*give --calib PATH"):
        load_calibration(None)


def test_l1a_csv_is_recognised_by_content_under_any_name(tmp_path: Path, clock) -> None:
    named = l1a.read_l1a_csv(T010_L1A, clock)
    other = tmp_path / "t010-input.txt"
    other.write_bytes(T010_L1A.read_bytes())
    assert l1a.csv_header(other) is not None
    assert l1a.csv_header(XTCE) is None
    # the mode and rates are only in the team's names: without one, the user says them
    with pytest.raises(InputFormatError, match="t010-input.txt: the team's L1A CSV layout, "
                       "but its name does not give.*--csv-layout"):
        l1a.read_l1a_csv(other, clock)
    renamed = l1a.read_l1a_csv(other, clock, layout="normal-(2,2)-8s")
    for key, ds in named.items():
        assert renamed[key].identical(ds)
    with pytest.raises(InputFormatError, match="field '--csv-layout'.*not <normal|burst>"):
        l1a.read_l1a_csv(other, clock, layout="normal-2-8s")


def test_csv_layout_errors_name_file_line_and_field(tmp_path: Path, clock) -> None:
    bad = tmp_path / "vectors.csv"
    bad.write_text("sequence\n1\n")
    with pytest.raises(InputFormatError, match="vectors.csv, line 1: not the team's L1A CSV"):
        l1a.read_l1a_csv(bad, clock)
    text = T010_L1A.read_text().replace(",1,16", ",1,24", 1)
    named = tmp_path / T010_L1A.name
    named.write_text(text)
    with pytest.raises(InputFormatError, match="line 2, field 'compression': compression 1 "
                       "with width 24"):
        l1a.read_l1a_csv(named, clock)
    short = tmp_path / "MAGScience-normal-(1,1)-8s-20250206-12h05.csv"
    short.write_text(T010_L1A.read_text())
    with pytest.raises(InputFormatError, match="line 10, field 'pri_coarse'"):
        l1a.read_l1a_csv(short, clock)
