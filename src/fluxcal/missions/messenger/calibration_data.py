"""Versioned MESSENGER MAG calibration files and the loader that picks them for a day.

Every file in ``missions/messenger/data`` is named ``<name>_v<version>.<csv|toml>`` and
carries a header citing its seed section/table, its version and its validity interval
``[valid_from, valid_to)``; headers, versions, validity and a user folder over these
defaults are `fluxcal.calibration.store`'s (this module parses the bodies).
`load_calibration` returns, for one day, the highest version
of every table whose interval covers that day; a day outside every interval of a table
raises `fluxcal.errors.CalibrationRangeError`.

References
----------
.. [1] MESSENGER MAG EDR-to-CDR Processing v2i (Korth and Anderson, 2016), sec. 5
   Table 1, sec. 7 Tables 2-3, sec. 8 Table 4, sec. 12 Table 5, Appendix Tables 6-8.
"""

from __future__ import annotations

import re
import tomllib
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

import numpy as np

from fluxcal.calibration.gain_matrix import lower_triangular_matrix
from fluxcal.calibration.stated_ranges import StatedRanges
from fluxcal.calibration.store import (
    CalibrationStore,
    TableHeader,
    _key,
    read_header,
    user_folder,
)
from fluxcal.errors import CalibrationError
from fluxcal.textfile import read_text

TABLE_NAMES = (
    "latency",
    "offsets_temperature",
    "offsets_duty_cycle",
    "gain_matrix",
    "heater_signal_x",
    "heater_signal_y",
    "heater_signal_z",
    "processing",
)
#: Header fields every MESSENGER table carries (docs/formats/calibration.md).
REQUIRED_FIELDS = ("version", "valid_from", "valid_to")
_NAME_RE = re.compile(r"^(?P<name>[a-z_]+)_v(?P<version>\d+)\.(?P<ext>csv|toml)$")
#: Sec. 7: a 5000-s look-back for tau = 872 s; the offset before it, assumed zero, errs
#: by at most 200 exp(-5000 / 872) = 0.65 DN (docs/decisions/messenger_fit.md entry 10).
SEED_LOOK_BACK_S, SEED_TAU_S = 5000.0, 872.0


#: The regulated temperature of sec. 7 (``C0 = cT(-50 C)``), where a processing file
#: leaves ``reference_temperature_c`` out.
SEED_REFERENCE_TEMPERATURE_C = -50.0


def required_look_back_s(tau_s: float) -> float:
    """Return the shortest look-back (s) that keeps sec. 7's truncation for ``tau_s``.

    ``max(5000, 5000 / 872 x tau)``: 200 exp(-look_back / tau) stays at the seed's
    0.65 DN for a longer tau; a shorter tau keeps the seed's 5000 s.

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 7 (the 5000-s look-back).
    """
    return float(max(SEED_LOOK_BACK_S, SEED_LOOK_BACK_S / SEED_TAU_S * float(tau_s)))


def check_look_back(path: Path, relaxation: dict) -> None:
    """Refuse a ``processing`` table whose tau needs a longer look-back than it has.

    A look-back shorter than `required_look_back_s` truncates the relaxing offset by
    more than sec. 7 accepts (issue 34: 0.03 nT rms, up to 0.12 nT, for tau = 1150 s with
    5000 s); it is refused, naming the value to set, never applied silently.

    Raises
    ------
    CalibrationError
        Naming the file, the field, the truncation and the least look-back.
    """
    tau = float(relaxation["tau_s"])
    look_back = float(relaxation["look_back_s"])
    need = required_look_back_s(tau)
    if look_back < need - 0.1:  # written to 0.1 s
        dn = 200.0 * np.exp(-look_back / tau)
        raise CalibrationError(
            f"{path}: [relaxation] look_back_s = {look_back:g} s is too short for tau_s = "
            f"{tau:g} s: the offset before the look-back, assumed zero, errs by up to "
            f"200 exp(-look_back_s / tau_s) = {dn:.2g} DN, above sec. 7's 0.65 DN; set "
            f"look_back_s to at least {np.ceil(need * 10) / 10:.1f} (5000 s x tau_s / 872 s)")


