"""MESSENGER MAG EDRs (PDS3 labels + tables) through the declared mapping (issue 14 item 3).

Expected values come from (a) the CSV route on the same simulation (the EDR fixtures are
written by `edr_write`, which packs the simulated samples into packets without using the
reader's code), (b) the packet time rule written out in closed form on hand-written
tables, (c) Table 1's sample rates typed from the seed.
"""

import logging
import tempfile
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
from hypothesis import given, settings
from hypothesis import strategies as st

from fluxcal.cli import main
from fluxcal.errors import InputFormatError
from fluxcal.geometry.kernels import KernelPool
from fluxcal.geometry.time import SclkKernel
from fluxcal.missions.messenger.edr import load_mapping, read_edr
from fluxcal.missions.messenger.edr_write import (
    filled_mapping,
    template_path,
    write_edr_archive,
)
from fluxcal.missions.messenger.readers import read_heater, read_science, read_temperature
from fluxcal.missions.messenger.routes import run_edr2cdr, run_edr_archive
from fluxcal.missions.messenger.simulate import SimulationConfig, simulate, write_inputs
from fluxcal.missions.messenger.synthetic_kernels import write_messenger_like_kernels
from fluxcal.products import read_fluxcal_product

#: Table 1 of the seed (sec. 5): sample rate (1/s) per rate setting 0..10.
TABLE1_HZ = [0.01, 0.02, 0.05, 0.10, 0.20, 0.50, 1.00, 2.0, 5.0, 10.0, 20.0]
C0, C1 = -150.0, 0.0625  # the simulation's temperature conversion (filled_mapping default)


def _quantised(sim):
    """The simulation with temperatures on the conversion's 1/16 degC counts (a copy)."""
    out = dict(sim)
    t = sim["temperature"]["temperature_c"]
    out["temperature"] = sim["temperature"].assign(
        temperature_c=C0 + C1 * np.rint((t - C0) / C1))
    return out


def _csv_streams(paths):
    return (read_science([paths["science"]]), read_heater([paths["heater"]]),
            read_temperature([paths["temperature"]]))


def _assert_same(edr, csv):
    # identical values, dtypes and dims; only the 'inputs' attribute (file names) differs
    for a, b in zip(edr, csv, strict=True):
        xr.testing.assert_identical(a.assign_attrs(inputs=""), b.assign_attrs(inputs=""))


@pytest.fixture(scope="module")
def archive(tmp_path_factory, simulated, messenger_kernels):
    """The conftest simulation as CSV and as EDRs (versions 9 and 1 wrong, 10 right)."""
    root = tmp_path_factory.mktemp("msgr_edr")
    sim = _quantised(simulated)
    mapping = filled_mapping(template_path(), root / "mapping.toml")
    with KernelPool(messenger_kernels):
        write_edr_archive(sim, root / "edr", mapping, SclkKernel.from_pool(-236),
                          version=10, superseded=(9, 1))
    return {"root": root, "mapping": mapping, "edr": root / "edr",
            "csv": write_inputs(sim, root / "csv")}


def test_edr_route_reads_the_csv_routes_streams(archive, caplog):
    with caplog.at_level(logging.INFO, logger="fluxcal.missions.messenger.edr"):
        edr = read_edr(archive["edr"], archive["mapping"])
    _assert_same(edr, _csv_streams(archive["csv"]))
    # V10 read, V9 and V1 skipped (numeric, not text, order of versions), and said so
    skipped = [r.getMessage() for r in caplog.records if "skipped" in r.getMessage()]
    assert any("_V9.LBL" in s for s in skipped) and any("_V1.LBL" in s for s in skipped)
    assert not any("_V10" in s.split(" skipped")[0] for s in skipped)
    assert all("_V10.LBL" in p for p in edr[0].attrs["inputs"].split(";"))


