from __future__ import annotations

from pathlib import Path

import pytest

import fluxcal
from fluxcal.products.provenance import checksums, provenance_attrs, sha256_file


def test_sha256_known_vector(tmp_path: Path) -> None:
    # FIPS 180-2 test vector: SHA-256("abc").
    p = tmp_path / "abc"
    p.write_bytes(b"abc")
    assert sha256_file(p) == "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad"


def test_provenance_attrs(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "86400")
    a = tmp_path / "a.csv"
    a.write_bytes(b"abc")
    cal = tmp_path / "table2.csv"
    cal.write_text("x")
    attrs = provenance_attrs(inputs=[a], calibration={"table2": cal, "heater": "v3"},
                             kernels=[a, "missing.bsp"], command_line="fluxcal x")
    assert attrs["software_version"] == fluxcal.__version__
    assert attrs["inputs"][0]["sha256"].startswith("ba7816bf")
    assert attrs["calibration"]["heater"] == {"version": "v3"}
    assert "sha256" in attrs["calibration"]["table2"]
    assert attrs["kernels"][1] == {"name": "missing.bsp"}
    assert attrs["inputs"][0] == {"name": "a.csv", "sha256": attrs["inputs"][0]["sha256"]}
    assert attrs["command_line"] == "fluxcal x"
    assert attrs["creation_time"] == "1970-01-02T00:00:00Z"
    sums = checksums(attrs)
    assert sums["input:a.csv"].startswith("ba7816bf")  # keyed by name, not by folder
    assert sums["calibration:heater"] == "v3"


def test_missing_input_is_an_error(tmp_path: Path) -> None:
    with pytest.raises(FileNotFoundError):
        provenance_attrs(inputs=[tmp_path / "nope.csv"])