def data_dir() -> Path:
    """Return the folder holding the packaged MESSENGER calibration files."""
    return Path(str(resources.files("fluxcal.missions.messenger") / "data"))


@dataclass(frozen=True)
class TableFile:
    """One versioned calibration file: its header and its parsed body."""

    name: str
    version: int
    valid_from: np.datetime64
    valid_to: np.datetime64
    path: Path
    header: dict[str, str]
    columns: dict[str, np.ndarray] = field(repr=False)
    toml: dict = field(repr=False, default_factory=dict)


#: The columns of the CSV tables that hold words (Tables 2, 3: ``axis``; Table 4:
#: ``range_name``); every other column is numbers (docs/formats/calibration.md).
_TEXT_COLUMNS = frozenset({"axis", "range_name"})


def _parse_csv(path: Path) -> dict[str, np.ndarray]:
    """Return the columns of a CSV table (its ``#`` header lines are the store's).

    Raises
    ------
    CalibrationError
        A row with another number of fields than the column line, a value that is not
        a finite number in a numeric column (every column but `_TEXT_COLUMNS`), naming
        the file, line and column.
    """
    rows: list[list[str]] = []
    lines: list[int] = []
    names: list[str] | None = None
    text = read_text(path, "a CSV calibration table", CalibrationError)
    for lineno, line in enumerate(text.splitlines(), start=1):
        if not line.strip() or line.startswith("#"):
            continue
        fields = line.split(",")
        if names is None:
            names = fields
            continue
        if len(fields) != len(names):
            raise CalibrationError(
                f"{path}: line {lineno}: expected {len(names)} fields, got {len(fields)}"
            )
        rows.append(fields)
        lines.append(lineno)
    if names is None or not rows:
        raise CalibrationError(f"{path}: no column header or no data rows")
    columns: dict[str, np.ndarray] = {}
    for j, name in enumerate(names):
        values = [r[j] for r in rows]
        if name.strip() in _TEXT_COLUMNS:
            columns[name] = np.array(values)
            continue
        numbers = []
        for lineno, v in zip(lines, values, strict=True):
            try:
                x = float(v)
            except ValueError:
                x = float("nan")
            if not np.isfinite(x):
                raise CalibrationError(f"{path}: line {lineno}, column {name!r}: {v!r} is "
                                       "not a finite number; correct the table")
            numbers.append(x)
        columns[name] = np.array(numbers)
    return columns


def _read_table(path: Path, header: TableHeader | None = None) -> TableFile:
    """Read one table: its header through the calibration store, its body here."""
    match = _NAME_RE.match(path.name)
    if match is None:
        raise CalibrationError(f"{path}: file name must be <name>_v<version>.csv|toml")
    header = header or read_header(path, match["name"], require=REQUIRED_FIELDS)
    doc: dict = {}
    columns: dict[str, np.ndarray] = {}
    if match["ext"] == "toml":
        try:
            doc = tomllib.loads(read_text(path, "a TOML calibration file", CalibrationError))
        except tomllib.TOMLDecodeError as exc:
            raise CalibrationError(f"{path}: not valid TOML: {exc}") from None
    else:
        columns = _parse_csv(path)
    return TableFile(
        name=match["name"],
        version=int(header.version),
        valid_from=header.valid_from,
        valid_to=header.valid_to,
        path=path,
        header=dict(header.fields),
        columns=columns,
        toml=doc,
    )


def calibration_store(folder: Path | None = None) -> CalibrationStore:
    """Return the store of MESSENGER tables: ``folder`` over the packaged tables.

    ``folder`` None: ``$FLUXCAL_CALIBRATION_DIR`` when set (`user_folder`).  A table
    present in the user folder (any version) hides the packaged files of that table
    (`fluxcal.calibration.store`).
    """
    return CalibrationStore(data_dir(), user_folder(folder), names=TABLE_NAMES,
                            require=REQUIRED_FIELDS)


