"""Help and error texts name the procedure documents by title, not "seed 000/003" (issue 12).

Before: ``fluxcal messenger edr2cdr --help`` said "(seed 000 sec. 5-13)"; errors of
LEVEL_A, the calibration files and the offset check cited "seed 003 sec. ..." (the
numbering of this project's input files, meaningless to a user).
"""

import ast
import re
from pathlib import Path

import typer

from fluxcal.cli import app, main

SEED = re.compile(r"seed\s*0*[03]\b", re.I)
SRC = Path(__file__).resolve().parents[1] / "src" / "fluxcal"
#: helper-12's file at the time of writing (a report header); left to its owner
NOT_YET: set[str] = set()


def _commands(cmd, path: tuple[str, ...] = ()):
    yield path
    if hasattr(cmd, "commands"):  # a group (typer may vendor its own click)
        for name, sub in cmd.commands.items():
            yield from _commands(sub, (*path, name))


def test_every_help_text_names_documents_by_title(capsys):
    paths = list(_commands(typer.main.get_command(app)))
    assert ("messenger", "edr2cdr") in paths and ("rosetta", "clean") in paths
    for path in paths:
        assert main([*path, "--help"]) == 0, path
        text = capsys.readouterr().out
        assert not SEED.search(text), (path, SEED.search(text))
    main(["messenger", "edr2cdr", "--help"])
    assert "MESSENGER MAG EDR-to-CDR Processing" in " ".join(capsys.readouterr().out.split())


def _docstrings(tree: ast.AST) -> set[int]:
    out = set()
    for node in ast.walk(tree):
        body = getattr(node, "body", None)
        if (isinstance(node, (ast.Module, ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef))
                and body and isinstance(body[0], ast.Expr)
                and isinstance(body[0].value, ast.Constant)):
            out.add(id(body[0].value))
    return out


def test_no_string_outside_docstrings_cites_a_seed_number():
    # messages, column descriptions and written file headers (docstring References may
    # keep the project's seed numbers next to the titles)
    found = []
    for path in sorted(SRC.rglob("*.py")):
        if path.relative_to(SRC).as_posix() in NOT_YET:
            continue
        tree = ast.parse(path.read_text())
        docs = _docstrings(tree)
        found += [f"{path.relative_to(SRC)}:{node.lineno}" for node in ast.walk(tree)
                  if isinstance(node, ast.Constant) and isinstance(node.value, str)
                  and id(node) not in docs and SEED.search(node.value)]
    assert not found, found
    for yaml in SRC.rglob("istp_variables.yaml"):
        catdesc = [ln for ln in yaml.read_text().splitlines() if "CATDESC" in ln]
        assert not any(SEED.search(ln) for ln in catdesc), yaml
