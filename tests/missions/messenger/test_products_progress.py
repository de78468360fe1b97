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
    products = [a for a in seen if a[0].startswith("12153 ")]
    # 2 frames x (full resolution + one average), counted up to the total
    assert [a[1:] for a in products] == [(1, 4), (2, 4), (3, 4), (4, 4)]
    assert products[0][0] == "12153 MAGMSOSCI12153_V01"
    assert seen[0][0] == "reading inputs"


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