def read_tables(folder: Path) -> list[TableFile]:
    """Read every calibration table file (``<name>_v<version>.csv|toml``) of ``folder``.

    For checking a user's ``--calib`` folder up front, before any data are read.

    Raises
    ------
    CalibrationError
        Naming the file (and line) of the first table that cannot be read: not text,
        not valid TOML or CSV, a header without version or validity.
    """
    return [_read_table(p) for p in sorted(Path(folder).iterdir())
            if (m := _NAME_RE.match(p.name)) and m["name"] in TABLE_NAMES]


def resolve_table(name: str, day: np.datetime64 | str, folder: Path | None = None) -> TableFile:
    """Return the highest version of table ``name`` whose validity covers ``day``.

    Parameters
    ----------
    name : str
        Table name (file stem without ``_v<version>``), one of `TABLE_NAMES`.
    day : numpy.datetime64 or str
        Any instant of the day being processed (UTC).
    folder : Path, optional
        User folder of calibration files over the packaged ``data`` folder (default:
        ``$FLUXCAL_CALIBRATION_DIR`` if set, else the packaged tables only); a table it
        holds hides the packaged files of that table.

    Raises
    ------
    CalibrationRangeError
        When no version of the table is valid at ``day``.
    CalibrationError
        When no file of that name exists, a header is malformed, or two files of the
        table share the winning version.
    """
    header = calibration_store(folder).resolve(name, day)
    return _read_table(header.path, header)