def test_edr_route_products_identical_to_csv_route(archive, messenger_kernels, tmp_path):
    opts = dict(frames=("mso", "rtn"), formats=("tab",), averages=(60,))
    csv = run_edr2cdr([archive["csv"]["science"]], [archive["csv"]["heater"]],
                      [archive["csv"]["temperature"]], messenger_kernels, tmp_path / "csv",
                      **opts)
    edr = run_edr_archive(archive["edr"], archive["mapping"], messenger_kernels,
                          tmp_path / "edr", **opts)
    tabs = sorted(p.name for p in csv if p.suffix == ".TAB")
    assert tabs == sorted(p.name for p in edr if p.suffix == ".TAB") and len(tabs) == 4
    for name in tabs:  # the net lag is subtracted once, by the pipeline, on both routes
        assert (tmp_path / "csv" / name).read_bytes() == (tmp_path / "edr" / name).read_bytes()
    label = (tmp_path / "edr" / tabs[0]).with_suffix(".LBL").read_text()
    assert "MAGSCI" in label and "mapping.toml" in label  # provenance names the EDRs


def test_header_rows_only_at_state_changes_join_the_same(archive, simulated,
                                                         messenger_kernels, tmp_path):
    # the science-header EDR with a row only where the rate changes (several changes
    # mid-day: 20, 5, 1, 10, 20 Hz): each packet takes the latest state at or before it
    with KernelPool(messenger_kernels):
        write_edr_archive(_quantised(simulated), tmp_path / "edr", archive["mapping"],
                          SclkKernel.from_pool(-236), superseded=(), header="changes")
    shd = sorted((tmp_path / "edr").rglob("MAGSHD*.TAB"))
    n_rows = sum(len(p.read_bytes().splitlines()) for p in shd)
    assert n_rows < 10  # a handful of state rows, not one per packet
    _assert_same(read_edr(tmp_path / "edr", archive["mapping"]), _csv_streams(archive["csv"]))


@pytest.mark.parametrize("counts", ["three_columns", "one_column"])
def test_packet_per_row_layout(archive, simulated, messenger_kernels, tmp_path, counts):
    # one row per packet, samples as ITEMS (I = item number), a valid-sample count
    text = archive["mapping"].read_text().replace('from = "rows"', 'from = "items"')
    text += '\n[science.sample_count]\ncolumn = "NSAMPLES"\n'
    if counts == "three_columns":  # x, y, z columns of N items each
        text = text.replace('column = "MAG_COUNTS"', 'columns = ["BX", "BY", "BZ"]')
    (tmp_path / "m.toml").write_text(text)  # else MAG_COUNTS of 3N items x1 y1 z1 x2 ...
    with KernelPool(messenger_kernels):
        write_edr_archive(_quantised(simulated), tmp_path / "edr", tmp_path / "m.toml",
                          SclkKernel.from_pool(-236), superseded=())
    sci_tab = next((tmp_path / "edr").rglob("MAGSCI*.TAB"))
    assert b"ITEMS = 7" in sci_tab.with_suffix(".LBL").read_bytes()
    _assert_same(read_edr(tmp_path / "edr", tmp_path / "m.toml"), _csv_streams(archive["csv"]))


# --- hand-written tables: the packet time rule in closed form -------------------------------


def _write_table(folder, name, columns, start="1/0"):
    """Write ``name``.TAB/.LBL: columns = [(NAME, width, values (n,) or (n, items))]."""
    n = len(columns[0][2])
    fields, objects, pos = [], [], 1
    for i, (cname, width, values) in enumerate(columns, start=1):
        v = np.asarray(values)
        items = v.shape[1] if v.ndim == 2 else 1
        v2 = v.reshape(n, items)
        width = max(width, *(len(str(x)) for x in v2.ravel().tolist()))
        fields.append([" ".join(f"{x:>{width}}" for x in row) for row in v2.tolist()])
        nbytes = items * width + items - 1
        item = (f"    ITEMS = {items}\r\n    ITEM_BYTES = {width}\r\n    ITEM_OFFSET = "
                f"{width + 1}\r\n") if items > 1 else ""
        real = v.dtype.kind == "f"
        objects.append(
            f"  OBJECT = COLUMN\r\n    COLUMN_NUMBER = {i}\r\n    NAME = {cname}\r\n"
            f"    DATA_TYPE = {'ASCII_REAL' if real else 'ASCII_INTEGER'}\r\n"
            f"    START_BYTE = {pos}\r\n    BYTES = {nbytes}\r\n{item}"
            f"  END_OBJECT = COLUMN\r\n")
        pos += nbytes + 1
    rows = [" ".join(parts) for parts in zip(*fields, strict=True)]
    row_bytes = pos  # text (pos - 2 bytes: one blank between fields) + CRLF
    (folder / f"{name}.TAB").write_bytes("".join(r + "\r\n" for r in rows).encode())
    (folder / f"{name}.LBL").write_bytes((
        f"PDS_VERSION_ID = PDS3\r\nRECORD_TYPE = FIXED_LENGTH\r\nRECORD_BYTES = {row_bytes}\r\n"
        f"FILE_RECORDS = {n}\r\n^TABLE = \"{name}.TAB\"\r\n"
        f"SPACECRAFT_CLOCK_START_COUNT = \"{start}\"\r\nOBJECT = TABLE\r\n"
        f"  INTERCHANGE_FORMAT = ASCII\r\n  ROWS = {n}\r\n  COLUMNS = {len(columns)}\r\n"
        f"  ROW_BYTES = {row_bytes}\r\n{''.join(objects)}END_OBJECT = TABLE\r\nEND\r\n"
    ).encode())


