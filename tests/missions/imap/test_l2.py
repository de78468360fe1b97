"""IMAP MAG L2 (issue 33 item 3): the team's matrices and offsets, sensor and SRF frames.

The team's L2 files for 2025-10-17 hold unit matrices and zero offsets, so L2 there equals
the L1B exactly; the calibration itself is checked with non-trivial matrices and offsets
written here in the team's layout, against an explicit loop over 300 vectors (written
apart from fluxcal's lookup) and against the team's own package.  The SRF rotation is
checked against direct ``pxform`` calls with a frames kernel written here.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import spiceypy
from cdflib.cdfwrite import CDF as CDFWriter
from typer.testing import CliRunner

from fluxcal.errors import InputFormatError
from fluxcal.geometry.kernels import KernelPool
from fluxcal.missions.imap import l2
from fluxcal.missions.imap.cli import app
from fluxcal.missions.imap.team_layout import from_team, to_team
from fluxcal.products.cdf import write_cdf_as_is
from tests.missions.imap._levels import run_team, team_dir

DAY = "2025-10-17"
RNG = np.random.default_rng(20251017)
# a 3x3 matrix per range: non-symmetric, both signs, gains 0.9-1.1
MATS = np.stack([np.eye(3) * (0.9 + 0.05 * r) + RNG.uniform(-0.05, 0.05, (3, 3))
                 for r in range(4)])


def _files() -> tuple[Path, Path, Path]:
    team = team_dir()
    return (team / "L2" / "imap_mag_l1b_norm-mago_20251017_v002.cdf",
            team / "calibration" / "imap_mag_l2-calibration-matrices_20251017_v004.cdf",
            team / "calibration" / "imap_mag_l2-offsets-norm_20251017_20251017_v001.cdf")


def _write_matrices(path: Path, mats: np.ndarray) -> Path:
    """The team's layout: URFTOORFO/URFTOORFI (3 records = rows) x (3 columns, 4 ranges)."""
    cdf = CDFWriter(str(path), cdf_spec={"Majority": "Row_major"})
    stored = np.transpose(mats, (1, 2, 0))  # stored[i, j, r] = M_r[i, j]
    for name in ("URFTOORFO", "URFTOORFI"):
        cdf.write_var({"Variable": name, "Data_Type": CDFWriter.CDF_DOUBLE,
                       "Num_Elements": 1, "Rec_Vary": True, "Dim_Sizes": [3, 4]},
                      var_attrs={}, var_data=stored)
    cdf.close()
    return path


def _write_offsets(path: Path, epoch: np.ndarray, offsets: np.ndarray,
                   timedeltas: np.ndarray) -> Path:
    cdf = CDFWriter(str(path), cdf_spec={"Majority": "Row_major"})
    spec = {"Num_Elements": 1, "Rec_Vary": True, "Dim_Sizes": []}
    cdf.write_var({**spec, "Variable": "epoch", "Data_Type": CDFWriter.CDF_TIME_TT2000},
                  var_attrs={}, var_data=epoch)
    cdf.write_var({**spec, "Variable": "offsets", "Data_Type": CDFWriter.CDF_DOUBLE,
                   "Dim_Sizes": [3]}, var_attrs={}, var_data=offsets)
    cdf.write_var({**spec, "Variable": "timedeltas", "Data_Type": CDFWriter.CDF_DOUBLE},
                  var_attrs={}, var_data=timedeltas)
    for name in ("quality_flag", "quality_bitmask"):
        cdf.write_var({**spec, "Variable": name, "Data_Type": CDFWriter.CDF_UINT1},
                      var_attrs={}, var_data=np.zeros(epoch.size, np.uint8))
    cdf.close()
    return path


def _synthetic(tmp_path: Path):
    l1b_path, _, _ = _files()
    ds = from_team(l1b_path)
    n = ds.sizes["time"]
    ds["range"] = ("time", np.arange(n) % 4)  # every range's matrix used
    offsets = RNG.uniform(-20, 20, (n, 3))
    deltas = RNG.uniform(-0.01, 0.01, n)
    cal = l2.load_l2_calibration(
        _write_matrices(tmp_path / "m.cdf", MATS),
        _write_offsets(tmp_path / "o.cdf", ds["epoch"].values, offsets, deltas))
    return ds, cal, offsets, deltas


def test_real_day_with_the_team_files_is_the_l1b() -> None:
    l1b_path, mats, offs = _files()
    ds = from_team(l1b_path)
    out = l2.calibrate(ds, l2.load_l2_calibration(mats, offs), DAY)
    assert out.sizes["time"] == ds.sizes["time"] == 3504
    # the team's files are unit matrices and zero offsets, zero time deltas
    np.testing.assert_array_equal(out["b"].values, ds["b"].values)
    np.testing.assert_array_equal(out["epoch"].values, ds["epoch"].values)


