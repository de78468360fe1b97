"""edr2cdr progress: a callback per step and product, quiet off a terminal, compile notice."""

import numpy as np
from numba import njit

from fluxcal.missions.messenger.cli import compilation_notice, progress_display
from fluxcal.missions.messenger.routes import run_edr2cdr


def test_progress_reports_every_product(tmp_path, simulated_files, messenger_kernels):
    seen = []
    f = simulated_files
    written = run_edr2cdr([f["science"]], [f["heater"]], [f["temperature"]], messenger_kernels,
                          tmp_path / "out", frames=("mso", "sc"), formats=("cdf",),
                          averages=(60,), progress=lambda *a: seen.append(a))
    assert written
    products = [a[0] for a in seen if a[0].startswith("wrote messenger_mag_")]
    # 2 frames x (full resolution + one average), each CDF named by its Logical_source
    assert products == [f"wrote messenger_mag_{f}-{k}" for f in ("mso", "sc")
                        for k in ("sci", "avg60")]
    assert seen[0][0] == "reading inputs" and seen[-1][0] == f"wrote {len(written)} files"


def test_no_progress_display_off_a_terminal(capsys):
    with progress_display() as progress:  # pytest captures stderr: not a terminal
        assert progress is None
    assert capsys.readouterr().err == ""


def test_compile_notice_once(capsys):
    with compilation_notice():
        # two fresh functions: two compilations, one notice
        njit(lambda x: x + 1)(np.int64(1))
        njit(lambda x: x * 2)(np.int64(1))
    err = capsys.readouterr().err
    assert err.count("compiling the numerical kernels") == 1
    with compilation_notice():
        pass  # nothing compiled: nothing said
    assert capsys.readouterr().err == ""


def test_simulate_status_is_quiet_off_a_terminal(capsys):
    from fluxcal.missions.messenger.cli import status_display

    with status_display("simulating"):
        pass
    assert capsys.readouterr().err == ""