def _tiny_archive(folder, packets, header, start="1/0"):
    """Science packets [(MET, delta_ts, n_samples)], header rows [(MET, rate)], and a
    short LAC and status stream around them (file day 12153, version 1)."""
    folder.mkdir(parents=True, exist_ok=True)
    met = np.concatenate([np.full(k, m) for m, _, k in packets])
    dts = np.concatenate([np.full(k, d) for _, d, k in packets])
    n = met.size
    counts = np.column_stack([np.arange(n), -np.arange(n), np.full(n, 7)])
    _write_table(folder, "MAGSCI121530000_V1", [
        ("MET", 10, met), ("DELTA_TS", 3, dts), ("RANGE", 1, np.zeros(n, int)),
        ("MAG_COUNTS", 6, counts)], start)
    _write_table(folder, "MAGSHD121530000_V1", [
        ("MET", 10, np.array([h[0] for h in header])),
        ("RATE", 2, np.array([h[1] for h in header]))], start)
    t = np.arange(min(met) - 50, max(met) + 200)
    _write_table(folder, "MAGLAC121530000_V1", [("MET", 10, t),
                                                ("HEATER_STATE", 4, (t % 100 < 40) * 1)],
                 start)
    ts = np.arange(min(met) - 50, max(met) + 200, 10)
    _write_table(folder, "MAGSTAT121530000_V1", [("MET", 12, ts.astype(float)),
                                                 ("SENSOR_TEMP", 6, np.full(ts.size, 1600))],
                 start)


@pytest.fixture(scope="module")
def tiny_mapping(tmp_path_factory):
    return filled_mapping(template_path(), tmp_path_factory.mktemp("map") / "mapping.toml")


@pytest.mark.parametrize("rate", range(11))
def test_packet_time_rule_closed_form(tmp_path, tiny_mapping, rate):
    # two packets at MET 5000 (delta_ts 3) and 5000 + 4 / rate_hz + 1 (delta_ts 17)
    hz = TABLE1_HZ[rate]
    met2 = 5000 + int(np.ceil(4 / hz)) + 1
    _tiny_archive(tmp_path / "edr", [(5000, 3, 4), (met2, 17, 3)], [(4990, rate)])
    sci, heat, temp = read_edr(tmp_path / "edr", tiny_mapping)
    expected = np.concatenate([5000 + 0.05 * 3 + np.arange(4) / hz,
                               met2 + 0.05 * 17 + np.arange(3) / hz])
    # the reader sums in whole microseconds: exact; 1e-9 s covers the float closed form
    np.testing.assert_allclose(sci["met"].values, expected, rtol=0, atol=1e-9)
    assert (sci["rate"].values == rate).all() and (sci["partition"].values == 1).all()
    np.testing.assert_array_equal(sci["counts"].values[:, 0], np.arange(7))
    # status counts 1600 -> -150 + 1600 / 16 = -50 degC (the declared polynomial)
    np.testing.assert_array_equal(temp["temperature_c"].values, -50.0)
    assert heat["heater"].values.sum() > 0