def test_matrices_offsets_and_time_deltas_against_an_explicit_loop(tmp_path: Path) -> None:
    ds, cal, offsets, deltas = _synthetic(tmp_path)
    out = l2.calibrate(ds, cal, DAY)
    b, rng = ds["b"].values, ds["range"].values
    for k in range(300):
        m = MATS[rng[k]]
        want = [sum(m[i][j] * b[k][j] for j in range(3)) + offsets[k][i] for i in range(3)]
        np.testing.assert_allclose(out["b"].values[k], want, rtol=0, atol=1e-9)
        assert out["epoch"].values[k] == ds["epoch"].values[k] + round(deltas[k] * 1e9)


def test_offsets_for_another_input_are_refused(tmp_path: Path) -> None:
    ds, _, offsets, deltas = _synthetic(tmp_path)
    epoch = ds["epoch"].values.copy()
    epoch[10] += 2000  # 2 us off: not this input's row (the team's file is within 496 ns)
    cal = l2.load_l2_calibration(tmp_path / "m.cdf",
                                 _write_offsets(tmp_path / "x.cdf", epoch, offsets, deltas))
    with pytest.raises(InputFormatError, match="vector 10 is 2000 ns from its row"):
        l2.calibrate(ds, cal)
    with pytest.raises(InputFormatError, match="no variable 'URFTOORFO'"):
        l2.load_l2_calibration(tmp_path / "o.cdf", tmp_path / "o.cdf")


def test_frames_needing_kernels_are_refused_by_name(tmp_path: Path) -> None:
    l1b_path, mats, offs = _files()
    for frame, needs in (("gse", "attitude"), ("rtn", "attitude"), ("srf", "frames kernel")):
        result = CliRunner().invoke(app, [
            "l2", "--input", str(l1b_path), "--l2-matrices", str(mats), "--l2-offsets",
            str(offs), "--out", str(tmp_path / frame), "--frame", frame])
        assert isinstance(result.exception, InputFormatError), result.output
        assert f"frame {frame.upper()}" in str(result.exception)
        assert needs in str(result.exception)
        assert not (tmp_path / frame).exists()
    with pytest.raises(InputFormatError, match="frame 'xyz'"):
        l2.check_frames(["xyz"])


TK = """KPL/FK
\\begindata
FRAME_IMAP_SPACECRAFT = -43000
FRAME_-43000_NAME = 'IMAP_SPACECRAFT'
FRAME_-43000_CLASS = 4
FRAME_-43000_CLASS_ID = -43000
FRAME_-43000_CENTER = -43
TKFRAME_-43000_RELATIVE = 'J2000'
TKFRAME_-43000_SPEC = 'ANGLES'
TKFRAME_-43000_ANGLES = ( 0.0, 0.0, 0.0 )
TKFRAME_-43000_AXES = ( 3, 1, 3 )
TKFRAME_-43000_UNITS = 'DEGREES'
FRAME_IMAP_MAG_BASE = -43253
FRAME_-43253_NAME = 'IMAP_MAG_BASE'
FRAME_-43253_CLASS = 4
FRAME_-43253_CLASS_ID = -43253
FRAME_-43253_CENTER = -43
TKFRAME_-43253_RELATIVE = 'IMAP_SPACECRAFT'
TKFRAME_-43253_SPEC = 'ANGLES'
TKFRAME_-43253_ANGLES = ( 30.0, -45.0, 10.0 )
TKFRAME_-43253_AXES = ( 3, 1, 3 )
TKFRAME_-43253_UNITS = 'DEGREES'
\\begintext
"""


def test_srf_with_a_frames_kernel_against_pxform(tmp_path: Path) -> None:
    l1b_path, mats, offs = _files()
    (tmp_path / "imap_test.tf").write_text(TK)
    sensor = l2.calibrate(from_team(l1b_path), l2.load_l2_calibration(mats, offs), DAY)
    with KernelPool([tmp_path / "imap_test.tf"], fluxcal_frames=False):
        srf = l2.to_frame(sensor.isel(time=slice(0, 300)), "srf")
        m = spiceypy.pxform("IMAP_MAG_BASE", "IMAP_SPACECRAFT", 0.0)
    assert np.abs(m - np.eye(3)).max() > 0.3  # a real rotation
    for k in range(300):
        want = [sum(m[i][j] * sensor["b"].values[k][j] for j in range(3)) for i in range(3)]
        np.testing.assert_allclose(srf["b"].values[k], want, rtol=0, atol=1e-9)
    assert srf.attrs["output_frame"] == "srf"


