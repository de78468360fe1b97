"""Every L1a and L1b validation case of the IMAP MAG team, by both input routes.

The cases are listed in ``../shared/data/imap/team/MANIFEST.tsv`` (the team's
``tests/mag/validation``, MIT License): L1a T001-T008 (one packet in, the L1A CSV out:
uncompressed, compressed at widths 13 and 18, range changes inside the packet, the
switch to uncompressed values after a vector longer than 60 bits), L1b T009-T012 (the
packet ``data.bin`` and the L1A CSV in, MAGo and MAGi nT out; T012 with its own
calibration).  Expected values are the team's files, compared the team's way
(``tests/mag/test_mag_validation.py`` in imap_processing): counts, ranges,
coarse/fine, sequence and flags exactly (the width where the vectors are compressed),
the field to 1e-9 nT, times to 16 us: the expected times divide the fine time by 65535
where fluxcal reads the clock exactly (/65536), up to 15.3 us later
(docs/decisions/imap.md).
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest

from fluxcal.geometry.time import utc_to_tt2000
from fluxcal.missions.imap import l1a, l1b
from fluxcal.missions.imap.calibration import load_calibration
from fluxcal.missions.imap.packets import read_packets, vectors_per_second
from tests.missions.imap.conftest import TEAM, XTCE, team_cases

#: Times: the 65535/65536 readings differ by at most 15.26 us; the expected L1b times are
#: printed to the microsecond.
TIME_TOLERANCE_NS = 16_000
FIELD_TOLERANCE_NT = 1e-9
L1B_CALIBRATION = "calibration/imap_mag_l1b-calibration_20240229_v001.cdf"


def _rows(path: Path) -> dict[str, np.ndarray]:
    with path.open(newline="") as fh:
        rows = list(csv.DictReader(fh))
    return {k: np.array([r[k] for r in rows]) for k in rows[0]}


def _ints(values: np.ndarray) -> np.ndarray:
    return values.astype(np.int64)


def _layout(path: Path) -> str:
    """The ``--csv-layout`` of a packet file's packets (mode, rates, seconds)."""
    p = read_packets(path, xtce=XTCE)
    mode = "normal" if int(p.fields["PKT_APID"][0]) == 1052 else "burst"
    pri, sec = (int(vectors_per_second(p.fields[f"{s}_VECSEC"][0])) for s in ("PRI", "SEC"))
    return f"{mode}-({pri},{sec})-{int(p.fields['PUS_SSUBTYPE'][0]) + 1}s"


def _check_flags(ds, compression: np.ndarray, width: np.ndarray) -> None:
    np.testing.assert_array_equal(ds["compression"].values, compression)
    on = compression == 1
    np.testing.assert_array_equal(ds["compression_width"].values[on], width[on])


@pytest.mark.parametrize("case", team_cases("L1a"))
def test_l1a_case_by_packets_and_by_the_l1a_csv(case: str, imap_data: Path, clock) -> None:
    folder = TEAM / "L1a" / case
    number = case[1:].lower()
    packets_in = folder / f"mag-l0-l1a-t{number}-in.bin"
    expected = folder / f"mag-l0-l1a-t{number}-out.csv"
    team = _rows(expected)
    packets = read_packets(packets_in, xtce=XTCE)
    from_packets = l1a.from_packets(packets, clock)
    from_csv = l1a.read_l1a_csv(expected, clock, layout=_layout(packets_in))
    mago_primary = int(packets.fields["PRI_SENS"][0]) == 0
    for side in ("pri", "sec"):
        sensor = "mago" if (side == "pri") == mago_primary else "magi"
        for route in (from_packets, from_csv):
            ds = route[("norm", sensor)]
            assert ds.sizes["time"] == team["sequence"].size
            np.testing.assert_array_equal(
                ds["counts"].values, np.stack([_ints(team[f"{a}_{side}"]) for a in "xyz"], 1))
            np.testing.assert_array_equal(ds["range"].values, _ints(team[f"rng_{side}"]))
            np.testing.assert_array_equal(ds["coarse"].values, _ints(team[f"{side}_coarse"]))
            np.testing.assert_array_equal(ds["fine"].values, _ints(team[f"{side}_fine"]))
            np.testing.assert_array_equal(ds["sequence"].values, _ints(team["sequence"]))
            _check_flags(ds, _ints(team["compression"]), _ints(team["compression_width_bits"]))
        # the team's time of the packet's first vector: coarse + fine/65535 s
        ds = from_packets[("norm", sensor)]
        coarse, fine = int(team[f"{side}_coarse"][0]), int(team[f"{side}_fine"][0])
        exact = int(ds["epoch"].values[0])
        whole = int(l1a.vector_tt2000(clock, np.array([coarse]), np.array([0]),
                                      np.array([0]), np.array([1]))[0])
        assert abs(exact - (whole + round(fine * 1e9 / 65535))) <= TIME_TOLERANCE_NS
        np.testing.assert_array_equal(from_csv[("norm", sensor)]["epoch"].values,
                                      ds["epoch"].values)


@pytest.mark.parametrize("route", ["packets", "l1a_csv"])
@pytest.mark.parametrize("case", team_cases("L1b"))
def test_l1b_case(case: str, route: str, imap_data: Path, clock) -> None:
    folder = TEAM / "L1b" / case
    number = case[1:].lower()
    own = folder / f"mag-l1a-l1b-t{number}-cal.cdf"
    cal = load_calibration(own if own.is_file() else TEAM / L1B_CALIBRATION)
    if route == "packets":
        sets = l1a.from_packets(read_packets(folder / "data.bin", xtce=XTCE), clock)
    else:
        (named,) = folder.glob("MAGScience-*.csv")
        sets = l1a.read_l1a_csv(named, clock)
    for sensor in ("mago", "magi"):
        team = _rows(folder / f"mag-l1a-l1b-t{number}-{sensor}-out.csv")
        ds = l1b.calibrate(sets[("norm", sensor)], cal)
        b = np.stack([team[a].astype(float) for a in "xyz"], axis=1)
        assert np.abs(ds["b"].values - b).max() <= FIELD_TOLERANCE_NT
        for name, column in (("range", "range"), ("coarse", "coarse"), ("fine", "fine"),
                             ("sequence", "sequence")):
            np.testing.assert_array_equal(ds[name].values, _ints(team[column]))
        _check_flags(ds, _ints(team["compression"]), _ints(team["compression_width"]))
        dt = utc_to_tt2000(team["t"]) - ds["epoch"].values
        assert np.abs(dt).max() <= TIME_TOLERANCE_NS
        # and the whole difference is the 65535 reading, the expected times being cut
        # (not rounded) to the microsecond: 0..1 us below it
        fine = ds["fine"].values
        rest = dt - (np.rint(fine * 1e9 / 65535) - np.rint(fine * 1e9 / 65536))
        assert np.all((rest <= 1) & (rest > -1000))