@settings(max_examples=40, deadline=None)
@given(met_us=st.integers(1_000_000_000, 340_000_000_000_000), dts=st.integers(0, 19),
       rate=st.integers(0, 10), n=st.integers(1, 12))
def test_packet_time_rule_property(tiny_mapping, met_us, dts, rate, n):
    # packet MET with a microsecond fraction (an ASCII_REAL column), up to MET 3.4e8 s
    hz = TABLE1_HZ[rate]
    met = met_us / 1e6
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp) / "edr"
        _tiny_archive(folder, [(met, dts, n)], [(np.floor(met), rate)])
        sci = read_edr(folder, tiny_mapping)[0]
    expected = met + 0.05 * dts + np.arange(n) / hz
    # 2e-7 s: a few float64 steps at MET 3.4e8 s (the closed form rounds, the reader not)
    np.testing.assert_allclose(sci["met"].values, expected, rtol=0, atol=2e-7)


def test_header_state_changes_between_packets(tmp_path, tiny_mapping):
    # rate 9 (10 Hz) from MET 4000, rate 6 (1 Hz) from 5010: the packet at 5010 is 1 Hz
    _tiny_archive(tmp_path / "edr", [(5000, 0, 5), (5010, 0, 3), (5020, 4, 2)],
                  [(4000, 9), (5010, 6)])
    sci = read_edr(tmp_path / "edr", tiny_mapping)[0]
    np.testing.assert_array_equal(sci["rate"].values, [9] * 5 + [6] * 5)
    np.testing.assert_allclose(sci["met"].values[5:],
                               [5010, 5011, 5012, 5020.2, 5021.2], rtol=0, atol=1e-9)


def test_packet_before_any_header_is_an_error(tmp_path, tiny_mapping):
    _tiny_archive(tmp_path / "edr", [(5000, 0, 5), (5010, 0, 3)], [(5005, 9)])
    with pytest.raises(InputFormatError, match=r"MAGSCI121530000_V1\.TAB, line 1.*no "
                       "science-header state"):
        read_edr(tmp_path / "edr", tiny_mapping)


def test_partition_from_label_start_count(tmp_path, tiny_mapping):
    _tiny_archive(tmp_path / "edr", [(5000, 0, 2)], [(5000, 8)], start="2/0000004950")
    sci, heat, temp = read_edr(tmp_path / "edr", tiny_mapping)
    assert {int(v) for ds in (sci, heat, temp) for v in np.unique(ds["partition"])} == {2}


# --- a clock-partition change inside a day (the 2013-01-08 reset) ---------------------------


@pytest.fixture(scope="module")
def reset_day(tmp_path_factory):
    """Two 1-Hz simulations either side of the synthetic clock reset (2013-01-08 20:00)."""
    root = tmp_path_factory.mktemp("msgr_reset")
    mk = write_messenger_like_kernels(root / "k", "2013-01-08T17:00:00", 6 * 3600.0)
    sims = []
    with KernelPool(mk):
        sclk = SclkKernel.from_pool(-236)
        for start, duration in (("2013-01-08T18:00:00", 3000.0),
                                ("2013-01-08T21:00:00", 1800.0)):
            cfg = SimulationConfig(start_utc=start, duration_s=duration,
                                   rate_segments=[(0.0, 6), (0.5, 8)], coarse_intervals=[])
            sims.append(_quantised(simulate(cfg, None, sclk)))
    csv = [write_inputs(s, root / f"csv{i}") for i, s in enumerate(sims)]
    return {"root": root, "kernels": mk, "sims": sims, "csv": csv}


@pytest.mark.parametrize("style", ["label", "column"])
def test_partition_change_inside_a_day(reset_day, tmp_path, style):
    mapping = filled_mapping(template_path(), tmp_path / "mapping.toml")
    if style == "column":  # a partition column in every table instead of the label rule
        text = mapping.read_text().replace('column = ""\nfrom_label', 'column = "PARTITION"\n'
                                           'from_label')
        mapping.write_text(text)
    with KernelPool(reset_day["kernels"]):
        written = write_edr_archive(reset_day["sims"], tmp_path / "edr", mapping,
                                    SclkKernel.from_pool(-236))
    assert {p.name[6:11] for p in written if p.name.startswith("MAGSCI")} == {"13008"}
    edr = read_edr(tmp_path / "edr", mapping)
    csv = [read_science([c["science"] for c in reset_day["csv"]]),
           read_heater([c["heater"] for c in reset_day["csv"]]),
           read_temperature([c["temperature"] for c in reset_day["csv"]])]
    _assert_same(edr, csv)
    assert set(np.unique(edr[0]["partition"].values)) == {1, 2}
    assert edr[0]["met"].values[-1] < edr[0]["met"].values[0]  # MET restarted


