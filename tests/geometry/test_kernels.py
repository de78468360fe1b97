from __future__ import annotations

import pytest
import spiceypy

from fluxcal.errors import KernelError
from fluxcal.geometry import frames
from fluxcal.geometry import kernels as kernels_mod
from fluxcal.geometry.kernels import KernelPool, frame_defined
from fluxcal.runs import registry


def test_pool_restores_previous_state(shared_kernels):
    before = spiceypy.ktotal("ALL")
    with KernelPool([shared_kernels / "messenger" / "messenger_2548.tsc"]) as pool:
        assert spiceypy.ktotal("ALL") > before
        assert any("messenger_2548.tsc" in f for f in pool.kernel_list())
    assert spiceypy.ktotal("ALL") == before


def test_pool_unloads_after_exception(shared_kernels):
    before = spiceypy.ktotal("ALL")
    with pytest.raises(RuntimeError), KernelPool([]):
        raise RuntimeError("boom")
    assert spiceypy.ktotal("ALL") == before


def test_missing_kernel_names_the_file(tmp_path):
    missing = tmp_path / "nope.bsp"
    with pytest.raises(KernelError, match="nope.bsp"):
        KernelPool([missing])


def test_generic_kernels_come_from_pypi():
    with KernelPool([]):
        # the LSK: 2017-01-01 leap second gives TAI-UTC = 37 s
        et = spiceypy.str2et("2020-01-01T00:00:00")
        assert spiceypy.deltet(et, "ET") == pytest.approx(32.184 + 37, abs=2e-3)
        # DE421: Mercury is within 0.31-0.47 AU of the Sun
        r = spiceypy.vnorm(spiceypy.spkpos("MERCURY", et, "J2000", "NONE", "SUN")[0])
        assert 0.30 * 1.496e8 < r < 0.47 * 1.496e8


def test_fluxcal_frames_loaded_only_when_undefined(shared_kernels):
    # the frames are the caller's (the runner passes the registered missions'; issue 32)
    frames = registry.frame_kernels()
    # ROS_V38.TF defines 67P/C-G_CSEQ itself (id -226910): fluxcal must keep it
    with KernelPool([shared_kernels / "rosetta" / "ROS_V38.TF"], frames=frames):
        assert spiceypy.namfrm("67P/C-G_CSEQ") == -226910
        assert spiceypy.namfrm("MSGR_MSO") == 1499001
    with KernelPool([], frames=frames):
        assert spiceypy.namfrm("67P/C-G_CSEQ") == 1499010
    with KernelPool([], frames=frames, fluxcal_frames=False):
        assert not frame_defined("MSGR_MSO")


def test_pool_without_frames_loads_no_mission_frames(monkeypatch):
    """``KernelPool()`` looks no mission up: no registry scan, no frame (issue 32)."""
    def no_scan(*args, **kwargs):
        raise AssertionError("KernelPool() scanned the mission registry")

    monkeypatch.setattr(registry, "missions", no_scan)
    with KernelPool():
        assert not frame_defined("MSGR_MSO") and not frame_defined("67P/C-G_CSEQ")


def test_unknown_frame_is_kernel_error():
    with KernelPool([]), pytest.raises(KernelError, match="NO_SUCH_FRAME"):
        frames.rotation_matrices("NO_SUCH_FRAME", "J2000", [0.0, 1.0])


def test_time_outside_coverage_is_kernel_error(messenger_kernels):
    with KernelPool([messenger_kernels]):
        et = spiceypy.str2et("2013-06-01T00:00:00")  # a year after the synthetic CK
        with pytest.raises(KernelError, match=r"MSGR_MAG.*2013-06-01.*msgr_synthetic_sc\.bc"):
            frames.rotation_matrices("MSGR_MAG", "J2000", [et, et + 1.0])


def test_nested_pool_restores_the_outer_pool():
    # SPICE keeps one copy of a file: an inner pool loading the same generic kernels must
    # not leave the outer pool without them when it exits
    before = kernels_mod.loaded_kernels()
    with KernelPool([]) as outer:
        files_outer = outer.kernel_list()
        with KernelPool([]):
            pass
        assert sorted(outer.kernel_list()) == sorted(files_outer)
        # the outer pool still works: DE421 and the leapseconds are there
        et = spiceypy.str2et("2020-01-01T00:00:00")
        spiceypy.spkpos("MERCURY", et, "J2000", "NONE", "SUN")
    assert kernels_mod.loaded_kernels() == before
