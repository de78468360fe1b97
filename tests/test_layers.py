"""Layers of fluxcal: generic packages name no mission, and no import cycle.

Every module under ``src/fluxcal`` is parsed with `ast` (nothing is imported):

(a) a module of a generic package imports no module of ``fluxcal.missions``;
(b) a generic module's source names no mission (``messenger``, ``rosetta`` as words,
    ``msgr``, the NAIF ids ``-236``/``-226``), except the seed documents' titles and the
    docs/ files a docstring cites (`ALLOWED`);
(c) the module-level imports among fluxcal modules form no cycle (strongly connected
    components of the import graph), nor do all imports, those inside functions included,
    but for `KNOWN_CYCLES`.

`KNOWN_VIOLATIONS` and `KNOWN_CYCLES` list the exceptions: none since the run driver,
batch runner and command line moved to ``fluxcal.runs`` and the missions (issue 20).
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src"
PACKAGE = SRC / "fluxcal"
#: Packages that take every mission detail as an argument.
GENERIC = ("geometry", "calibration", "cleaning", "products", "archive", "runs")
#: A mission's name in source text (words, frame prefixes and NAIF ids).
MISSION_WORDS = re.compile(r"\bmessenger\b|\brosetta\b|msgr|(?<![\w.])-2[23]6(?!\.)\d*",
                           re.IGNORECASE)
#: What a docstring may cite by name: the seed documents' titles and the documents of
#: docs/ that record a mission's decisions or formats.
ALLOWED = re.compile(r"MESSENGER MAG EDR-to-CDR Processing|Rosetta RPC-MAG Calibration "
                     r"Procedure|docs/(?:decisions|formats)/(?:messenger|rosetta)\w*\.md",
                     re.IGNORECASE)
#: Modules allowed to break (a) or (b): none (the batch runner, CLI commands and demos
#: that did moved to fluxcal.runs and the missions, issue 20).
KNOWN_VIOLATIONS: set[str] = set()


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(SRC).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _modules() -> dict[str, Path]:
    return {_module_name(p): p for p in sorted(PACKAGE.rglob("*.py"))}


MODULES = _modules()


def _is_generic(module: str) -> bool:
    parts = module.split(".")
    return len(parts) > 1 and parts[1] in GENERIC


def _resolve(module: str, node: ast.ImportFrom) -> str:
    """Absolute name of the module a ``from ... import`` names (relative ones resolved)."""
    if node.level == 0:
        return node.module or ""
    is_package = MODULES[module].name == "__init__.py"
    base = module.split(".")[: len(module.split(".")) - node.level + (1 if is_package else 0)]
    return ".".join(base + ([node.module] if node.module else []))


def _imports(module: str, *, top_level_only: bool) -> set[str]:
    """fluxcal modules imported by ``module`` (module level only, or anywhere)."""
    tree = ast.parse(MODULES[module].read_text(encoding="utf-8"))
    nodes = tree.body if top_level_only else list(ast.walk(tree))
    if top_level_only:  # module level, including inside if/try blocks at that level
        nodes = [n for stmt in tree.body for n in ast.walk(stmt)
                 if not isinstance(stmt, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef))]
    out: set[str] = set()
    for node in nodes:
        if isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = _resolve(module, node)
            # ``from fluxcal.x import y``: y may be a module of package x
            names = [f"{base}.{alias.name}" if f"{base}.{alias.name}" in MODULES else base
                     for alias in node.names]
        else:
            continue
        out.update(n for n in names if n == "fluxcal" or n.startswith("fluxcal."))
    return out


def test_every_module_is_found():
    assert "fluxcal.geometry.kernels" in MODULES and len(MODULES) > 100


@pytest.mark.parametrize("module", [m for m in MODULES if _is_generic(m)])
def test_generic_module_imports_no_mission(module):
    if module in KNOWN_VIOLATIONS:
        pytest.skip("moved to runs/ by the lead (issue 20)")
    bad = _mission_imports(module)
    assert not bad, f"{module} imports {bad}"


@pytest.mark.parametrize("module", [m for m in MODULES if _is_generic(m)])
def test_generic_module_names_no_mission(module):
    if module in KNOWN_VIOLATIONS:
        pytest.skip("moved to runs/ by the lead (issue 20)")
    hits = _mission_lines(module)
    assert not hits, f"{module} names a mission:\n" + "\n".join(hits)


def _mission_imports(module: str) -> list[str]:
    return sorted(n for n in _imports(module, top_level_only=False)
                  if n == "fluxcal.missions" or n.startswith("fluxcal.missions."))


def _mission_lines(module: str) -> list[str]:
    lines = MODULES[module].read_text(encoding="utf-8").splitlines()
    return [f"{number}: {line.strip()}" for number, line in enumerate(lines, 1)
            if MISSION_WORDS.search(ALLOWED.sub("", line))]


@pytest.mark.parametrize("module", sorted(KNOWN_VIOLATIONS))
def test_known_violations_are_current(module):
    """An entry leaves `KNOWN_VIOLATIONS` once its module is moved or clean."""
    if module not in MODULES:
        pytest.skip("moved")
    assert _mission_imports(module) or _mission_lines(module), f"{module} is clean now"


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    out: list[list[str]] = []
    counter = 0
    for root in sorted(graph):
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on_stack.add(root)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = counter
                    counter += 1
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph[child]))))
                elif child in on_stack:
                    low[node] = min(low[node], index[child])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                component = []
                while True:
                    item = stack.pop()
                    on_stack.discard(item)
                    component.append(item)
                    if item == node:
                        break
                if len(component) > 1:
                    out.append(sorted(component))
    return out


def test_cycle_finder_finds_a_cycle():
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert _cycles({"a": {"b"}, "b": set()}) == []


def test_no_import_cycle():
    graph = {m: {n for n in _imports(m, top_level_only=True) if n in MODULES and n != m}
             for m in MODULES}
    # a module's package is imported before it: that edge is not a dependency of the code
    cycles = _cycles(graph)
    assert not cycles, f"import cycles among fluxcal modules: {cycles}"


#: Cycles through imports inside functions that remain today: the CLI modules the lead
#: moves to runs/ (issue 20).
KNOWN_CYCLES: list[list[str]] = []


def test_no_import_cycle_through_function_imports():
    graph = {m: {n for n in _imports(m, top_level_only=False) if n in MODULES and n != m}
             for m in MODULES}
    cycles = [c for c in _cycles(graph) if c not in KNOWN_CYCLES]
    assert not cycles, f"import cycles (imports inside functions included): {cycles}"


#: Modules whose imports inside functions are kept on purpose (issue 20 item 3): the command
#: bodies (``fluxcal --help`` loads no numerical library, tests/test_cli_startup.py), the
#: demos, and the boundaries of the optional extras (tests/test_extras.py).
LAZY_MODULES = re.compile(r"fluxcal\.((\w+\.)*(cli|\w+_cli|\w*demo)|"
                          r"product_commands|products\.quicklook|runs\.cluster)")
#: The optional extras, and fluxcal's modules that import them at their top.
EXTRA_IMPORTS = ("matplotlib", "dask", "distributed", "zarr", "sphinx", "pyspedas",
                 "fluxcal.products.quicklook", "fluxcal.products.fit_plots",
                 "fluxcal.runs.cluster")
#: Imports inside functions of the other (library) modules, extras left out: 208
#: before issue 20 item 3 moved them up.  Those left: ``import fluxcal`` stays light
#: (``fluxcal.__getattr__``), a table writer loads when its format is asked for
#: (`fluxcal.products.writer`, tests/test_cli_startup.py), a mission's command module loads
#: when the command line is built (``rosetta.mission``), the run report's numerical
#: libraries load after the command ran (`fluxcal.runs.options`), ``fcntl`` is POSIX only
#: (`fluxcal.products.staging`).  A ratchet: lower it when one moves up, never raise it.
MAX_FUNCTION_IMPORTS = 10


def _function_imports(module: str) -> list[str]:
    """``line: import`` of each import inside a function of ``module``, extras left out."""
    tree = ast.parse(MODULES[module].read_text(encoding="utf-8"))
    found: dict[int, str] = {}
    for func in ast.walk(tree):
        if not isinstance(func, (ast.FunctionDef, ast.AsyncFunctionDef)):
            continue
        for node in ast.walk(func):
            if isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = _resolve(module, node)
                names = [f"{base}.{alias.name}" for alias in node.names] + [base]
            else:
                continue
            if not any(n == e or n.startswith(e + ".") for n in names for e in EXTRA_IMPORTS):
                found[node.lineno] = f"{node.lineno}: {ast.unparse(node)}"
    return [found[k] for k in sorted(found)]


def test_function_imports_of_library_modules_do_not_grow_back():
    """Imports at the top of library modules; laziness only where start-up time is won."""
    inner = {m: _function_imports(m) for m in MODULES if not LAZY_MODULES.fullmatch(m)}
    count = sum(len(v) for v in inner.values())
    listing = "\n".join(f"{m}:{line}" for m, lines in sorted(inner.items()) for line in lines)
    assert count <= MAX_FUNCTION_IMPORTS, (
        f"{count} imports inside functions of library modules (at most "
        f"{MAX_FUNCTION_IMPORTS}): move them to the top of their module\n{listing}")


def test_the_lazy_modules_are_the_command_and_extras_modules():
    lazy = sorted(m for m in MODULES if LAZY_MODULES.fullmatch(m))
    assert "fluxcal.cli" in lazy and "fluxcal.missions.rosetta.clean_cli" in lazy
    assert "fluxcal.missions.messenger.fit_demo" in lazy and "fluxcal.runs.cluster" in lazy
    assert "fluxcal.missions.rosetta.products" not in lazy and "fluxcal.api" not in lazy


#: Packages below ``fluxcal.runs``: they take the registry's pieces (frame kernels,
#: archived-product readers) as arguments and never look missions up (issue 32).
LOWER = ("geometry", "calibration", "cleaning", "products", "archive")
#: What a lower-layer module must not name, in an import or in a string of its code: the
#: run layer and the missions (a ``"module:attribute"`` string imported at run time is an
#: import the import graph does not see).
UPWARD = re.compile(r"\bfluxcal\.(runs|missions)\b")


def _docstrings(tree: ast.AST) -> set[int]:
    """ids of the docstring nodes of a module, its classes and functions."""
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
            body = node.body
            if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant) \
                    and isinstance(body[0].value.value, str):
                out.add(id(body[0].value))
    return out


def _upward_names(module: str, pattern: re.Pattern = UPWARD) -> list[str]:
    """Imports and string constants (docstrings aside) of ``module`` matching ``pattern``."""
    tree = ast.parse(MODULES[module].read_text(encoding="utf-8"))
    hits = [f"imports {n}" for n in sorted(_imports(module, top_level_only=False))
            if pattern.search(n)]
    docs = _docstrings(tree)
    hits += [f"line {node.lineno}: {node.value!r}" for node in ast.walk(tree)
             if isinstance(node, ast.Constant) and isinstance(node.value, str)
             and id(node) not in docs and pattern.search(node.value)]
    return hits


def _is_lower(module: str) -> bool:
    parts = module.split(".")
    return len(parts) > 1 and parts[1] in LOWER


@pytest.mark.parametrize("module", [m for m in MODULES if _is_lower(m)])
def test_lower_layer_names_neither_runs_nor_missions(module):
    hits = _upward_names(module)
    assert not hits, f"{module} reaches up:\n" + "\n".join(hits)


@pytest.mark.parametrize("module", [m for m in MODULES if m.startswith("fluxcal.runs.")])
def test_runs_name_no_mission_module(module):
    # the entry-point group "fluxcal.missions" is a name, not a module: a module is
    # "fluxcal.missions.<name>" or "fluxcal.missions:<attribute>"
    hits = _upward_names(module, re.compile(r"\bfluxcal\.missions[.:]\w"))
    assert not hits, f"{module} names a mission module:\n" + "\n".join(hits)


def test_the_string_check_sees_a_reference_by_name(tmp_path, monkeypatch):
    """The check fails for the right reason: a ``module:attribute`` string is caught."""
    bad = tmp_path / "bad.py"
    bad.write_text('"""Doc: fluxcal.runs.registry is fine here."""\n'
                   'DEFAULT = "fluxcal.runs.registry:frame_kernels"\n')
    monkeypatch.setitem(MODULES, "fluxcal.geometry.bad", bad)
    assert _upward_names("fluxcal.geometry.bad") == [
        "line 2: 'fluxcal.runs.registry:frame_kernels'"]
