"""A frame's field and position from J2000 (`levels.frame_variables`, issue 10 item 8).

A run is calibrated with the J2000 field only; each product frame's field and position
are evaluated when that frame is written, by the function `levels.add_geometry` uses
for every frame but J2000 and SC.  Checked against SPICE per sample (``pxform``/
``spkpos``, independent of fluxcal's interpolated legs), against the compiled passes
of the former `add_geometry` (`compiled.attitude_frames` and the per-leg loops: equal
bit for bit), against the run calibrated with every frame, and end to end: the products of
both runs are byte-identical files.
"""

import logging

import numpy as np
import pytest
import spiceypy

from fluxcal.errors import InputFormatError
from fluxcal.geometry.kernels import KernelPool
from fluxcal.missions.messenger import levels
from fluxcal.missions.messenger.chain import calibrate
from fluxcal.missions.messenger.levels import (
    calibration_frames,
    frame_variables,
    note_mbf_rotation,
)
from fluxcal.missions.messenger.products import day_products
from fluxcal.missions.messenger.run import RAW_UNWRITTEN, calibrate_run
from fluxcal.products.declared import write_declared

ALL = ("mso", "j2000", "mbf", "rtn", "sc", "vso")


@pytest.fixture(scope="module")
def runs(messenger_kernels, simulated, calibration):
    """The same samples calibrated with J2000 only and with every frame (kernels loaded)."""
    sci = simulated["science"].isel(time=slice(0, None, 50))  # 20 Hz -> ~0.4 Hz, every rate
    with KernelPool(messenger_kernels):
        only = calibrate(sci, simulated["heater"], simulated["temperature"], calibration,
                         frames=("j2000",), max_offset_step=None, keep_intermediates=False)
        full = calibrate(sci, simulated["heater"], simulated["temperature"], calibration,
                         frames=ALL, max_offset_step=None, keep_intermediates=False)
        yield only, full


def test_calibration_frames():
    assert calibration_frames(("mso", "rtn")) == ("j2000",)
    assert calibration_frames(("mso", "j2000", "mbf", "rtn", "sc")) == ("j2000", "sc")
    assert calibration_frames(("sc",)) == ("sc",)  # the SC field needs no J2000 leg
    assert calibration_frames(()) == ()


@pytest.mark.parametrize("frame", ["mso", "mbf", "rtn", "vso"])
def test_frame_equals_the_run_calibrated_with_it(runs, frame):
    only, full = runs
    assert f"b_{frame}" not in only
    got = frame_variables(only, frame)
    # the same interpolated legs on the same samples: equal bit for bit
    np.testing.assert_array_equal(got[f"b_{frame}"].values, full[f"b_{frame}"].values)
    # add_geometry also notes the MBF rotation model on b_mbf (no product reads it)
    expected = {k: v for k, v in full[f"b_{frame}"].attrs.items() if k != "rotation_model"}
    assert got[f"b_{frame}"].attrs == expected
    pos = {"mso": "pos_mso", "mbf": "pos_mbf", "rtn": "pos_rtn", "vso": "pos_vso"}[frame]
    if frame != "vso":  # (add_geometry is not asked for VSO in ``runs``)
        np.testing.assert_array_equal(got[pos].values, full[pos].values)
        assert got[pos].attrs == full[pos].attrs


