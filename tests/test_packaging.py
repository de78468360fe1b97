"""Package metadata, licence, changelog and citation file (issue 25)."""

import re
import tomllib
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[1]


def _released_version() -> str:
    """The newest release the changelog names (the version comes from the git tags)."""
    text = (ROOT / "CHANGELOG.md").read_text()
    return re.findall(r"^## \[(\d[^\]]*)\]", text, re.M)[0]


@pytest.fixture(scope="module")
def project() -> dict:
    return tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]


def test_license_file_is_the_declared_bsd_3_clause(project):
    text = (ROOT / "LICENSE").read_text()
    assert project["license"] == "BSD-3-Clause"
    assert "LICENSE" in project["license-files"]
    # the three clauses of the SPDX BSD-3-Clause text, and the holder
    assert "Copyright (c)" in text and "fluxcal developers" in text
    assert "Neither the name of the copyright holder nor the names of its" in text
    assert text.count("\n\n1. ") + text.count("\n\n2. ") + text.count("\n\n3. ") == 3


def test_metadata_is_complete_and_placeholder_free(project):
    assert project["authors"] and all(a.get("name") for a in project["authors"])
    assert project["keywords"] and project["classifiers"]
    # PEP 639: a licence expression excludes the legacy licence classifiers
    assert not [c for c in project["classifiers"] if c.startswith("License ::")]
    for url in project.get("urls", {}).values():
        assert "example" not in url and "TODO" not in url, url


def test_extras_split_by_purpose_and_make_test_installs_the_same_tools(project):
    extras = project["optional-dependencies"]
    names = {k: {d.split(">")[0].split("[")[0].split("=")[0].strip() for d in v}
             for k, v in extras.items()}
    assert names["test"] == {"pytest", "pytest-xdist", "hypothesis", "pytest-benchmark",
                             "build", "setuptools-scm", "setuptools"}
    assert names["lint"] == {"ruff"}
    assert names["interop"] == {"pdr", "spacepy", "pyspedas", "sunpy", "mpl-animators"}
    assert {"sphinx", "numpydoc", "myst-parser"} <= names["docs"]
    makefile = (ROOT / "Makefile").read_text()
    # the core installs without matplotlib, dask and zarr; make test installs them
    assert {"plot", "batch", "zarr"} <= set(extras)
    core = " ".join(project["dependencies"])
    assert not {"matplotlib", "dask", "distributed", "zarr"} & set(re.findall(r"[\w-]+", core))
    assert '-e ".[test,lint,interop,plot,batch,zarr]"' in makefile


def test_citation_cff_is_valid_cff_1_2(project):
    cff = yaml.safe_load((ROOT / "CITATION.cff").read_text())
    # the keys CFF 1.2.0 requires, and an author that is a person or an entity
    for key in ("cff-version", "message", "title", "authors"):
        assert cff.get(key), key
    assert cff["cff-version"] == "1.2.0"
    assert all(("name" in a) or ("family-names" in a) for a in cff["authors"])
    assert cff["version"] == _released_version()
    assert cff["license"] == project["license"]
    assert str(cff["date-released"]) and cff.get("type") == "software"


def test_changelog_has_an_entry_for_the_current_version(project):
    text = (ROOT / "CHANGELOG.md").read_text()
    assert text.startswith("# Changelog")
    assert "## [Unreleased]" in text
    assert f"## [{_released_version()}]" in text