@dataclass(frozen=True)
class MessengerCalibration:
    """All MESSENGER MAG calibration constants valid for one day (fine-range counts).

    Attributes
    ----------
    net_lag_s : ndarray, shape (11,)
        Net time lag per rate setting 0-10 (Table 1).
    sample_rate_hz : ndarray, shape (11,)
        Sample rate per rate setting (Table 1).
    temperature_coefficients : ndarray, shape (3, 4)
        ``A0, B0, A1, B1`` per axis x, y, z (Table 2).
    breakpoint_temperature_c : ndarray, shape (3,)
        ``T_m`` per axis as printed in Table 2.
    duty_cycle_c0, duty_cycle_d0 : ndarray, shape (3,)
        ``C0`` (counts) and ``D0`` (counts per part per 1000) per axis (Table 3).
    matrices : ndarray, shape (2, 3, 3)
        Counts-to-nT matrices of eq. 8 for range flag 0 (fine) and 1 (coarse) (Table 4).
    heater_signal : ndarray, shape (3, 101, 8)
        Heater signal (counts) per axis, heater-cycle second 0..100, duty-cycle bin.
    heater_duty_bins_percent : ndarray, shape (8,)
        Bin centres 12..40 % (Tables 6-8).
    constants : dict
        The ``processing`` TOML (relaxation, heater, pre-V10, quality dates).
    files : list of (str, int)
        File names and versions used, for product provenance.
    paths : tuple of Path
        The files themselves (checksummed in product provenance).
    temperature_range : StatedRanges or None
        ``T_RANGE`` of the Table 2 file's header (C): the temperatures over which a
        fitted law is determined (`fluxcal.missions.messenger.fit_write`), one or more
        intervals (``lo hi`` pairs separated by commas; a table of one interval, the
        older form, reads the same); calibrating samples outside it warns
        (`chain.warn_outside_temperature_range`).  None: the table states no range
        (the seed's Table 2).
    duty_range : tuple of float or None
        ``D_RANGE`` of the heater-signal files' headers (percent, ``lo <= d < hi``):
        the duty cycles over which fitted waveforms are determined
        (`fit_waveforms.supported_duty_range`); calibrating a heater-on sample outside it warns
        (`chain.warn_outside_duty_range`).  Several files: the narrowest (their
        intersection).  None: no file states one (the seed's Tables 6-8), nothing warns.
    waveform_error : ndarray, shape (3, n_bins) or None
        ``WAVEFORM_ERROR`` of the heater-signal files' headers: each column's stated
        error (counts, 1 sigma, rms over the phase) per axis.  None unless all three
        files state it (the seed's tables, fits before it was written).
    waveform_part_nt : ndarray, shape (3,) or None
        ``WAVEFORM_PART_NT``: the waveform part (nT, sensor x y z) of the fit's stated
        prediction; a calibrated day whose own duty cycles give more warns
        (`chain.warn_waveform_part`).  Several files: the least per axis.
    """

    net_lag_s: np.ndarray
    sample_rate_hz: np.ndarray
    temperature_coefficients: np.ndarray
    breakpoint_temperature_c: np.ndarray
    duty_cycle_c0: np.ndarray
    duty_cycle_d0: np.ndarray
    matrices: np.ndarray
    prelaunch_offsets: np.ndarray
    heater_signal: np.ndarray
    heater_duty_bins_percent: np.ndarray
    constants: dict
    files: list[tuple[str, int]]
    paths: tuple[Path, ...] = ()
    temperature_range: StatedRanges | None = None
    duty_range: tuple[float, float] | None = None
    waveform_error: np.ndarray | None = None
    waveform_part_nt: np.ndarray | None = None

    def __repr__(self) -> str:
        """Two lines: the tables by version and folder, then validity and key constants."""
        by_version: dict[int, list[str]] = {}
        for name, version in self.files:
            stem = Path(name).stem.removesuffix(f"_v{version}")
            by_version.setdefault(version, []).append(stem)
        files = "; ".join(f"v{v}: {', '.join(n)}" for v, n in sorted(by_version.items()))
        folders = sorted({p.parent for p in self.paths})
        # a folder by its name only: the full paths are in ``paths``
        where = ("packaged" if folders == [data_dir()] else
                 ", ".join(f"{f.name}/" for f in folders) or "no files")
        relax = self.constants.get("relaxation", {})
        valid = [str(self.constants.get(k, "?"))[:10] for k in ("valid_from", "valid_to")]
        return (f"MessengerCalibration({files} [{where}]\n"
                f"  processing valid {valid[0]} .. {valid[1]}; tau {relax.get('tau_s')} s, "
                f"heater delay {relax.get('delay_s')} s; Table 4 offsets "
                f"{self.constants.get('offsets', {}).get('prelaunch_offsets')})")

    @property
    def reference_temperature_c(self) -> float:
        """The regulated sensor temperature (C) that anchors the duty-cycle law.

        ``C0 = cT(-50 C)``: the heater runs only while the sensor is regulated at
        -50 C (sec. 7, eq. 2); the ``processing`` TOML's
        ``[relaxation] reference_temperature_c``, the seed's value where a file
        leaves it out.

        References
        ----------
        MESSENGER MAG EDR-to-CDR Processing v2i, sec. 7.
        """
        rel = self.constants.get("relaxation", {})
        return float(rel.get("reference_temperature_c", SEED_REFERENCE_TEMPERATURE_C))

    @property
    def prelaunch_offsets_reading(self) -> str:
        """How Table 4's pre-launch offsets enter the offset model (``[offsets]`` table).

        ``"not_applied"`` (default reading: Table 2 + Table 3 are the whole offset, eq. 1)
        or ``"added_to_table2"`` (Table 2 is a residual after Table 4's offsets); see
        docs/decisions/messenger.md.
        """
        return str(self.constants["offsets"]["prelaunch_offsets"])

    def offset_coefficients(self) -> np.ndarray:
        """Return ``A0, B0, A1, B1`` per axis of the total temperature offset (counts).

        Table 2, with Table 4's fine-range pre-launch offsets added to ``A0`` and ``A1``
        under the ``"added_to_table2"`` reading (a constant shift: ``T_m`` of eq. 4 is
        unchanged; coarse-range samples get it through ``M_coarse^-1 M_fine``, which
        reproduces Table 4's coarse offsets to 0.01 count).

        References
        ----------
        .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 7 Table 2, sec. 8 Table 4.
        """
        out = np.array(self.temperature_coefficients, dtype=float)
        if self.prelaunch_offsets_reading == "added_to_table2":
            out[:, 0] += self.prelaunch_offsets[0]
            out[:, 2] += self.prelaunch_offsets[0]
        return out

    def date(self, key: str) -> np.datetime64:
        """Return the quality-table date ``key`` (e.g. ``"boom_deployment"``)."""
        return np.datetime64(self.constants["quality"][key], "s")

    def provenance(self) -> str:
        """Return ``"name vN; ..."`` for product labels."""
        return "; ".join(f"{n} v{v}" for n, v in self.files)


