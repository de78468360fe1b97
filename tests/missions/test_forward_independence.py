"""The forward models share no calibration code with the pipeline (issue 11).

Both simulators (``missions/<m>/simulate.py`` and ``forward.py``) may use the seed's tables
(parsed by `fluxcal.missions.rosetta.calib` or their own reader), SPICE access
(`fluxcal.geometry`), the input/output writers and `fluxcal.errors`; never a level function
or a calibration building block.  Checked statically (every import, also inside functions,
followed through fluxcal's own modules) and dynamically (``sys.modules`` after importing and
running the Rosetta simulator in a fresh interpreter).
"""

import ast
import json
import subprocess
import sys
from pathlib import Path

import pytest

import fluxcal

SRC = Path(fluxcal.__file__).parent
SIMULATORS = [
    "fluxcal.missions.messenger.simulate",
    "fluxcal.missions.messenger.forward",
    "fluxcal.missions.messenger.flight_sim",
    "fluxcal.missions.rosetta.simulate",
    "fluxcal.missions.rosetta.forward",
    "fluxcal.missions.imap.simulate",
    "fluxcal.missions.imap.sim_packets",
]
FORBIDDEN = (
    "fluxcal.calibration",  # also binned_stats, constrained_fits, solar_wind_offsets (fit)
    "fluxcal.missions.messenger.fit",  # the in-flight calibration fit (issue 13), any fit*
    "fluxcal.missions.messenger.batch_task",  # calls the pipeline's calibration loader
    "fluxcal.cleaning",
    "fluxcal.missions.messenger.levels",
    "fluxcal.missions.messenger.chain",
    "fluxcal.missions.messenger.run",
    "fluxcal.missions.messenger.calibration_data",  # builds eq. 8 with the pipeline's code
    "fluxcal.missions.messenger._compiled",
    "fluxcal.missions.rosetta.level_a",
    "fluxcal.missions.rosetta.level_b",
    "fluxcal.missions.rosetta.level_c",
    "fluxcal.missions.rosetta.products",
    "fluxcal.missions.rosetta.day_edges",
    "fluxcal.missions.rosetta.hk",
    "fluxcal.missions.rosetta.extended_model",
    "fluxcal.missions.rosetta.averaged",
    "fluxcal.missions.rosetta.cleaning_levels",
    # the IMAP decoder and levels (the forward model writes packets with its own packer)
    "fluxcal.missions.imap.vectors",
    "fluxcal.missions.imap.packets",
    "fluxcal.missions.imap.l1a",
    "fluxcal.missions.imap.l1b",
    "fluxcal.missions.imap.calibration",
    "fluxcal.missions.imap.chain",
    "fluxcal.missions.imap.products",
    "fluxcal.missions.imap.routes",
)


#: Allowed below a forbidden package: the calibration *store* finds and versions table files
#: (which file, not what is in it or how it is applied), and the package's ``__init__`` is
#: empty (checked by `test_calibration_package_init_imports_nothing`).
ALLOWED = ("fluxcal.calibration", "fluxcal.calibration.store")


def _forbidden(module: str) -> bool:
    if module in ALLOWED:
        return False
    return any(module == f or module.startswith(f + ".") for f in FORBIDDEN) or (
        module.startswith("fluxcal.missions.messenger.fit"))


def _file(module: str) -> Path | None:
    rel = Path(*module.split(".")[1:])
    for candidate in (SRC / rel.with_suffix(".py"), SRC / rel / "__init__.py"):
        if candidate.is_file():
            return candidate
    return None


def _is_type_checking(node: ast.If) -> bool:
    t = node.test
    return (isinstance(t, ast.Name) and t.id == "TYPE_CHECKING") or (
        isinstance(t, ast.Attribute) and t.attr == "TYPE_CHECKING")


