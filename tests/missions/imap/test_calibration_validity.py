"""IMAP L1B products say why their calibration is not valid (issue 31).

The team's calibration file is valid 2024-01-01 .. 2024-12-31; the ground-test packets
are of 2023-10-25 and 2023-11-30, so every demo product is ``calibration_valid: no``
(docs/decisions/imap.md decision 7: recorded, not refused).  The product now says how
many samples, over which span, against which validity, and that the matrices were
applied as given; the HTML report shows it as a warning.  Expected times come from
cdflib's own TT2000 conversion, not from fluxcal's.
"""

from __future__ import annotations

from pathlib import Path

import cdflib
import numpy as np

from fluxcal.missions.imap.calibration import MagCalibration
from fluxcal.missions.imap.l1b import validity_attrs
from fluxcal.products.html_report import ProductFile, Quality, render


def _tt2000(*fields: int) -> int:
    return int(cdflib.cdfepoch.compute_tt2000([*fields, 0, 0, 0, 0][:9]))


CAL = MagCalibration(matrices={}, time_shift_ns={}, valid_from=_tt2000(2024, 1, 1, 0, 0, 0),
                     valid_to=_tt2000(2024, 12, 31, 0, 0, 0), path=Path("cal_v01.cdf"))
SPAN = "cal_v01.cdf: 2024-01-01T00:00:00 .. 2024-12-31T00:00:00 UTC"


def _inside(epoch: np.ndarray) -> np.ndarray:
    return (epoch >= CAL.valid_from) & (epoch <= CAL.valid_to)


def test_valid_calibration_says_yes_and_its_validity() -> None:
    epoch = np.array([_tt2000(2024, 6, 1, 0, 0, s) for s in range(3)], dtype=np.int64)
    assert validity_attrs(epoch, _inside(epoch), CAL) == {
        "calibration_valid": "yes", "calibration_validity": SPAN}


def test_samples_outside_the_validity_are_counted_with_their_span() -> None:
    # two before the validity (2023), one inside, one after (2025): both sides
    epoch = np.array([_tt2000(2023, 10, 25, 18, 30, 19), _tt2000(2023, 11, 30, 19, 9, 4),
                      _tt2000(2024, 6, 1, 0, 0, 0), _tt2000(2025, 2, 6, 12, 5, 0)],
                     dtype=np.int64)
    attrs = validity_attrs(epoch, _inside(epoch), CAL)
    assert attrs["calibration_validity"] == SPAN
    assert attrs["calibration_valid"] == (
        "no: 3 of 4 samples (2023-10-25T18:30:19 .. 2025-02-06T12:05:00 UTC) are outside "
        "the calibration file's validity (see calibration_validity); its matrices were "
        "applied as given")
    # whole in the report's cell (which cuts a value at 200 characters)
    assert len(attrs["calibration_valid"]) < 200


def test_report_shows_an_invalid_calibration_as_a_warning() -> None:
    q = Quality(samples=4, attributes={"calibration_valid": "no: 3 of 4 samples ...",
                                       "calibration_validity": SPAN})
    product = ProductFile("x.cdf", Path("x.cdf"), "CDF", 1)
    page = render("t", [product], [([product], q)], 1)
    assert '<span class="warn">calibration_valid: no: 3 of 4 samples ...</span>' in page
    assert f"calibration_validity: {SPAN}" in page
    ok = Quality(samples=4, attributes={"calibration_valid": "yes"})
    assert '<span class="warn">calibration_valid' not in render("t", [product],
                                                               [([product], ok)], 1)
