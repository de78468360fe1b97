"""``fluxcal rosetta clean --level H`` without lines to remove is refused (issue 12).

Before: exit 0 and a LEVEL_H product identical to its input, nothing said.
"""

from fluxcal.cli import main


def test_level_h_without_wheels_or_lap_lines_is_refused(tmp_path, capsys):
    src = tmp_path / "RPCMAG_20140801_CLC_OB.cdf"
    src.write_bytes(b"")  # refused before any input is read
    out = tmp_path / "out"
    code = main(["rosetta", "clean", "--level", "H", "--input", str(src), "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("fluxcal: error:")
    assert "--wheels" in err and "--lap-lines" in err
    assert not out.exists() or not any(out.iterdir())