# --- mapping errors, malformed tables, the CLI ------------------------------------------------


def test_template_without_conversion_is_refused(tmp_path):
    with pytest.raises(InputFormatError) as exc:
        load_mapping(template_path())
    msg = str(exc.value)
    assert "edr_mapping_template.toml" in msg and "[status.temperature.conversion]" in msg
    assert "\n" not in msg


def test_table_conversion_and_bad_mappings(tmp_path, tiny_mapping):
    text = tiny_mapping.read_text()
    table = text.replace('kind = "polynomial"\ncoefficients = [-150.0, 0.0625]',
                         'kind = "table"\ncounts = [0, 1600, 3200]\ndegc = [-150, -60, 50]')
    (tmp_path / "table.toml").write_text(table)
    _tiny_archive(tmp_path / "edr", [(5000, 0, 2)], [(5000, 8)])
    temp = read_edr(tmp_path / "edr", tmp_path / "table.toml")[2]
    np.testing.assert_array_equal(temp["temperature_c"].values, -60.0)
    bad = text.replace("coefficients = [-150.0, 0.0625]", "coefficients = []")
    (tmp_path / "bad.toml").write_text(bad)
    with pytest.raises(InputFormatError, match=r"\[status\.temperature\.conversion\]"):
        load_mapping(tmp_path / "bad.toml")
    (tmp_path / "nopat.toml").write_text(text.replace("(?P<version>", "(?P<v>", 1))
    with pytest.raises(InputFormatError, match=r"\[science\.file\].*version"):
        load_mapping(tmp_path / "nopat.toml")


def test_missing_column_names_the_mapping_entry_and_label(tmp_path, tiny_mapping):
    text = tiny_mapping.read_text().replace('column = "MAG_COUNTS"', 'column = "MAG_XYZ"')
    (tmp_path / "m.toml").write_text(text)
    _tiny_archive(tmp_path / "edr", [(5000, 0, 2)], [(5000, 8)])
    with pytest.raises(InputFormatError) as exc:
        read_edr(tmp_path / "edr", tmp_path / "m.toml")
    msg = str(exc.value)
    assert "MAGSCI121530000_V1.LBL" in msg and "[science.counts]" in msg
    assert "'MAG_XYZ'" in msg and "\n" not in msg


@pytest.mark.parametrize(("table", "old", "new", "where"), [
    ("MAGSHD121530000_V1.TAB", b"  8\r\n", b" 11\r\n", "MAGSHD121530000_V1.TAB, line 1, "
     "field 'RATE': value 11 outside the rate settings"),
    ("MAGSCI121530000_V1.TAB", b"   0 0      2", b"   0 2      2", "MAGSCI121530000_V1.TAB, "
     "line 3, field 'RANGE': value 2 outside the range flags"),
    ("MAGSCI121530000_V1.TAB", b"     1     -1", b" 40000     -1", "MAGSCI121530000_V1.TAB, "
     "line 2, field 'MAG_COUNTS': value 40000 outside the signed 16-bit"),
])
def test_value_errors_name_file_row_and_column(tmp_path, tiny_mapping, table, old, new, where):
    _tiny_archive(tmp_path / "edr", [(5000, 0, 4)], [(5000, 8)])
    path = tmp_path / "edr" / table
    data = path.read_bytes()
    assert old in data
    path.write_bytes(data.replace(old, new, 1))
    with pytest.raises(InputFormatError) as exc:
        read_edr(tmp_path / "edr", tiny_mapping)
    assert where in str(exc.value)


