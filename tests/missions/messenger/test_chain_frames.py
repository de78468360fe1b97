"""Frame keys are checked once (`chain.check_frames`), before any work."""

from __future__ import annotations

import pytest

from fluxcal.errors import InputFormatError
from fluxcal.missions.messenger.chain import check_frames


def test_every_product_frame_is_accepted():
    # the frame keys of docs/formats/messenger.md (MSO, J2000, MBF, RTN, SC, VSO)
    check_frames(("mso", "j2000", "mbf", "rtn", "sc", "vso"))
    check_frames(())


@pytest.mark.parametrize("frames", [("mso", "xyz"), ("MSO",), ("gse", "rtn")])
def test_an_unknown_frame_is_refused_naming_it(frames):
    with pytest.raises(InputFormatError) as err:
        check_frames(frames)
    assert err.value.field == "frames"
    bad = [f for f in frames if f not in ("mso", "rtn")]
    assert all(repr(b) in str(err.value) for b in bad)
