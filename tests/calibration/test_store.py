"""The generic calibration store: versions, dates, user folder over defaults, aliases, errors.

Expected values are written by hand (the files the tests write) or by a brute-force
search over the same files (hypothesis), never taken from the store's own output.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fluxcal.calibration.store import (
    ENV_VAR,
    CalibrationStore,
    describe,
    read_header,
    user_folder,
)
from fluxcal.errors import CalibrationError, CalibrationRangeError, FluxcalError


def _table(folder: Path, file_name: str, version: int | str | None = None,
           valid: tuple[str, str] | None = ("2010-01-01", "2011-01-01"),
           source: str = "test table", body: str = "a,b\n1,2\n") -> Path:
    lines = ["# a calibration table written by the test"]
    if source:
        lines.append(f"# source: {source}")
    if version is not None:
        lines.append(f"# version: {version}")
    if valid is not None:
        lines += [f"# valid_from: {valid[0]}", f"# valid_to: {valid[1]}"]
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / file_name
    path.write_text("\n".join(lines) + "\n" + body, encoding="utf-8")
    return path


# ---------------------------------------------------------------------------------------
# one header format, read from the three syntaxes fluxcal's files use
# ---------------------------------------------------------------------------------------
def test_header_from_comment_lines(tmp_path):
    path = _table(tmp_path, "gain_v3.csv", 3, ("2010-01-01T00:00:00", "2012-06-01T12:00:00"),
                  "sec. 8, Table 4")
    h = read_header(path)
    assert (h.name, h.version, h.source) == ("gain", 3, "sec. 8, Table 4")
    assert h.valid_from == np.datetime64("2010-01-01T00:00:00")
    assert h.valid_to == np.datetime64("2012-06-01T12:00:00")
    assert h.checksum == hashlib.sha256(path.read_bytes()).hexdigest()
    assert h.field("Valid From") == "2010-01-01T00:00:00"  # case-blind, spaces as _
    assert h.field("units", "none") == "none"


def test_header_from_key_value_lines(tmp_path):
    path = tmp_path / "ALIGN.TXT"
    path.write_text("# Source: a memo, sec. 4\nVERSION = 007   # comment\n"
                    "VALID_FROM = 2004-03-02T00:00:00\nA_0 = 1 2 3\n", encoding="utf-8")
    h = read_header(path)
    assert (h.name, h.version, h.source) == ("ALIGN.TXT", 7, "a memo, sec. 4")
    assert h.valid_from == np.datetime64("2004-03-02") and h.valid_to is None
    assert h.covers("2099-01-01") and not h.covers("2004-03-01T23:59:59")


def test_header_from_toml_top_level_keys_only(tmp_path):
    path = tmp_path / "processing_v2.toml"
    path.write_text('# source: sec. 7\nversion = 2\nvalid_from = "2011-03-18T00:00:00"\n'
                    'valid_to = "2015-05-01T00:00:00"\n\n[fit]\nversion = 9\nsource = "x"\n',
                    encoding="utf-8")
    h = read_header(path)
    assert (h.name, h.version, h.source) == ("processing", 2, "sec. 7")
    assert h.valid_to == np.datetime64("2015-05-01")
    # a fitted file keeps the base's comment and adds a top-level source: the key wins
    path.write_text('# source: sec. 7\n# version: 1\nversion = 2\nsource = "fitted"\n',
                    encoding="utf-8")
    h = read_header(path)
    assert (h.version, h.source, h.field("source")) == (2, "fitted", "fitted")


def test_repr_is_one_short_line(tmp_path):
    h = read_header(_table(tmp_path, "gain_v1.csv", 1))
    assert "\n" not in repr(h) and len(repr(h)) < 110
    assert repr(h).startswith("TableHeader(gain v1, valid 2010-01-01T00:00:00 .. ")
    store = CalibrationStore(tmp_path / "data", tmp_path / "mine", aliases={"A": ["B", "C"]})
    assert repr(store) == "CalibrationStore(mine/ over data/, 1 tables, 2 aliases)"


# ---------------------------------------------------------------------------------------
# versions and dates
# ---------------------------------------------------------------------------------------
def test_highest_version_valid_at_the_time_wins(tmp_path):
    d = tmp_path / "data"
    _table(d, "gain_v1.csv", 1, ("2004-01-01", "2015-01-01"))
    _table(d, "gain_v2.csv", 2, ("2011-01-01", "2012-01-01"))
    _table(d, "gain_v3.csv", 3, ("2013-01-01", "2014-01-01"))
    store = CalibrationStore(d)
    assert store.resolve("gain", "2010-06-01").version == 1
    assert store.resolve("gain", "2011-06-01").version == 2
    assert store.resolve("gain", "2012-01-01T00:00:00").version == 1  # valid_to is open
    assert store.resolve("gain", "2013-01-01T00:00:00").version == 3  # valid_from is closed
    assert store.resolve("gain").version == 3  # no time: the highest version
    assert [h.version for h in store.versions("gain")] == [1, 2, 3]


def test_time_outside_every_interval_lists_them(tmp_path):
    d = tmp_path / "data"
    _table(d, "gain_v1.csv", 1, ("2004-01-01", "2015-01-01"))
    _table(d, "gain_v2.csv", 2, ("2011-01-01", "2012-01-01"))
    with pytest.raises(CalibrationRangeError) as err:
        CalibrationStore(d).resolve("gain", "2016-01-01")
    message = str(err.value)
    assert "\n" not in message and message.startswith(f"{d}: calibration table gain: ")
    assert "2016-01-01T00:00:00 lies outside every validity interval" in message
    assert "v1 [2004-01-01T00:00:00, 2015-01-01T00:00:00) gain_v1.csv" in message
    assert "v2 [2011-01-01T00:00:00, 2012-01-01T00:00:00) gain_v2.csv" in message


_DAY = np.datetime64("2010-01-01", "D")
_interval = st.tuples(st.integers(0, 60), st.integers(1, 30)).map(
    lambda a: (_DAY + a[0], _DAY + a[0] + a[1]))


@settings(max_examples=40, deadline=None)
@given(tables=st.lists(st.tuples(st.integers(0, 6), _interval), min_size=1, max_size=6),
       day=st.integers(-2, 95))
def test_resolution_matches_brute_force(tmp_path_factory, tables, day):
    """The chosen file is the highest version whose [from, to) covers the day (searched
    by hand over the files written); two files of that version are refused."""
    d = tmp_path_factory.mktemp("data")
    for k, (version, (start, stop)) in enumerate(tables):
        # distinct file names, same table: a fixed name for the first, aliases after it
        name = "T.TXT" if k == 0 else f"T{k}.TXT"
        _table(d, name, version, (str(start), str(stop)))
    store = CalibrationStore(d, aliases={"T.TXT": [f"T{k}.TXT" for k in range(1, 6)]})
    when = _DAY + day
    covering = [v for v, (a, b) in tables if a <= when < b]
    if not covering:
        with pytest.raises(CalibrationRangeError):
            store.resolve("T.TXT", when)
    elif covering.count(max(covering)) > 1:
        with pytest.raises(CalibrationError, match="keep one"):
            store.resolve("T.TXT", when)
    else:
        assert store.resolve("T.TXT", when).version == max(covering)


def test_text_versions_resolve_alone_and_never_compete(tmp_path):
    """``VERSION = sim-1`` (the simulator's) reads as text: fine alone, not orderable."""
    d = tmp_path / "data"
    _table(d, "ALIGN.TXT", "sim-1", None)
    store = CalibrationStore(d, aliases={"ALIGN.TXT": ["ALIGN.ASC"]})
    assert store.resolve("ALIGN.TXT").version == "sim-1"
    _table(d, "ALIGN.ASC", "2", None)
    with pytest.raises(CalibrationError, match=r"ALIGN.TXT: version 'sim-1' is not a whole "
                       r"number, so it cannot be ordered against ALIGN.ASC \(version 2\)"):
        store.resolve("ALIGN.TXT")


# ---------------------------------------------------------------------------------------
# user folder over shipped defaults
# ---------------------------------------------------------------------------------------
def test_user_folder_hides_the_defaults_table_by_table(tmp_path):
    d, u = tmp_path / "data", tmp_path / "mine"
    _table(d, "gain_v1.csv", 1)
    _table(d, "gain_v5.csv", 5)
    _table(d, "lag_v1.csv", 1)
    _table(u, "gain_v2.csv", 2)  # lower than the shipped v5, still the one used
    store = CalibrationStore(d, u, names=["gain", "lag"])
    assert store.resolve("gain", "2010-06-01").path == u / "gain_v2.csv"
    assert store.resolve("lag", "2010-06-01").path == d / "lag_v1.csv"
    assert store.folders == (u, d)
    listed = store.tables("2010-06-01")
    assert [h.path for h in listed[:2]] == [u / "gain_v2.csv", d / "lag_v1.csv"]
    assert {h.path for h in listed[2:]} == {d / "gain_v1.csv", d / "gain_v5.csv"}
    lines = describe(listed, 2)
    assert [line[0] for line in lines] == ["*", "*", " ", " "]
    assert "mine/gain_v2.csv" in lines[0] and "sha256 " in lines[0]


def test_user_folder_from_argument_then_environment():
    assert user_folder("a", {ENV_VAR: "b"}) == Path("a")
    assert user_folder(None, {ENV_VAR: "b"}) == Path("b")
    assert user_folder(None, {ENV_VAR: "  "}) is None
    assert user_folder(None, {}) is None


def test_missing_user_folder_is_an_error(tmp_path):
    _table(tmp_path / "data", "gain_v1.csv", 1)
    with pytest.raises(CalibrationError, match="user calibration folder does not exist"):
        CalibrationStore(tmp_path / "data", tmp_path / "nope").resolve("gain")


# ---------------------------------------------------------------------------------------
# aliases
# ---------------------------------------------------------------------------------------
def test_alias_in_user_folder_replaces_the_default(tmp_path):
    d, u = tmp_path / "data", tmp_path / "mine"
    _table(d, "GROUND_FM.TXT", "001", None)
    _table(u, "ARCHIVE_GND_FM.ASC", "001", None)
    store = CalibrationStore(d, u, aliases={"GROUND_FM.TXT": ["ARCHIVE_GND_FM.ASC"]})
    h = store.resolve("GROUND_FM.TXT")
    assert h.path == u / "ARCHIVE_GND_FM.ASC" and h.name == "GROUND_FM.TXT"
    assert store.table_of("ARCHIVE_GND_FM.ASC") == "GROUND_FM.TXT"
    assert store.table_of("other.txt") is None


def test_two_names_of_one_table_same_version_is_ambiguous(tmp_path):
    u = tmp_path / "mine"
    _table(u, "GROUND_FM.TXT", "001", None)
    _table(u, "ARCHIVE_GND_FM.ASC", "001", None)
    store = CalibrationStore(tmp_path, u, aliases={"GROUND_FM.TXT": ["ARCHIVE_GND_FM.ASC"]})
    with pytest.raises(CalibrationError) as err:
        store.resolve("GROUND_FM.TXT")
    assert str(err.value) == (f"{u}: both ARCHIVE_GND_FM.ASC and GROUND_FM.TXT hold "
                              "calibration table GROUND_FM.TXT version 1: keep one")
    _table(u, "ARCHIVE_GND_FM.ASC", "002", None)  # a higher version: that one
    assert store.resolve("GROUND_FM.TXT").path == u / "ARCHIVE_GND_FM.ASC"


# ---------------------------------------------------------------------------------------
# errors: one line naming the file, the line and the field; exit 2 through the CLI
# ---------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("file_name", "version", "valid", "expected"),
    [
        ("gain_v1.csv", "one", ("2010-01-01", "2011-01-01"),
         r"gain_v1.csv, line 3: header field 'version' one differs from the file name's v1"),
        ("gain_v1.csv", 2, ("2010-01-01", "2011-01-01"),
         r"gain_v1.csv, line 3: header field 'version' 2 differs from the file name's v1"),
        ("gain_v1.csv", 1, ("2010-13-01", "2011-01-01"),
         r"gain_v1.csv, line 4: header field 'valid_from' '2010-13-01' is not an ISO UTC time"),
        ("gain_v1.csv", 1, ("2011-01-01", "2010-01-01"),
         r"gain_v1.csv, line 5: header field 'valid_to' 2010-01-01T00:00:00 is not after"),
        ("gain_v1.csv", 1, None, r"gain_v1.csv: header field 'valid_from' is missing"),
    ],
)
def test_malformed_header_is_one_line(tmp_path, file_name, version, valid, expected):
    _table(tmp_path, file_name, version, valid)
    store = CalibrationStore(tmp_path, require=("version", "valid_from", "valid_to"))
    with pytest.raises(CalibrationError, match=expected) as err:
        store.resolve("gain", "2010-06-01")
    assert isinstance(err.value, FluxcalError) and "\n" not in str(err.value)


def test_missing_table_names_both_folders_and_the_file_names(tmp_path):
    (tmp_path / "mine").mkdir()
    store = CalibrationStore(tmp_path / "data", tmp_path / "mine", aliases={"G.TXT": ["G.ASC"]})
    with pytest.raises(CalibrationError) as err:
        store.resolve("G.TXT")
    assert str(err.value) == (f"calibration table G.TXT found neither in {tmp_path / 'mine'} "
                              f"nor in {tmp_path / 'data'} (file names G.TXT_v<N>.*, G.TXT, "
                              "G.ASC)")
    with pytest.raises(CalibrationError, match="not found in"):
        CalibrationStore(tmp_path / "data").resolve("gain")


def test_binary_table_is_refused_naming_the_line(tmp_path):
    (tmp_path / "gain_v1.csv").write_bytes(b"# version: 1\n\x00\x01CDF")
    with pytest.raises(CalibrationError, match=r"gain_v1.csv, line 2: not a text file"):
        CalibrationStore(tmp_path).resolve("gain")