def load_calibration(day: np.datetime64 | str, folder: Path | None = None) -> MessengerCalibration:
    """Load every MESSENGER MAG calibration table valid for ``day``.

    Parameters
    ----------
    day : numpy.datetime64 or str
        An instant of the processed day (UTC).
    folder : Path, optional
        User folder of calibration files over the packaged ones (`resolve_table`).

    Returns
    -------
    MessengerCalibration

    Raises
    ------
    CalibrationRangeError
        When ``day`` lies outside every validity interval of some table.

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 5 Table 1, sec. 7 Tables 2-3,
       sec. 8 Table 4, sec. 12 Table 5, Appendix Tables 6-8.
    """
    t = {name: resolve_table(name, day, folder) for name in TABLE_NAMES}
    lat = t["latency"].columns
    order = np.argsort(lat["rate_setting"])
    if not np.array_equal(lat["rate_setting"][order], np.arange(11)):
        raise CalibrationError(f"{t['latency'].path}: rate settings must be 0..10")
    temp = t["offsets_temperature"].columns
    duty = t["offsets_duty_cycle"].columns
    for table, cols in (("offsets_temperature", temp), ("offsets_duty_cycle", duty)):
        if list(cols["axis"]) != ["x", "y", "z"]:
            raise CalibrationError(f"{t[table].path}: axes must be x, y, z in order")
    gain = t["gain_matrix"].columns
    matrices = np.empty((2, 3, 3))
    prelaunch = np.empty((2, 3))
    for row, flag in enumerate(gain["range_flag"].astype(int)):
        matrices[flag] = lower_triangular_matrix(
            gain["kx"][row], gain["ky"][row], gain["kz"][row],
            gain["alpha"][row], gain["beta"][row], gain["gamma"][row],
        )
        prelaunch[flag] = [gain[f"offset_{a}"][row] for a in "xyz"]
    readings = ("not_applied", "added_to_table2")
    proc = t["processing"]
    if proc.toml.get("offsets", {}).get("prelaunch_offsets") not in readings:
        raise CalibrationError(
            f"{proc.path}: [offsets] prelaunch_offsets must be one of {readings} "
            "(how Table 4's pre-launch offsets enter the offset model)"
        )
    check_look_back(proc.path, proc.toml["relaxation"])
    heater = []
    bins = None
    for axis in "xyz":
        cols = t[f"heater_signal_{axis}"].columns
        if not np.array_equal(cols["t_s"], np.arange(101)):
            raise CalibrationError(f"{t[f'heater_signal_{axis}'].path}: t_s must be 0..100")
        names = [c for c in cols if c != "t_s"]
        bins = np.array([float(c) for c in names])
        heater.append(np.column_stack([cols[c] for c in names]))
    return MessengerCalibration(
        net_lag_s=lat["net_lag_s"][order],
        sample_rate_hz=lat["sample_rate_hz"][order],
        temperature_coefficients=np.column_stack([temp["A0"], temp["B0"], temp["A1"], temp["B1"]]),
        breakpoint_temperature_c=temp["Tm_c"],
        duty_cycle_c0=duty["C0"],
        duty_cycle_d0=duty["D0"],
        matrices=matrices,
        prelaunch_offsets=prelaunch,
        heater_signal=np.stack(heater),
        heater_duty_bins_percent=bins,
        constants=t["processing"].toml,
        files=[(tf.path.name, tf.version) for tf in t.values()],
        paths=tuple(tf.path for tf in t.values()),
        temperature_range=_stated_range(t["offsets_temperature"], "T_RANGE", "C"),
        duty_range=_duty_range([t[f"heater_signal_{axis}"] for axis in "xyz"]),
        **_waveform_errors([t[f"heater_signal_{axis}"] for axis in "xyz"], bins.size),
    )


