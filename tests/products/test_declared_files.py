"""Declared files, refusals and dated quicklooks (`fluxcal.products.declared`, issue 32).

Expected values are the declarations themselves (the bytes given, the error given, the
samples given): the runner must write them as declared, all or nothing.
"""

import datetime as dt
import gc
import weakref

import numpy as np
import pytest
import xarray as xr

import fluxcal.products.quicklook as quicklook
from fluxcal.errors import InputFormatError, ValidationError
from fluxcal.products.declared import File, Product, Quicklook, Refused, write_declared

DAY = dt.date(2024, 1, 1)
EPOCH_2024 = 757_339_269_184_000_000  # TT2000 of 2024-01-01T00:00:00 UTC (cdflib)
S = 10**9


def _field(epoch):
    epoch = np.asarray(epoch, dtype=np.int64)
    return xr.Dataset({"b": (("time", "component"), np.ones((epoch.size, 3)),
                             {"units": "nT"})},
                      coords={"epoch": ("time", epoch), "component": ["x", "y", "z"]})


def _none(product):
    return {}


def test_files_are_written_as_declared(tmp_path):
    written = write_declared([File("a.txt", "text\n", DAY), File("b.bin", b"\x00\x01"),
                              File("c.txt", lambda tmp: tmp.write_text("made when written"))],
                             tmp_path, _none)
    assert [p.name for p in written] == ["a.txt", "b.bin", "c.txt"]
    assert (tmp_path / "a.txt").read_bytes() == b"text\n"
    assert (tmp_path / "b.bin").read_bytes() == b"\x00\x01"
    assert (tmp_path / "c.txt").read_text() == "made when written"


def test_a_file_of_another_day_is_not_written_on_a_batch_day(tmp_path):
    later = DAY + dt.timedelta(days=1)
    written = write_declared([File("a.txt", "a", DAY), File("b.txt", "b", later)],
                             tmp_path, _none, only_day=later)
    assert [p.name for p in written] == ["b.txt"]


def test_a_file_name_with_a_folder_is_refused(tmp_path):
    with pytest.raises(InputFormatError, match="file name"):
        write_declared([File("../a.txt", "a")], tmp_path / "out", _none)
    assert not (tmp_path / "a.txt").exists()


def test_refused_is_raised_after_the_others_are_written(tmp_path):
    error = ValidationError("day 2: not smooth")
    with pytest.raises(ValidationError) as caught:
        write_declared([File("a.txt", "a"), Refused(error, DAY), File("b.txt", "b")],
                       tmp_path, _none)
    assert caught.value is error
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.txt", "b.txt"]


def test_several_refusals_are_one_error_naming_each(tmp_path):
    with pytest.raises(ValidationError, match="^day 1: a; day 3: b$"):
        write_declared([Refused(ValidationError("day 1: a")), File("a.txt", "a"),
                        Refused(ValidationError("day 3: b"))], tmp_path, _none)
    assert [p.name for p in tmp_path.iterdir()] == ["a.txt"]


def test_a_refusal_of_another_day_is_not_raised_on_a_batch_day(tmp_path):
    later = DAY + dt.timedelta(days=1)
    written = write_declared([File("a.txt", "a", DAY),
                              Refused(ValidationError("later"), later)],
                             tmp_path, _none, only_day=DAY)
    assert [p.name for p in written] == ["a.txt"]


def test_an_error_after_a_file_writes_nothing(tmp_path):
    def failing(tmp):
        raise RuntimeError("injected")

    with pytest.raises(RuntimeError, match="injected"):
        write_declared([File("a.txt", "a"), File("b.txt", failing)], tmp_path, _none)
    assert list(tmp_path.iterdir()) == []


def test_a_dated_quicklook_is_drawn_as_declared_on_a_batch_day(tmp_path, monkeypatch):
    """The mission's day (samples up to 2 s after its midnight) is not cut at midnight."""
    drawn = []
    monkeypatch.setattr(quicklook, "write_quicklooks",
                        lambda ds, out, name, field, frame: drawn.append(ds.sizes["time"]) or [])
    epoch = EPOCH_2024 + np.array([3600, 86_399, 86_401]) * S
    write_declared([Quicklook("Q", _field(epoch), day=DAY)], tmp_path, _none, only_day=DAY)
    assert drawn == [3]
    # undated: the batch day's own UTC samples only (the runner splits)
    write_declared([Quicklook("Q", _field(epoch))], tmp_path, _none, only_day=DAY)
    assert drawn == [3, 2]


def test_a_product_is_released_before_the_next_is_made(tmp_path):
    """A generator's product is no longer held by the runner when the next one is made."""
    alive = []

    def declarations():
        first = _field(EPOCH_2024 + np.arange(3) * S)
        ref = weakref.ref(first)
        yield Product("A", first, day=DAY, formats=("nc",))
        del first
        gc.collect()
        alive.append(ref() is not None)
        yield File("b.txt", "b", DAY)

    written = write_declared(declarations(), tmp_path, _none)
    assert [p.name for p in written] == ["A.nc", "b.txt"]
    assert alive == [False]
