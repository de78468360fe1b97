"""Bad-input files: every defect is an InputFormatError naming file, line and field."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fluxcal.errors import InputFormatError
from fluxcal.missions.messenger import readers
from fluxcal.missions.messenger.readers import read_heater, read_science, read_temperature

SCI_HEADER = "partition,met,rate,range,cx,cy,cz"
GOOD_SCI = ["1,1000.000000,10,0,100,-200,300", "1,1000.050000,10,0,101,-201,301",
            "1,1000.100000,10,1,5,-6,7"]


def _write(tmp_path, name, lines):
    p = tmp_path / name
    p.write_text("\n".join(lines) + "\n")
    return p


def test_good_science(tmp_path):
    ds = read_science(_write(tmp_path, "s.csv", [SCI_HEADER, *GOOD_SCI]))
    assert ds.sizes["time"] == 3
    np.testing.assert_array_equal(ds["counts"].values[2], [5, -6, 7])
    np.testing.assert_array_equal(ds["range"].values, [0, 0, 1])


def test_column_order_free(tmp_path):
    lines = ["met,partition,rate,range,cz,cy,cx", "1000.0,1,10,0,3,2,1"]
    ds = read_science(_write(tmp_path, "s.csv", lines))
    np.testing.assert_array_equal(ds["counts"].values[0], [1, 2, 3])


@pytest.mark.parametrize(
    ("lines", "line", "field", "match"),
    [
        (["partition,met,rate,range,cx,cy,cz,extra", "1,1,10,0,1,2,3,4"], 1, "extra",
         "unknown column"),
        ([SCI_HEADER, GOOD_SCI[0], "1,1000.05,10,0,abc,2,3"], 3, "cx", "non-numeric"),
        ([SCI_HEADER, GOOD_SCI[0], "1,1000.05,11,0,1,2,3"], 3, "rate", "rate settings"),
        ([SCI_HEADER, GOOD_SCI[0], "1,1000.05,-1,0,1,2,3"], 3, "rate", "rate settings"),
        ([SCI_HEADER, GOOD_SCI[0], "1,1000.05,10,2,1,2,3"], 3, "range", "range flags"),
        ([SCI_HEADER, GOOD_SCI[0], "1,1000.05,10,0,1,40000,3"], 3, "cy", "count limits"),
        ([SCI_HEADER, GOOD_SCI[0], "1,1000.05,10,0,1,2,-32769"], 3, "cz", "count limits"),
        ([SCI_HEADER, GOOD_SCI[0], "1,999.0,10,0,1,2,3"], 3, "met", "backwards"),
        ([SCI_HEADER, GOOD_SCI[0], "3,1001.0,10,0,1,2,3"], 3, "partition", "partitions"),
        ([SCI_HEADER, GOOD_SCI[0], "1,1000.05,10,0,1.5,2,3"], 3, "cx", "1.5 is not an integer"),
    ],
)
def test_bad_science(tmp_path, lines, line, field, match):
    path = _write(tmp_path, "bad.csv", lines)
    with pytest.raises(InputFormatError, match=match) as info:
        read_science(path, on_clock_jump="raise")  # the default drops MET going back
    err = info.value
    assert err.path == str(path) and err.line == line and err.field == field
    assert str(path) in str(err) and f"line {line}" in str(err)


def test_wrong_field_count(tmp_path):
    path = _write(tmp_path, "bad.csv", [SCI_HEADER, GOOD_SCI[0], "1,1000.05,10,0,1,2"])
    with pytest.raises(InputFormatError, match="expected 7 fields") as info:
        read_science(path)
    assert info.value.line == 3


def test_backwards_across_files(tmp_path):
    a = _write(tmp_path, "a.csv", [SCI_HEADER, "1,2000.0,10,0,1,2,3", "1,2001.0,10,0,1,2,3"])
    b = _write(tmp_path, "b.csv", [SCI_HEADER, "1,2000.5,10,0,1,2,3"])
    with pytest.raises(InputFormatError, match="across files"):
        read_science([a, b], on_clock_jump="raise")
    # issue 23: by default the sample off the time-ordered run is dropped and counted
    ds = read_science([a, b])
    assert ds["met"].values.tolist() in ([2000.0, 2001.0], [2000.0, 2000.5])
    assert ds.attrs["clock_jumps"][0][3] == 1.0


def test_files_sorted_by_time(tmp_path):
    a = _write(tmp_path, "a.csv", [SCI_HEADER, "1,3000.0,10,0,1,2,3"])
    b = _write(tmp_path, "b.csv", [SCI_HEADER, "1,2000.0,10,0,4,5,6"])
    ds = read_science([a, b])
    np.testing.assert_array_equal(ds["met"].values, [2000.0, 3000.0])


def test_heater_gap_longer_than_period(tmp_path):
    lines = ["partition,met,heater"] + [f"1,{t},0" for t in range(10)] + ["1,111,1"]
    path = _write(tmp_path, "h.csv", lines)
    with pytest.raises(InputFormatError, match="exceeds one heater period") as info:
        read_heater(path, on_gap="raise")
    assert info.value.line == 12 and info.value.field == "met"


def test_heater_gap_between_files(tmp_path):
    a = _write(tmp_path, "a.csv", ["partition,met,heater", "1,0,0", "1,1,0"])
    b = _write(tmp_path, "b.csv", ["partition,met,heater", "1,200,0"])
    with pytest.raises(InputFormatError, match="heater period"):
        read_heater([a, b], on_gap="raise")
    assert read_heater([a, b]).attrs["stream_gaps"] == [[1.0, 1.0, 200.0]]  # issue 23


def test_temperature_gap_longer_than_limit(tmp_path):
    """A 601-s hole in the temperature stream is not bridged by the interpolation."""
    lines = ["partition,met,temperature_c"] + [f"1,{t}.0,20.0" for t in range(0, 100, 10)]
    lines.append("1,691.0,21.0")  # 90 -> 691: 601 s > 600 s
    path = _write(tmp_path, "t.csv", lines)
    with pytest.raises(InputFormatError, match="temperature stream gap of 601 s") as info:
        read_temperature(path, on_gap="raise")
    assert read_temperature(path).attrs["stream_gaps"] == [[1.0, 90.0, 691.0]]  # issue 23
    assert info.value.line == 12 and info.value.field == "met" and "t.csv" in str(info.value)
    read_temperature(path, max_gap_s=700.0)  # an explicit, longer limit accepts it
    lines[-1] = "1,690.0,21.0"  # exactly 600 s: accepted
    assert read_temperature(_write(tmp_path, "ok.csv", lines)).sizes["temperature_time"] == 11


def test_temperature_gap_between_files(tmp_path):
    a = _write(tmp_path, "a.csv", ["partition,met,temperature_c", "1,0,20", "1,10,20"])
    b = _write(tmp_path, "b.csv", ["partition,met,temperature_c", "1,1000,20"])
    with pytest.raises(InputFormatError, match="between") as info:
        read_temperature([a, b], on_gap="raise")
    assert info.value.line == 2 and "b.csv" in str(info.value)


def test_heater_bad_bit(tmp_path):
    path = _write(tmp_path, "h.csv", ["partition,met,heater", "1,0,0", "1,1,2"])
    with pytest.raises(InputFormatError, match="heater bit") as info:
        read_heater(path)
    assert info.value.line == 3 and info.value.field == "heater"


def test_temperature_unknown_column_and_range(tmp_path):
    path = _write(tmp_path, "t.csv", ["partition,met,temp", "1,0,-50"])
    with pytest.raises(InputFormatError, match="unknown column") as info:
        read_temperature(path)
    assert info.value.field == "temp"
    path = _write(tmp_path, "t2.csv", ["partition,met,temperature_c", "1,0,-50", "1,10,900"])
    with pytest.raises(InputFormatError, match="outside") as info:
        read_temperature(path)
    assert info.value.line == 3


def test_missing_column(tmp_path):
    path = _write(tmp_path, "t.csv", ["partition,met", "1,0"])
    with pytest.raises(InputFormatError, match="missing column") as info:
        read_temperature(path)
    assert info.value.field == "temperature_c"


def test_nan_rejected(tmp_path):
    path = _write(tmp_path, "t.csv", ["partition,met,temperature_c", "1,0,nan"])
    with pytest.raises(InputFormatError, match="non-finite") as info:
        read_temperature(path)
    assert info.value.line == 2 and info.value.field == "temperature_c"


def test_writer_reader_round_trip(simulated, simulated_files):
    """write_inputs -> read_* gives back the simulated streams (MET to the microsecond)."""
    sci = read_science(simulated_files["science"])
    ref = simulated["science"]
    for name in ("partition", "rate", "range", "counts"):
        np.testing.assert_array_equal(sci[name].values, ref[name].values)
    np.testing.assert_allclose(sci["met"].values, ref["met"].values, rtol=0, atol=5e-7)
    heat = read_heater(simulated_files["heater"])
    np.testing.assert_array_equal(heat["heater"].values, simulated["heater"]["heater"].values)
    temp = read_temperature(simulated_files["temperature"])
    np.testing.assert_allclose(temp["temperature_c"].values,
                               simulated["temperature"]["temperature_c"].values, atol=5e-5)


@pytest.mark.parametrize(
    ("body", "line", "field", "match"),
    [
        (["1,1000.0,10,0,1,2,3", "", "1,1000.1,10,0,1,2,3"], 3, None, "empty line"),
        (["1,1000.0,10,0,1,2,3", "1,1000.1,10,0,,2,3"], 3, "cx", "non-numeric"),
        (["1,1000.0,10,0,1,2,3", "1,1000.1,10,0,NA,2,3"], 3, "cx", "non-numeric"),
        (["1,1000.0,10,0,1,2,3", "1,1000.1,10,0,1,2,3,4"], 3, None, "expected 7 fields"),
        (["1,1000.0,10,0,1,2,3", "1,inf,10,0,1,2,3"], 3, "met", "non-finite"),
    ],
)
def test_fast_reader_defects_name_line_and_field(tmp_path, body, line, field, match):
    """The pyarrow reader rejects what it cannot parse; the message names line and field."""
    path = _write(tmp_path, "bad.csv", [SCI_HEADER, *body])
    with pytest.raises(InputFormatError, match=match) as info:
        read_science(path)
    assert info.value.line == line and info.value.field == field


def test_header_only_and_blank_padded_numbers(tmp_path):
    assert read_science(_write(tmp_path, "empty.csv", [SCI_HEADER])).sizes["time"] == 0
    ds = read_science(_write(tmp_path, "pad.csv", [SCI_HEADER, "1, 1000.5,10,0,1,2,3"]))
    assert ds["met"].values.tolist() == [1000.5]


# The compiled reader of plain decimal fields (`readers._parse_plain`) against Python's
# ``float`` (correctly rounded, an independent parser): bit-identical doubles, no tolerance.
_decimal = st.builds(
    lambda neg, whole, frac: ("-" if neg else "") + whole + ("." + frac if frac else ""),
    st.booleans(), st.text("0123456789", min_size=1, max_size=9),
    st.text("0123456789", min_size=0, max_size=6),  # <= 15 digits: mantissa < 2**53
)


@settings(max_examples=60, deadline=None)
@given(met=st.lists(_decimal, min_size=1, max_size=20),
       counts=st.lists(st.integers(-32768, 32767), min_size=3, max_size=3),
       final_newline=st.booleans())
def test_plain_fields_parse_as_python_float(tmp_path_factory, met, counts, final_newline):
    tmp = tmp_path_factory.mktemp("plain")
    lines = [f"1,{m},10,{i % 2},{counts[0]},{counts[1]},{counts[2]}" for i, m in enumerate(met)]
    path = tmp / "s.csv"
    path.write_text("\n".join([SCI_HEADER, *lines]) + ("\n" if final_newline else ""))
    data = readers._parse_plain(path, 7, list(range(7)))
    assert data is not None and data.shape == (7, len(met))
    expected = np.array([float(m) for m in met])
    assert data[1].tobytes() == expected.tobytes()  # sign of zero included
    np.testing.assert_array_equal(data[4:7].T, np.tile(counts, (len(met), 1)))


@pytest.mark.parametrize(
    "field",
    ["+5", "1e3", "5.", ".5", " 12", "12345678901234567890", "0.1234567890123456789",
     "9007199254740993"],
)
def test_other_number_forms_go_to_the_general_parser(tmp_path, field):
    """Forms outside ``-?digits[.digits]`` (or beyond exact conversion) are left to pyarrow.

    The result is still Python's ``float`` of the field (correctly rounded both ways).
    """
    path = _write(tmp_path, "s.csv", [SCI_HEADER, f"1,{field},10,0,1,2,3"])
    assert readers._parse_plain(path, 7, list(range(7))) is None
    assert read_science(path)["met"].values.tolist() == [float(field)]


def test_crlf_lines_and_column_order(tmp_path):
    """CRLF files take the general path; a permuted header is mapped in both paths."""
    path = tmp_path / "crlf.csv"
    path.write_bytes(b"partition,met,rate,range,cx,cy,cz\r\n1,1000.5,10,0,1,2,3\r\n")
    assert readers._parse_plain(path, 7, list(range(7))) is None
    assert read_science(path)["met"].values.tolist() == [1000.5]
    order = [1, 0, 2, 3, 6, 5, 4]  # expected column j is file column order[j]
    lines = ["met,partition,rate,range,cz,cy,cx", "1000.0,1,10,0,3,2,1", "1000.5,2,9,1,-3,-2,-1"]
    data = readers._parse_plain(_write(tmp_path, "p.csv", lines), 7, order)
    np.testing.assert_array_equal(data.T, [[1, 1000.0, 10, 0, 1, 2, 3],
                                           [2, 1000.5, 9, 1, -1, -2, -3]])


def test_partition_order_decides_before_met(tmp_path):
    """A new clock partition may restart MET; a partition going back is an error."""
    ok = _write(tmp_path, "ok.csv", [SCI_HEADER, "1,5000.0,10,0,1,2,3", "2,10.0,10,0,1,2,3",
                                     "2,10.05,10,0,1,2,3"])
    assert read_science(ok)["partition"].values.tolist() == [1, 2, 2]
    bad = _write(tmp_path, "bad.csv", [SCI_HEADER, "2,10.0,10,0,1,2,3", "2,11.0,10,0,1,2,3",
                                       "1,5000.0,10,0,1,2,3"])
    with pytest.raises(InputFormatError, match="backwards") as info:
        read_science(bad, on_clock_jump="raise")
    assert info.value.line == 4 and info.value.field == "met"
    assert read_science(bad)["partition"].values.tolist() == [2, 2]  # issue 23: dropped


def test_header_without_newline_takes_the_general_path(tmp_path):
    path = tmp_path / "h.csv"
    path.write_text(SCI_HEADER)
    assert readers._parse_plain(path, 7, list(range(7))) is None
    assert read_science(path).sizes["time"] == 0