def _stated_range(table: TableFile, key: str, unit: str) -> StatedRanges | None:
    """``KEY: lo hi[, lo hi ...]`` of a table's header (``T_RANGE``, ``D_RANGE``), or None.

    Raises
    ------
    CalibrationError
        A range that is not pairs of finite numbers, low before high, the pairs in
        increasing order and not overlapping (`StatedRanges.parse`).
    """
    text = next((v for k, v in table.header.items() if _key(k) == key.lower()), None)
    if text is None:
        return None
    try:
        return StatedRanges.parse(text)
    except ValueError as exc:
        raise CalibrationError(f"{table.path}: header field {key!r} must be two numbers "
                               f"LOW HIGH ({unit}, low below high), or several such pairs "
                               f"separated by commas in increasing order, got {text!r}: "
                               f"{exc}") from None


def _duty_range(tables: list[TableFile]) -> tuple[float, float] | None:
    """Return the narrowest ``D_RANGE`` (percent) the heater-signal files state, or None.

    Raises
    ------
    CalibrationError
        A malformed ``D_RANGE``, one of several intervals, or files whose ranges do not
        overlap.
    """
    stated = []
    for tf in tables:
        ranges = _stated_range(tf, "D_RANGE", "%")
        if ranges is None:
            continue
        if len(ranges.intervals) != 1:
            raise CalibrationError(f"{tf.path}: header field 'D_RANGE' must be one interval "
                                   f"LOW HIGH (%), got {ranges.header_text()!r}")
        stated.append((tf, ranges.span))
    if not stated:
        return None
    lo = max(r[0] for _, r in stated)
    hi = min(r[1] for _, r in stated)
    if not lo < hi:
        raise CalibrationError(
            f"{stated[-1][0].path}: header field 'D_RANGE' does not overlap the D_RANGE of "
            f"{', '.join(tf.path.name for tf, _ in stated[:-1])}; give heater-signal files "
            "of one fit")
    return lo, hi


#: Header field of each heater-signal file: its columns' stated errors (counts), one per
#: column in the table's order (issue 34, docs/decisions/messenger_fit.md entry 32).
WAVEFORM_ERROR_KEY = "WAVEFORM_ERROR"
#: Header field of the heater-signal files: the waveform part (nT, x y z) of the fit's
#: stated prediction of a recalibrated day.
WAVEFORM_PART_KEY = "WAVEFORM_PART_NT"


def _header_numbers(table: TableFile, key: str, size: int, what: str) -> np.ndarray | None:
    """``KEY: v1 ... vn`` of a table's header as ``size`` finite non-negative numbers, or None.

    Raises
    ------
    CalibrationError
        Not ``size`` numbers, or one not finite or negative.
    """
    text = next((v for k, v in table.header.items() if _key(k) == key.lower()), None)
    if text is None:
        return None
    try:
        values = np.array([float(v) for v in text.split()])
    except ValueError:
        values = np.array([])
    if values.size != size or not np.all(np.isfinite(values)) or np.any(values < 0):
        raise CalibrationError(f"{table.path}: header field {key!r} must be {size} finite "
                               f"non-negative numbers ({what}), got {text!r}")
    return values


def _waveform_errors(tables: list[TableFile], n_bins: int) -> dict[str, np.ndarray | None]:
    """Return ``waveform_error`` (3, n_bins) and ``waveform_part_nt`` (3,) of the heater files.

    ``waveform_error`` only when all three files state it; ``waveform_part_nt`` the least
    per axis over the files stating it.
    """
    errors = [_header_numbers(tf, WAVEFORM_ERROR_KEY, n_bins,
                              "counts, one per column") for tf in tables]
    parts = [p for p in (_header_numbers(tf, WAVEFORM_PART_KEY, 3, "nT, x y z")
                         for tf in tables) if p is not None]
    return {"waveform_error": (np.stack(errors) if all(e is not None for e in errors)
                               else None),
            "waveform_part_nt": np.min(parts, axis=0) if parts else None}