def test_command_writes_l2_and_compare_reads_the_team_l1b(tmp_path: Path) -> None:
    from fluxcal.products.compare import compare, load_product

    l1b_path, mats, offs = _files()
    for layout in ("fluxcal", "team"):
        result = CliRunner().invoke(app, [
            "l2", "--input", str(l1b_path), "--l2-matrices", str(mats), "--l2-offsets",
            str(offs), "--out", str(tmp_path / layout), "--layout", layout])
        assert result.exit_code == 0, result.output
    team_l1b = load_product(l1b_path)  # its vectors have blank units
    for layout in ("fluxcal", "team"):
        ours = load_product(tmp_path / layout / "imap_mag_l2_norm-mago_20251017_v001.cdf")
        c = compare(team_l1b, ours, 0, force=True)
        assert c.matched == 3504 and all(s.max_abs == 0.0 for s in c.overall)


def test_team_l2_agrees_to_1e9_nt(tmp_path: Path) -> None:
    """The team's package (1.0.40) applies the same matrices, offsets and time deltas."""
    ds, cal, offsets, deltas = _synthetic(tmp_path)
    ds.attrs["sensor"] = "mago"
    write_cdf_as_is(to_team(ds, "imap_mag_l1b_norm-mago"), tmp_path / "l1b.cdf")
    team = run_team(
        "import sys, numpy as np\n"
        "from imap_processing.cdf.utils import load_cdf\n"
        "from imap_processing.mag.constants import DataMode\n"
        "from imap_processing.mag.l2.mag_l2_data import MagL2, ValidFrames\n"
        "l1b, m, o = (load_cdf(p) for p in sys.argv[1:4])\n"
        "v = MagL2.apply_calibration(vectors=l1b['vectors'].data, "
        "calibration_matrix=m['URFTOORFO'])\n"
        "l2 = MagL2(vectors=v[:, :3], epoch=l1b['epoch'].data, range=v[:, 3], "
        "global_attributes={}, quality_flags=o['quality_flag'].data, "
        "quality_bitmask=o['quality_bitmask'].data, data_mode=DataMode.NORM, "
        "offsets=o['offsets'].data, timedelta=o['timedeltas'].data, frame=ValidFrames.MAGO)\n"
        "l2.truncate_to_24h(np.datetime64('2025-10-17'))\n"
        "np.savez(sys.argv[4], epoch=l2.epoch, vectors=l2.vectors)\n",
        tmp_path / "l1b.cdf", tmp_path / "m.cdf", tmp_path / "o.cdf", tmp_path / "team.npz")
    ours = l2.calibrate(ds, cal, DAY)
    assert team["vectors"].shape == ours["b"].shape == (3504, 3)
    np.testing.assert_allclose(team["vectors"], ours["b"].values, rtol=0, atol=1e-9)
    # the team shifts times in float64 ns (128 ns steps near 8.1e17 ns); fluxcal in int64
    assert np.abs(team["epoch"] - ours["epoch"].values).max() <= 128


def test_team_mag_l2_in_srf_agrees(tmp_path: Path) -> None:
    """The team's whole ``mag_l2`` (1.0.40) in SRF, with the frames kernel written here."""
    ds, cal, _, _ = _synthetic(tmp_path)
    write_cdf_as_is(to_team(ds, "imap_mag_l1b_norm-mago"), tmp_path / "l1b.cdf")
    (tmp_path / "imap_test.tf").write_text(TK)
    team = run_team(
        "import sys, numpy as np, spiceypy, xarray as xr\n"
        "from imap_processing.cdf.utils import load_cdf\n"
        "from imap_processing.mag.l2.mag_l2 import mag_l2\n"
        "from imap_processing.mag.l2.mag_l2_data import ValidFrames\n"
        "spiceypy.furnsh(sys.argv[4])\n"
        "l1b, m, o = (load_cdf(p) for p in sys.argv[1:4])\n"
        "dims = ('epoch', 'row', 'column', 'range')\n"
        "cal = xr.Dataset({k: (dims, m[k].values[None]) for k in ('URFTOORFO', 'URFTOORFI')},"
        " coords={'epoch': [np.datetime64('2025-10-17', 'ns')]})\n"
        "out = mag_l2(cal, o, l1b, np.datetime64('2025-10-17'), frames=[ValidFrames.SRF])[0]\n"
        "np.savez(sys.argv[5], epoch=out['epoch'].values, b=out['b_srf'].values)\n",
        tmp_path / "l1b.cdf", tmp_path / "m.cdf", tmp_path / "o.cdf", tmp_path / "imap_test.tf",
        tmp_path / "team.npz")
    with KernelPool([tmp_path / "imap_test.tf"], fluxcal_frames=False):
        ours = l2.to_frame(l2.calibrate(ds, cal, DAY), "srf")
    assert team["b"].shape == ours["b"].shape == (3504, 3)
    np.testing.assert_allclose(team["b"], ours["b"].values, rtol=0, atol=1e-9)
    assert np.abs(team["epoch"] - ours["epoch"].values).max() <= 128