def test_add_geometry_equals_one_fused_pass_through_every_leg(runs):
    """Every frame equals the compiled passes add_geometry used before the frames came
    from J2000 through `frame_variables` (`compiled.attitude_frames` through the MSO leg,
    `compiled.slerp_rotate` through the MBF leg, `compiled.rtn_rotate`): the same
    operations in the same order, bit for bit."""
    from fluxcal.geometry import compiled
    from fluxcal.geometry.frames import Rotator
    from fluxcal.geometry.positions import position

    _, full = runs
    et = np.ascontiguousarray(full["et"].values)
    n = et.size
    got = {k: np.empty((n, 3)) for k in ("b_j2000", "pos_mso", "b_mso", "pos_mbf", "b_mbf",
                                         "b_rtn")}
    sun_sc = np.empty((n, 3))  # (not kept in ``runs``: keep_intermediates=False)
    # under the pool ``runs`` loaded (a nested KernelPool reloads the kernels, and the
    # legs built then may differ in the last bits: 3e-9 nT seen)
    leg = Rotator("MSGR_SPACECRAFT", et).leg_table
    pole = np.ascontiguousarray(spiceypy.pxform("IAU_SUN", "J2000", float(et[0]))[:, 2:].T)
    assert np.array_equal(pole, spiceypy.pxform("IAU_SUN", "J2000", float(et[-1]))[:, 2:].T)
    sun = np.ascontiguousarray(full["pos_j2000"])
    mercury = position("MESSENGER", "MERCURY", "J2000", et)
    compiled.attitude_frames(
        leg("MSGR_SPACECRAFT"), leg("MSGR_MSO"), et, np.ascontiguousarray(full["b_sc"].values),
        sun, mercury, got["b_j2000"], sun_sc, (got["pos_mso"], got["b_mso"]))
    compiled.slerp_rotate(*compiled.IDENTITY_TABLE, *leg("IAU_MERCURY"), et,
                          (mercury, got["b_j2000"]), (False, False),
                          (got["pos_mbf"], got["b_mbf"]))
    compiled.rtn_rotate(sun, pole, got["b_j2000"], got["b_rtn"])
    for name, values in got.items():
        np.testing.assert_array_equal(full[name].values, values, err_msg=name)


def test_add_geometry_vso_is_frame_variables(runs, calibration, simulated):
    """VSO's field and (Venus) position from add_geometry are those the writer computes."""
    only, _ = runs
    sci = simulated["science"].isel(time=slice(0, None, 50))
    # under the pool ``runs`` loaded, as ``only`` (see the test above)
    vso = calibrate(sci, simulated["heater"], simulated["temperature"], calibration,
                    frames=("vso",), max_offset_step=None, keep_intermediates=False)
    got = frame_variables(only, "vso")
    assert "b_j2000" not in vso and "pos_j2000" not in vso  # not requested: not kept
    for name, var in got.items():
        np.testing.assert_array_equal(vso[name].values, var.values)
        assert vso[name].attrs == var.attrs


@pytest.mark.parametrize("frame", ["mso", "mbf", "rtn", "vso"])
def test_frame_against_spice_per_sample(runs, messenger_kernels, frame):
    only, _ = runs
    et = only["et"].values
    with KernelPool(messenger_kernels):
        got = frame_variables(only, frame)
        spice = levels.FRAMES[frame][0]
        m = np.array([spiceypy.pxform("J2000", spice, float(t)) for t in et])
        expected = np.einsum("nij,nj->ni", m, only["b_j2000"].values)
        # interpolated rotation legs: 5e-10 rad (frames.DEFAULT_TOLERANCE) of |B| < 1e5 nT,
        # 5e-5 nT, with margin
        np.testing.assert_allclose(got[f"b_{frame}"].values, expected, rtol=0, atol=2e-4)
        if frame == "rtn":  # sec. 10.2 distance from the Sun (km); angles: test_geometry_fast
            sun = np.array([spiceypy.spkpos("MESSENGER", float(t), "J2000", "NONE", "SUN")[0]
                            for t in et])
            np.testing.assert_allclose(got["pos_rtn"].values[:, 0],
                                       np.linalg.norm(sun, axis=1), rtol=0, atol=1e-3)
        else:  # 1e-4 km Hermite tolerance plus 5e-10 rad x 1e8 km (VSO), margin
            target = {"mso": "MERCURY", "mbf": "MERCURY", "vso": "VENUS"}[frame]
            expected = np.array([spiceypy.spkpos("MESSENGER", float(t), spice, "NONE", target)[0]
                                 for t in et])
            np.testing.assert_allclose(got[f"pos_{frame}"].values, expected, rtol=0, atol=0.1)


def test_frames_present_are_taken_not_recomputed(runs):
    _, full = runs
    for frame in ("mso", "sc", "j2000", "rtn"):
        got = frame_variables(full, frame)
        for name, var in got.items():
            assert np.shares_memory(var.values, full[name].values)


