"""Start-up cost of the ``fluxcal`` command (issue 10 item 8).

``import fluxcal.cli`` (and so ``fluxcal --help``) loads no numerical library: every
sub-command imports what it needs when it runs.  `fluxcal.cli.main` keeps the cyclic
garbage collector off the objects alive when it starts and gives the caller's
collector back unchanged.
"""

from __future__ import annotations

import gc
import json
import subprocess
import sys

import pytest

import fluxcal.products
from fluxcal.cli import main

# importlib.metadata is not here: the command line is built from the missions registered
# as entry points (fluxcal.runs.registry), and every command that reads data imports it
# anyway (xarray finds its backends the same way).
HEAVY = ("numpy", "xarray", "pandas", "numba", "scipy", "dask", "matplotlib", "cdflib",
         "pvl", "spiceypy", "pyarrow")


def _modules_after(code: str) -> set[str]:
    out = subprocess.run([sys.executable, "-c", code + "\nimport sys, json\n"
                          "print(json.dumps(sorted(sys.modules)))"],
                         capture_output=True, text=True, check=True).stdout
    return set(json.loads(out.splitlines()[-1]))


def test_import_of_the_cli_loads_no_numerical_library():
    loaded = _modules_after("import fluxcal.cli")
    assert not [m for m in HEAVY if m in loaded]


def test_help_lists_every_command_without_numerical_libraries():
    code = ("import contextlib, io\nfrom fluxcal.cli import main\nbuf = io.StringIO()\n"
            "with contextlib.redirect_stdout(buf):\n    main(['--help'])\n"
            "assert all(c in buf.getvalue() for c in ('messenger', 'rosetta', 'simulate', "
            "'plot', 'batch', 'compare', 'version', 'demo')), buf.getvalue()")
    loaded = _modules_after(code)
    assert not [m for m in HEAVY if m in loaded]


@pytest.mark.parametrize("argv", [["version"], ["no-such-command"],
                                  ["messenger", "edr2cdr", "--help"]])
def test_main_gives_the_garbage_collector_back_unchanged(argv, capsys):
    threshold, frozen = gc.get_threshold(), gc.get_freeze_count()
    main(argv)
    assert gc.get_threshold() == threshold
    assert gc.get_freeze_count() == frozen


def test_main_freezes_the_objects_alive_at_its_start(monkeypatch):
    seen = {}

    def command(*args, **kwargs):
        seen["frozen"] = gc.get_freeze_count()
        seen["threshold"] = gc.get_threshold()
        return 0

    import fluxcal.cli

    before = gc.get_freeze_count()
    monkeypatch.setattr(fluxcal.cli, "app", command)
    assert main(["anything"]) == 0
    assert seen["frozen"] > before
    assert seen["threshold"][2] >= fluxcal.cli.FULL_COLLECTION_EVERY
    assert gc.get_freeze_count() == before


def test_products_names_load_on_first_use():
    from fluxcal.products import Column, write_product
    from fluxcal.products.columns import Column as column_class
    from fluxcal.products.writer import write_product as writer_function

    assert Column is column_class and write_product is writer_function
    assert set(fluxcal.products.__all__) <= set(dir(fluxcal.products))
    for name in fluxcal.products.__all__:
        assert getattr(fluxcal.products, name) is not None
    with pytest.raises(AttributeError, match="no_such_name"):
        fluxcal.products.no_such_name  # noqa: B018


def test_version_attribute_is_the_installed_distribution():
    from importlib.metadata import version

    import fluxcal

    assert fluxcal.__version__ == version("fluxcal")
    with pytest.raises(AttributeError, match="__no_such__"):
        fluxcal.__no_such__  # noqa: B018


def test_a_cdf_only_product_loads_no_table_writer(tmp_path):
    code = f"""
import numpy as np, xarray as xr
from pathlib import Path
from fluxcal.products import write_product, read_fluxcal_product
ds = xr.Dataset({{"b": (("time",), np.arange(3.0), {{"units": "nT", "valid_min": -9.0,
                                                      "valid_max": 9.0}})}},
                coords={{"epoch": ("time", 757339269184000000 + np.arange(3) * 50000000)}})
(path,) = write_product(ds, Path({str(tmp_path)!r}) / "P", formats=("cdf",))
assert read_fluxcal_product(path)["b"].values.tolist() == [0.0, 1.0, 2.0]
"""
    loaded = _modules_after(code)
    assert not [m for m in ("pvl", "fluxcal.products.tab", "fluxcal.products.netcdf")
                if m in loaded]


def test_objects_the_caller_froze_stay_frozen():
    gc.freeze()
    try:
        main(["version"])
        # not unfrozen (a frozen object freed by reference counting leaves the count)
        assert gc.get_freeze_count() > 0
    finally:
        gc.unfreeze()


def _hugepage_advice(env_value: str | None) -> bool:
    """numpy's huge-page advice after a ``fluxcal`` command (`main`) in a fresh interpreter."""
    import os

    env = {k: v for k, v in os.environ.items() if k != "NUMPY_MADVISE_HUGEPAGE"}
    if env_value is not None:
        env["NUMPY_MADVISE_HUGEPAGE"] = env_value
    code = ("from fluxcal.cli import main\n"
            "main(['version'])\nimport numpy\n"
            "print(numpy._core.multiarray._get_madvise_hugepage())")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, env=env).stdout
    return out.split()[-1] == "True"


def test_the_command_turns_numpy_huge_page_advice_off():
    # numpy's own report of its switch (numpy reference, "Global state")
    assert _hugepage_advice(None) is False


@pytest.mark.parametrize("value, advised", [("1", True), ("0", False)])
def test_a_users_huge_page_setting_is_kept(value, advised):
    assert _hugepage_advice(value) is advised


def test_quicklooks_and_the_offset_figure_load_no_scipy_signal():
    # scipy.signal costs ~0.8 s of CPU at import (docs/decisions/products.md, decision 52);
    # only a spectrogram needs it (fluxcal.products.spectrogram)
    pytest.importorskip("matplotlib")
    loaded = _modules_after("import fluxcal.products.quicklook\n"
                            "import fluxcal.missions.messenger.validation_report")
    assert "scipy.signal" not in loaded
    assert "scipy.signal" in _modules_after("import fluxcal.products.spectrogram")
