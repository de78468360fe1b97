"""Sphinx configuration of the fluxcal documentation site (``make docs``)."""

from __future__ import annotations

import re
import sys
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
# the source tree first: the site documents this checkout, installed or not
sys.path.insert(0, str(ROOT / "src"))

project = "fluxcal"
author = "fluxcal developers"
copyright = "2026, fluxcal developers"  # noqa: A001 - Sphinx's name
try:
    release = version("fluxcal")
except PackageNotFoundError:  # pragma: no cover - docs built without an install
    release = "0.1.0"
version = ".".join(release.split(".")[:2])

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.mathjax",
    # MathJax 3 shipped in the package and copied into _static/mathjax: math renders
    # offline (no CDN; docs/decisions/packaging.md)
    "sphinx-mathjax-offline",
    "sphinx.ext.viewcode",
    "numpydoc",
    "sphinx_gallery.gen_gallery",
]

source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
root_doc = "index"
# `name` in a docstring links to that object where Sphinx knows it, plain text otherwise
default_role = "py:obj"
# examples/: the gallery's scripts (sphinx-gallery renders them into gallery/)
exclude_patterns = ["_build", "Thumbs.db", ".DS_Store", "examples"]
templates_path = ["_templates"]

# --- API reference ------------------------------------------------------------------
autosummary_generate = True
autosummary_imported_members = False
# the reference is the public API: a package's ``__all__`` names its public modules (only
# those get pages; the command line, demos and simulators are internal) or, for a package
# without public modules (``fluxcal.cleaning``, ``fluxcal.missions.messenger.levels``),
# the names it re-exports, documented on its own page (docs/_templates/autosummary/
# module.rst).  Members are documented on the page of the public module that defines them,
# so a name a package re-exports is not described twice
autosummary_ignore_module_all = False
autodoc_default_options: dict[str, bool] = {}
autodoc_typehints = "none"  # numpydoc's Parameters sections carry the types
autodoc_member_order = "bysource"
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_xref_param_type = False
numpydoc_validation_checks: set[str] = set()

# --- Gallery (sphinx-gallery): docs/examples/plot_*.py run at build time ----------------
sphinx_gallery_conf = {
    "examples_dirs": "examples",
    "gallery_dirs": "gallery",  # generated, not committed (.gitignore)
    "filename_pattern": r"/plot_",  # every example runs, its figures are kept
    "abort_on_example_error": True,  # a failing example fails the build
    "download_all_examples": False,
    "remove_config_comments": True,
    "matplotlib_animations": False,
    "write_computation_times": False,  # no sg_execution_times pages outside the toctree
    "image_scrapers": ("matplotlib",),
}

# --- Markdown (the decision records and format notes are MyST) ------------------------
myst_enable_extensions = ["dollarmath", "amsmath", "deflist", "colon_fence"]
myst_heading_anchors = 3

# --- HTML ---------------------------------------------------------------------------
html_theme = "pydata_sphinx_theme"
html_title = f"fluxcal {release}"
html_theme_options = {
    "navigation_depth": 2,
    "show_toc_level": 2,
    "secondary_sidebar_items": ["page-toc"],
}
html_static_path: list[str] = []


# --- References sections -----------------------------------------------------------------
#: ``.. [1] ...`` that a docstring defines without citing it in its text
CITATION = re.compile(r"^(?P<indent>\s*)\.\. \[(?P<label>[^\]]+)\]\s?(?P<text>.*)$")


def _uncited_references_as_list(app, what, name, obj, options, lines) -> None:
    """Render a docstring's uncited ``.. [n]`` references as a plain numbered list.

    Most fluxcal docstrings name the procedure document in References without citing
    ``[1]_`` in the text; as citations those warn ("not referenced") and, for a module
    and its function of the same name, collide.  Runs after numpydoc (which renames the
    labels per docstring and adds a LaTeX-only block citing them all); references that
    the text cites stay citations.
    """
    latex: set[int] = set()
    for i, line in enumerate(lines):
        if line.strip() == ".. only:: latex":
            j = i + 1
            while j < len(lines) and (not lines[j].strip() or lines[j].startswith(" ")):
                latex.add(j)
                j += 1
            latex.add(i)
    labels = [m["label"] for m in map(CITATION.match, lines) if m]
    if not labels:
        return
    body = "\n".join(line for i, line in enumerate(lines) if i not in latex)
    uncited = {label for label in labels if f"[{label}]_" not in body}
    out: list[str] = []
    body_indent: int | None = None
    for i, line in enumerate(lines):
        if i in latex:
            cited = [f"[{label}]_" for label in labels if label not in uncited]
            if line.strip() == ".. only:: latex" and cited:
                out += [line, "", "   " + ", ".join(cited), ""]
            continue
        if body_indent is not None:
            if line.strip() and len(line) - len(line.lstrip()) > body_indent:
                out.append(" " * (body_indent + 2) + line.strip())
                continue
            body_indent = None
        m = CITATION.match(line)
        if m and out and out[-1].strip():
            out.append("")  # a list item or a citation after other markup: a blank first
        if m and m["label"] in uncited:
            number = m["label"].rsplit("-", 1)[-1]
            out.append(f"{m['indent']}- [{number}] {m['text']}")
            body_indent = len(m["indent"])
            continue
        out.append(line)
    lines[:] = out


def setup(app):
    """Connect the References hook after numpydoc's docstring processing."""
    app.connect("autodoc-process-docstring", _uncited_references_as_list, priority=900)