def _imports(module: str) -> set[str]:
    """Every fluxcal module ``module`` imports, at any depth of its code (not under
    ``if TYPE_CHECKING:``)."""
    path = _file(module)
    if path is None:
        return set()
    found: set[str] = set()

    def visit(node: ast.AST) -> None:
        if isinstance(node, ast.If) and _is_type_checking(node):
            for child in node.orelse:
                visit(child)
            return
        if isinstance(node, ast.Import):
            found.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            found.add(node.module)
            found.update(f"{node.module}.{a.name}" for a in node.names
                         if _file(f"{node.module}.{a.name}") is not None)
        for child in ast.iter_child_nodes(node):
            visit(child)

    visit(ast.parse(path.read_text()))
    return {m for m in found if m.split(".")[0] == "fluxcal"}


def _closure(start: str) -> dict[str, str]:
    """Every fluxcal module reachable from ``start``, mapped to the module importing it."""
    seen = {start: ""}
    todo = [start]
    while todo:
        mod = todo.pop()
        for dep in _imports(mod):
            # a package import also runs the package's __init__ chain
            parts = dep.split(".")
            for k in range(2, len(parts) + 1):
                name = ".".join(parts[:k])
                if name not in seen:
                    seen[name] = mod
                    todo.append(name)
    return seen


@pytest.mark.parametrize("module", SIMULATORS)
def test_simulator_imports_no_pipeline_code(module):
    reached = _closure(module)
    bad = {m: via for m, via in reached.items() if _forbidden(m)}
    assert not bad, f"{module} reaches pipeline code (module: imported by): {bad}"


def test_calibration_package_init_imports_nothing():
    """Importing `fluxcal.calibration.store` runs the package's ``__init__``: it must stay
    empty, or the forward models would reach calibration building blocks through it."""
    assert not _imports("fluxcal.calibration")
    assert _imports("fluxcal.calibration.store") <= {"fluxcal.errors", "fluxcal.textfile"}


def test_the_check_would_catch_a_pipeline_import():
    # the old simulators imported these; the closure of the pipeline finds them
    assert any(_forbidden(m) for m in _closure("fluxcal.missions.rosetta.products"))
    assert any(_forbidden(m) for m in _imports("fluxcal.missions.messenger.chain"))


def _modules_after(code: str) -> list[str]:
    """The fluxcal modules a fresh interpreter holds after running ``code``."""
    code += 'print(json.dumps(sorted(m for m in sys.modules if m.startswith("fluxcal"))))\n'
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, timeout=300)
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_sys_modules_after_a_rosetta_simulation():
    code = """
import json, sys
import fluxcal.missions.messenger.simulate, fluxcal.missions.messenger.forward
from fluxcal.geometry.kernels import KernelPool
from fluxcal.missions.rosetta import calib, simulate
with KernelPool([]):
    cals = {s: calib.load_ground_calibration(s) for s in ("OB", "IB")}
    days = [__import__("numpy").datetime64("2014-08-01")]
    sim = simulate.simulate(
        "2014-08-01T00:00:00", 20.0, calibrations=cals,
        time_shifts=calib.load_time_shift_table(), nominal=calib.load_nominal_conversion(),
        alignment=simulate.synthetic_alignment(), jumps=calib.load_offset_jump_table(),
        daily_models=simulate.synthetic_daily_models(days), hk_period_s=2.0)
assert sim.science["OB"].sizes["time"] == 400
"""
    loaded = _modules_after(code)
    assert "fluxcal.missions.rosetta.forward" in loaded
    assert not [m for m in loaded if _forbidden(m)]


def test_sys_modules_after_a_flight_simulation(tmp_path):
    code = f"""
import json, sys
from fluxcal.missions.messenger.flight_sim import FlightConfig, simulate_flight
run = simulate_flight({str(tmp_path)!r}, FlightConfig(days=1, rate_setting=3))
assert run.n_samples == 8640
"""
    loaded = _modules_after(code)
    assert "fluxcal.missions.messenger.forward" in loaded
    assert not [m for m in loaded if _forbidden(m)]