def test_sc_and_j2000_are_never_recomputed(runs):
    only, _ = runs
    with pytest.raises(InputFormatError, match="b_sc"):
        frame_variables(only, "sc")
    with pytest.raises(InputFormatError, match="b_j2000"):
        frame_variables(only.drop_vars("b_j2000"), "mso")


def test_mbf_note_goes_where_add_geometry_puts_it(runs, messenger_kernels, caplog):
    only, full = runs
    with KernelPool(messenger_kernels), caplog.at_level(logging.WARNING):
        noted = note_mbf_rotation(only, ("mso", "mbf"))
        assert "no mission PCK" in caplog.text
        caplog.clear()
        assert note_mbf_rotation(only, ("mso", "rtn")) is only and not caplog.text
    assert list(noted.attrs) == list(full.attrs)  # same keys, same order (label layout)
    assert "mbf_rotation" not in only.attrs  # the input is not changed


def test_products_equal_to_those_of_a_run_with_every_frame(runs, messenger_kernels, tmp_path,
                                                           monkeypatch):
    """Byte-identical files: frames written from J2000 or from the all-frame run."""
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "0")
    only, full = runs
    frames = ("mso", "mbf", "rtn", "sc", "j2000")
    with KernelPool(messenger_kernels):
        only = note_mbf_rotation(only, frames)
        sc = full[["b_sc"]]
        a, b = (write_declared(day_products(ds, frames, ("tab", "cdf"), (60,)),
                               tmp_path / name, lambda product: {})
                for ds, name in ((only.assign(sc), "a"), (full, "b")))
    assert [p.name for p in a] == [p.name for p in b] and len(a) == 5 * 2 * 3
    for pa, pb in zip(a, b, strict=True):
        assert pa.read_bytes() == pb.read_bytes(), pa.name


def test_calibrate_run_keeps_no_product_frame_and_no_raw_column(messenger_kernels, simulated):
    sci = simulated["science"].isel(time=slice(0, None, 50))
    with KernelPool(messenger_kernels):
        ds, _ = calibrate_run(sci, simulated["heater"], simulated["temperature"],
                              frames=("mso", "rtn"), quicklook_frame="mbf")
    assert {"b_j2000", "pos_j2000", "pos_mso", "offset_nt"} <= set(ds.variables)
    assert not {"b_mso", "b_rtn", "b_mbf", "pos_rtn", "pos_mbf", "b_sc"} & set(ds.variables)
    assert not set(RAW_UNWRITTEN) & set(ds.variables)
    with pytest.raises(InputFormatError, match="quicklook"):
        calibrate_run(sci, simulated["heater"], simulated["temperature"],
                      quicklook_frame="gse")


def test_batch_products_equal_to_those_of_runs_with_every_frame(tmp_path, monkeypatch):
    """``fluxcal batch messenger``: same bytes whether frames come from calibrate or later."""
    import datetime as dt

    from fluxcal.missions.messenger import run
    from fluxcal.missions.messenger.batch_task import make_day_task, simulate_days
    from fluxcal.runs.batch import run_batch

    monkeypatch.setenv("SOURCE_DATE_EPOCH", "0")
    days = [dt.date(2012, 6, 1), dt.date(2012, 6, 2)]
    inp = tmp_path / "in"
    simulate_days(inp, days, seconds_per_day=300.0)
    frames = ("mso", "j2000", "mbf", "rtn", "sc")
    outs, calls = {}, []

    def every_frame(wanted):  # every frame computed by levels.add_geometry up front
        calls.append(wanted)
        return tuple(wanted)

    for mode in ("later", "calibrate"):
        if mode == "calibrate":
            monkeypatch.setattr(run, "calibration_frames", every_frame)
        out = tmp_path / mode
        task = make_day_task(inp, out, formats=("tab", "cdf"), frames=frames,
                             averages=(1, 60))
        report = run_batch(days, task, out, scheduler="serial")
        assert {d.status for d in report.days} == {"done"}, [d.error for d in report.days]
        outs[mode] = {p.name: p.read_bytes() for p in out.iterdir()
                      if p.suffix in (".TAB", ".LBL", ".cdf")}
    assert len(outs["later"]) == 2 * 5 * 3 * 3  # days x frames x (sci + 2 averages) x files
    assert len(calls) == 2 and outs["later"] == outs["calibrate"]