def _cli(edr, mapping, kernels, out, *extra):
    return main(["messenger", "edr2cdr", "--edr", str(edr), "--mapping", str(mapping),
                 "--kernels", str(kernels), "--out", str(out), "--frames", "mso",
                 "--formats", "tab", "--average", "", *extra])


def test_cli_input_styles(tmp_path, archive, messenger_kernels, capsys):
    csv = archive["csv"]
    both = _cli(archive["edr"], archive["mapping"], messenger_kernels, tmp_path / "o",
                "--sci", str(csv["science"]))
    no_mapping = main(["messenger", "edr2cdr", "--edr", str(archive["edr"]), "--kernels",
                       str(messenger_kernels), "--out", str(tmp_path / "o")])
    neither = main(["messenger", "edr2cdr", "--kernels", str(messenger_kernels), "--out",
                    str(tmp_path / "o")])
    template = _cli(archive["edr"], template_path(), messenger_kernels, tmp_path / "o")
    assert (both, no_mapping, neither, template) == (2, 2, 2, 2)
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 4 and all(e.startswith("fluxcal: error:") for e in err)
    assert not (tmp_path / "o").exists() or not any((tmp_path / "o").iterdir())


@pytest.mark.parametrize("damage", ["truncated", "non_numeric", "missing_column"])
def test_cli_malformed_tables_exit_2(tmp_path, tiny_mapping, messenger_kernels, capsys,
                                     damage):
    edr = tmp_path / "edr"
    _tiny_archive(edr, [(5000, 0, 4)], [(5000, 8)])
    tab = edr / "MAGSCI121530000_V1.TAB"
    data = tab.read_bytes()
    if damage == "truncated":
        tab.write_bytes(data[: len(data) - 9])
    elif damage == "non_numeric":
        tab.write_bytes(data.replace(b"  5000   0", b"  50x0   0", 1))
    else:
        lbl = edr / "MAGSCI121530000_V1.LBL"
        lbl.write_bytes(lbl.read_bytes().replace(b"NAME = RANGE", b"NAME = RNG"))
    assert _cli(edr, tiny_mapping, messenger_kernels, tmp_path / "o") == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("fluxcal: error:") and "MAGSCI121530000_V1" in err
    assert "\n" not in err


def test_simulate_layout_edr_then_edr2cdr_and_batch(tmp_path):
    # 23:30 - 00:30: two EDR days (12153, 12154), each in versions 1 (wrong) and 2
    sim = tmp_path / "sim"
    assert main(["simulate", "messenger", "--layout", "edr", "--out", str(sim),
                 "--start", "2012-06-01T23:30:00", "--duration", "3600"]) == 0
    edr, kernels = sim / "edr", sim / "kernels" / "messenger_synthetic.tm"
    assert sorted(p.name for p in edr.iterdir() if p.is_dir()) == ["LAC", "SCI", "SHD", "STAT"]
    names = {p.name for p in edr.rglob("MAGSCI*.LBL")}
    assert names == {"MAGSCI121532330_V1.LBL", "MAGSCI121532330_V2.LBL",
                     "MAGSCI121540000_V1.LBL", "MAGSCI121540000_V2.LBL"}
    assert _cli(edr, edr / "edr_mapping.toml", kernels, tmp_path / "one") == 0
    # the batch recognises the EDR folder by its edr_mapping.toml; day 3 has no data
    assert main(["batch", "messenger", "--input", str(edr), "--kernels", str(kernels),
                 "--start", "2012-06-01", "--end", "2012-06-03", "--out",
                 str(tmp_path / "batch"), "--scheduler", "serial", "--formats", "tab",
                 "--quiet"]) == 0
    for day in ("12153", "12154"):
        name = f"MAGMSOSCI{day}_V01.TAB"
        one = read_fluxcal_product(tmp_path / "one" / name)
        batch = read_fluxcal_product(tmp_path / "batch" / name)
        np.testing.assert_array_equal(one["met"].values, batch["met"].values)
        # a batch day sees the LAC of its day and the day before only, as for the CSV
        # batch; the field agrees to the products' print resolution (0.001 nT)
        np.testing.assert_allclose(np.asarray(batch["b"].values, float),
                                   np.asarray(one["b"].values, float), rtol=0, atol=1e-3)
