"""Whole-row TAB formatting (`fixedwidth.format_rows` via `format_chunk`/`write_tab`).

Oracle: Python's own ``%`` formatting of every field (correctly rounded, ties to
even); errors compared with the rule "first failing column in column order, its first
failing row", which the former one-column-at-a-time writer followed.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from fluxcal.errors import InputFormatError
from fluxcal.products import Column, write_tab
from fluxcal.products import fixedwidth as fw
from fluxcal.products.columns import resolve_columns
from fluxcal.products.tab import format_chunk


def _rows(ds: xr.Dataset, cols: list[Column]) -> list[str]:
    rc = resolve_columns(ds, cols)
    return [bytes(r).decode() for r in format_chunk(ds, rc, 0, ds.sizes["time"])]


def test_wide_table_takes_several_groups_and_matches_printf() -> None:
    """More variables of each kind than one kernel call holds: still one row each."""
    rng = np.random.default_rng(11)
    n, nvar = 300, fw.SLOTS * 2 + 3
    data = {f"r{k}": ("time", rng.normal(0, 10.0 ** (k % 5), n)) for k in range(nvar)}
    data |= {f"i{k}": ("time", rng.integers(-(10**k % 10**6), 10**6, n)) for k in range(nvar)}
    ds = xr.Dataset(data)
    cols, printf = [], []
    for k in range(nvar):  # interleaved kinds, widths and decimals
        d = k % 7
        cols += [Column(f"r{k}", f"F{12 + d}.{d}"), Column(f"i{k}", f"I{9 + k % 3}.{1 + k % 4}")]
        printf += [f"%{12 + d}.{d}f", f"%{9 + k % 3}.{1 + k % 4}d"]
    assert len(resolve_columns(ds, cols)) > 2 * fw.SLOTS
    line = " ".join(printf) + "\r\n"
    want = [line % tuple(v for k in range(nvar) for v in (ds[f"r{k}"].values[i],
                                                          ds[f"i{k}"].values[i]))
            for i in range(n)]
    assert _rows(ds, cols) == want


def test_mixed_kinds_signs_zero_pad_and_fill() -> None:
    """I/F/E/A side by side; -0.0, zero-padded negatives, NaN with and without fill."""
    x = np.array([-0.0, -0.0004, 0.0005, -1.5, 59.9996, np.nan, -9.9994, 1e-9])
    n = x.size
    ds = xr.Dataset({
        "x": ("time", x),
        "i": ("time", np.array([0, -1, 5, -99, 12345, -7, 3, 100], np.int32)),
        "u": ("time", np.array(["a", "bb", "c", "dd", "e", "f", "g", "h"])),
        "b": ("time", np.array([True, False] * (n // 2))),
    })
    cols = [Column("u", "A3"), Column("x", "%07.3f", label="xz"), Column("i", "I6.3"),
            Column("x", "F9.4", label="xf", fill=-999.0), Column("x", "E12.4", label="xe"),
            Column("x", "F8.3", label="xn"), Column("b", "I1")]
    filled = np.where(np.isnan(x), -999.0, x)

    def pr(spec: str, v: float) -> str:  # the writer prints NaN as "NaN", right-justified
        return "NaN".rjust(int(spec[1:].lstrip("0").split(".")[0])) if v != v else spec % v

    line = "%-3s %s %6.3d %s %s %s %1d\r\n"  # printf is the oracle
    want = [line % (u, pr("%07.3f", v), k, pr("%9.4f", f),
                                  pr("%12.4E", v), pr("%8.3f", v), b)
            for u, v, k, f, b in zip(ds["u"].values.tolist(), x.tolist(),
                                     ds["i"].values.tolist(), filled.tolist(),
                                     ds["b"].values.tolist(), strict=True)]
    assert _rows(ds, cols) == want


def test_integer_extremes() -> None:
    """int64 and uint64 limits that fit print as Python does; int64's minimum is refused."""
    v = np.array([np.iinfo(np.int64).max, np.iinfo(np.int64).min + 1, 0, -1])
    ds = xr.Dataset({"v": ("time", v), "u": ("time", np.array([2**63 - 1, 0, 7, 1],
                                                                np.uint64))})
    line = "%20d %25.22d\r\n"  # printf is the oracle
    assert _rows(ds, [Column("v", "I20"), Column("u", "I25.22")]) == [
        line % (a, b) for a, b in zip(v.tolist(), [2**63 - 1, 0, 7, 1],
                                                  strict=True)]
    low = xr.Dataset({"v": ("time", np.array([1, np.iinfo(np.int64).min]))})
    with pytest.raises(InputFormatError, match="row 1 is too large"):
        _rows(low, [Column("v", "I20")])
    big = xr.Dataset({"u": ("time", np.array([1, 2**63], np.uint64))})
    with pytest.raises(InputFormatError, match="beyond int64"):
        _rows(big, [Column("u", "I20")])


def test_first_failing_column_in_column_order_is_reported(tmp_path: Path) -> None:
    """Column b fails at row 1, column a (left of it) at row 3: a is named, row 3."""
    ds = xr.Dataset({"a": ("time", np.array([1.0, 2.0, 3.0, 12345.0])),
                     "b": ("time", np.array([1.0, -1e9, 3.0, 4.0]))})
    with pytest.raises(InputFormatError, match="row 3 does not fit") as exc:
        write_tab(ds, tmp_path / "P", [Column("a", "F7.3"), Column("b", "F8.2")])
    assert exc.value.field == "a"
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(("value", "fmt", "why"), [
    (-1.0, "F5.3", "does not fit"),  # -1.000 is 6 characters
    (-5, "I3.3", "does not fit"),  # -005
    (np.nan, "F3.3", "does not fit"),  # no room for the point and 3 decimals
    (np.nan, "F2.0", "does not fit"),  # NaN needs 3 characters
])
def test_does_not_fit(value: float, fmt: str, why: str) -> None:
    dtype = np.int64 if fmt.startswith("I") else np.float64
    ds = xr.Dataset({"v": ("time", np.array([0, value], dtype=dtype))})
    with pytest.raises(InputFormatError, match=why):
        _rows(ds, [Column("v", fmt)])


def test_float32_and_small_integer_sources_print_their_values() -> None:
    """Sources of other dtypes are widened to float64/int64 exactly before printing."""
    f = np.array([0.1, -2.5, 1e6], np.float32)
    i = np.array([-128, 0, 127], np.int8)
    ds = xr.Dataset({"f": ("time", f), "i": ("time", i)})
    assert _rows(ds, [Column("f", "F17.8"), Column("i", "I4")]) == [
        f"{float(a):17.8f} {int(b):4d}\r\n" for a, b in zip(f, i, strict=True)]
