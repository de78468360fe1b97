"""Rosetta RPC-MAG calibration files: parsers and the constants they hold.

Files (all plain text, ``KEY = v1 v2 ...`` per line, ``#`` starts a comment):

- ground calibration ``RPCMAG_001_CALIB_FSDPU_FM<IB|OB>.TXT`` (seed 003, sec. 3.3),
- daily extended-temperature files ``RPCMAG_<yymmdd>_006_CALIB_<IB|OB>.TXT`` (sec. 4.2.3.3),
- the alignment file ``RPCMAG_SC_ALIGN.TXT`` (sec. 4.3.1),

plus two CSV tables shipped with fluxcal: the filter-mode time shifts
(``RPCMAG_FILTER_TIMESHIFT.csv``, sec. 4.2.3.5) and the post-hibernation offset jumps
(``RPCMAG_OFFSET_JUMPS.csv``, Appendix B).  A user directory given with ``--calib DIR``
overrides any of them file by file; fluxcal's defaults live in ``missions/rosetta/data``.
In that folder a file may also carry the archive's name (``RPCMAG_GND_CALIB_FSDPU_FM<S>``
for the ground calibration) and the extension ``.ASC`` (`names_of`, `resolve`): the
generic `fluxcal.calibration.store` resolves them (registered as aliases), this module
parses the files.

References
----------
.. [1] I. Richter, "Step by Step Calibration Procedure for RPC-MAG Data",
   RO-IGEP-TR0028 issue 3 rev. 1 (2015) (seed 003), sec. 3.3, 4.2.3.3, 4.2.3.5, 4.3.1,
   Appendix B.
"""

from __future__ import annotations

import csv
import datetime as dt
import re
import tomllib
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

import numpy as np

from fluxcal.calibration.store import CalibrationStore, user_folder
from fluxcal.errors import CalibrationError, CalibrationRangeError
from fluxcal.products.atomic import atomic_write_bytes
from fluxcal.textfile import read_text

SENSORS = ("OB", "IB")

GROUND_FILE = {"OB": "RPCMAG_001_CALIB_FSDPU_FMOB.TXT", "IB": "RPCMAG_001_CALIB_FSDPU_FMIB.TXT"}
ALIGN_FILE = "RPCMAG_SC_ALIGN.TXT"
TIMESHIFT_FILE = "RPCMAG_FILTER_TIMESHIFT.csv"
JUMPS_FILE = "RPCMAG_OFFSET_JUMPS.csv"
NOMINAL_FILE = "nominal_conversion.toml"
_DAILY_RE = re.compile(r"^RPCMAG_(\d{6})_006_CALIB_(IB|OB)\.(TXT|ASC)$", re.IGNORECASE)
#: The archive's names of the files fluxcal names as the seed does (issue 14): the ground
#: calibration is ``RPCMAG_GND_CALIB_FSDPU_FM<S>`` in the archive's CALIB folder; the
#: archive's extension is ``.TXT`` (early deliveries) or ``.ASC`` (later ones), each with a
#: detached ``.LBL`` that fluxcal does not need (docs/decisions/rosetta_archive.md).
ARCHIVE_NAMES = {
    GROUND_FILE["OB"]: "RPCMAG_GND_CALIB_FSDPU_FMOB.TXT",
    GROUND_FILE["IB"]: "RPCMAG_GND_CALIB_FSDPU_FMIB.TXT",
}


@dataclass(frozen=True)
class ArchiveFileKind:
    """One kind of calibration file the RPC-MAG archive's ``CALIB`` folder holds.

    Attributes
    ----------
    kind : str
        Short name of the kind.
    pattern : re.Pattern
        Its file names (any case, ``.TXT`` or ``.ASC``).
    read : bool
        Whether fluxcal reads it (``False``: recognised and refused, see ``reason``).
    reason : str
        What the file holds (from the archive's ``CALINFO.TXT``), and for a refused kind
        why fluxcal does not read it and what to do instead.
    """

    kind: str
    pattern: re.Pattern
    read: bool
    reason: str


_EXT = r"\.(?:TXT|ASC)$"
#: Every calibration-file name of the RPC-MAG archive (the ``CALINFO.TXT`` of the data
#: sets from the Earth flybys to the final V9.0 delivery, and the ESC4 corrigenda), with
#: what fluxcal does with it (docs/formats/rosetta.md, "Archive calibration files";
#: docs/decisions/rosetta_archive.md, decision 10).  The archive's texts describe what
#: each file is for, not the layout of the refused kinds, so these are refused by name
#: rather than read by a guessed layout.
ARCHIVE_KINDS: tuple[ArchiveFileKind, ...] = (
    ArchiveFileKind(
        "ground calibration",
        re.compile(r"^RPCMAG_(?:GND|001)_CALIB_FSDPU_FM(?:IB|OB)" + _EXT, re.I),
        True,
        "temperature-dependent offset, sensitivity and misalignment (RO-IGEP-TR0028 sec. 3.3)",
    ),
    ArchiveFileKind(
        "daily temperature model 006", _DAILY_RE, True,
        "daily extended temperature model P_0..P_5 (RO-IGEP-TR0028 sec. 4.2.3.3)",
    ),
    ArchiveFileKind(
        "alignment", re.compile(r"^RPCMAG_SC_ALIGN" + _EXT, re.I), True,
        "R_UVW2SC, stowed and deployed boom (RO-IGEP-TR0028 sec. 4.3.1)",
    ),
    ArchiveFileKind(
        "boom alignment correction", re.compile(r"^RPCMAG_BOOM_ALIGN_CORR_EF1" + _EXT, re.I),
        False,
        "sensor-orientation correction from the first Earth flyby against the POMME model "
        "(a few hundredths of a degree: up to ~0.1 nT per 100 nT of field, CALINFO.TXT); its "
        "layout is not publicly documented: multiply the correction into the matrices of "
        "RPCMAG_SC_ALIGN.TXT and remove this file from the folder",
    ),
    ArchiveFileKind(
        "temperature model 008",
        re.compile(
            r"^RPCMAG_(?:\d{4}_\d{2}_)?(?:[A-Z0-9]+_)?008_CALIB_(?:IB|OB)" + _EXT
            + r"|^RPCMAG_INFLIGHT_08_CALIB_\w*" + _EXT,
            re.I,
        ),
        False,
        "in-flight temperature model 008 per mission phase (comet-phase archives; "
        "RPCMAG_INFLIGHT_08_CALIB_* in the corrigenda); its layout is not publicly "
        "documented and fluxcal implements the daily model 006 of RO-IGEP-TR0028 sec. 4.2.3.3: "
        "convert it to daily RPCMAG_<yymmdd>_006_CALIB_<IB|OB>.TXT files (keys P_0..P_5) "
        "and remove it from the folder",
    ),
    ArchiveFileKind(
        "temperature model 009 parameters",
        re.compile(r"^INFCAL_PARA_(?:IB|OB)_\d{8}_\d{3}" + _EXT, re.I),
        False,
        "in-flight model 009 parameters (final V9.0 archive); its layout is not publicly "
        "documented and fluxcal implements the daily model 006 of RO-IGEP-TR0028 sec. 4.2.3.3: "
        "convert it to daily RPCMAG_<yymmdd>_006_CALIB_<IB|OB>.TXT files (keys P_0..P_5) "
        "and remove it from the folder",
    ),
    ArchiveFileKind(
        "temperature model 009 offsets",
        re.compile(r"^INFCAL_OFF__(?:IB|OB)_\d{8}_\d{3}" + _EXT, re.I),
        False,
        "in-flight model 009 offsets (final V9.0 archive); its layout is not publicly "
        "documented: convert it to daily RPCMAG_<yymmdd>_006_CALIB_<IB|OB>.TXT files "
        "(keys P_0..P_5) or RPCMAG_OFFSET_JUMPS.csv rows, and remove it from the folder",
    ),
    ArchiveFileKind(
        "temperature model 002",
        re.compile(r"^RPCMAG_002_CALIB_(?:IB|OB)" + _EXT, re.I),
        False,
        "in-flight temperature model 002 (Earth-flyby archives); its layout is not publicly "
        "documented: convert it to daily RPCMAG_<yymmdd>_006_CALIB_<IB|OB>.TXT files "
        "(keys P_0..P_5) and remove it from the folder",
    ),
)


def archive_kind(name: str) -> ArchiveFileKind | None:
    """Return the `ArchiveFileKind` whose names include ``name``, or ``None``."""
    for kind in ARCHIVE_KINDS:
        if kind.pattern.match(Path(name).name):
            return kind
    return None


def refuse_unread_archive_files(calib_dir: Path | None) -> None:
    """Raise `CalibrationError` for the first archive calibration file fluxcal cannot read.

    A ``--calib`` folder holding one of the archive's calibration files whose layout no
    public description confirms (`ARCHIVE_KINDS` with ``read=False``) is refused in one
    line naming the file, what it holds and what to do, rather than read by a guessed
    layout or silently ignored (a calibration left out changes the field).  Detached
    ``.LBL`` labels are not looked at.

    References
    ----------
    .. [1] The RPC-MAG data sets' ``CALIB/CALINFO.TXT`` (e.g. RO-C-RPCMAG-4-EXT2-RESAMPLED-V9.0,
       RO-C-RPCMAG-3-ESC4-CALIBRATED-V6.0, RO-A-RPCMAG-3-AST1-CALIBRATED-V3.0) and the ESC4
       ``CORRIGENDA/CORRINFO.TXT``.
    """
    if calib_dir is None or not Path(calib_dir).is_dir():
        return
    for path in sorted(Path(calib_dir).iterdir()):
        kind = archive_kind(path.name)
        if kind is not None and not kind.read and path.is_file():
            raise CalibrationError(f"{path}: not read: {kind.kind} file, {kind.reason}")


def names_of(name: str) -> list[str]:
    """Every accepted name of calibration file ``name``: fluxcal's, the archive's, ``.ASC``."""
    out = [name, ARCHIVE_NAMES.get(name, name)]
    out += [n[:-4] + ".ASC" for n in out if n.upper().endswith(".TXT")]
    out += [n.lower() for n in out]  # mirrors that lower-case the archive's names
    return list(dict.fromkeys(out))


def default_dir() -> Path:
    """Return the folder of the calibration files shipped with fluxcal."""
    return Path(str(resources.files("fluxcal.missions.rosetta") / "data"))


def check_sensor(sensor: str) -> str:
    """Return ``sensor`` upper-cased, or raise `CalibrationError` if it is not OB or IB."""
    name = str(sensor).upper()
    if name not in SENSORS:
        raise CalibrationError(
            f"unknown RPC-MAG sensor {sensor!r}: only OB and IB have a ground calibration "
            "(RO-IGEP-TR0028 (Rosetta RPC-MAG calibration), sec. 3.3)"
        )
    return name


#: The calibration files a ``--calib`` folder may replace (`calibration_store`).
CALIBRATION_FILES = (*GROUND_FILE.values(), ALIGN_FILE, TIMESHIFT_FILE, JUMPS_FILE, NOMINAL_FILE)


def calibration_store(calib_dir: Path | None = None,
                      extra: tuple[str, ...] = ()) -> CalibrationStore:
    """Return the store of RPC-MAG files: ``calib_dir`` over fluxcal's defaults.

    ``calib_dir`` None: ``$FLUXCAL_CALIBRATION_DIR`` when set (`user_folder`).  Each file
    registers its other names (`names_of`) as aliases; ``extra`` adds names to serve.
    """
    names = tuple(dict.fromkeys((*CALIBRATION_FILES, *extra)))
    return CalibrationStore(default_dir(), user_folder(calib_dir),
                            aliases={n: names_of(n)[1:] for n in names})


def resolve(name: str, calib_dir: Path | None) -> Path:
    """Return the file ``name`` of ``calib_dir`` when it exists, else fluxcal's default file.

    In ``calib_dir`` the file may carry any of its names (`names_of`: the seed's, the
    archive's, ``.TXT`` or ``.ASC``); two of them with the same version is an error naming
    both (`fluxcal.calibration.store.CalibrationStore.resolve`).
    """
    refuse_unread_archive_files(user_folder(calib_dir))
    return calibration_store(calib_dir, (name,)).resolve(name).path


# ----------------------------------------------------------------------------------------
# KEY = values files
# ----------------------------------------------------------------------------------------
def read_key_file(path: Path) -> dict[str, tuple[list[str], int]]:
    """Read a ``KEY = v1 v2 ...`` file into ``{KEY: (tokens, line_number)}``.

    Keys are upper-cased and ``.`` is read as ``_`` (the seed writes both ``A.0`` and
    ``A_0``).  A line without ``=`` or a repeated key is a `CalibrationError` naming the
    file and line.
    """
    path = Path(path)
    try:
        text = read_text(path, "a 'KEY = values' calibration text file", CalibrationError)
    except OSError as exc:
        raise CalibrationError(f"cannot read calibration file {path}: {exc}") from None
    out: dict[str, tuple[list[str], int]] = {}
    for number, raw in enumerate(text.splitlines(), start=1):
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        if "=" not in line:
            raise CalibrationError(f"{path}, line {number}: expected 'KEY = values', got {raw!r}")
        key, _, value = line.partition("=")
        key = key.strip().upper().replace(".", "_")
        if key in out:
            raise CalibrationError(
                f"{path}, line {number}: key {key} repeated (first on line {out[key][1]})"
            )
        out[key] = (value.split(), number)
    return out


def _numbers(entries: dict, key: str, count: int, path: Path) -> np.ndarray:
    if key not in entries:
        raise CalibrationError(f"{path}: missing key {key} (expected {count} number(s))")
    tokens, number = entries[key]
    if len(tokens) != count:
        raise CalibrationError(
            f"{path}, line {number}: key {key} has {len(tokens)} value(s), expected {count}"
        )
    try:
        return np.array([float(t) for t in tokens])
    except ValueError:
        raise CalibrationError(
            f"{path}, line {number}: key {key} has a non-numeric value {tokens}"
        ) from None


def _text(entries: dict, key: str, default: str | None = None) -> str | None:
    if key not in entries:
        return default
    return " ".join(entries[key][0])


def _validity(entries: dict, path: Path) -> tuple[np.datetime64 | None, np.datetime64 | None]:
    out = []
    for key in ("VALID_FROM", "VALID_TO"):
        text = _text(entries, key)
        if text is None:
            out.append(None)
            continue
        try:
            out.append(np.datetime64(text, "s"))
        except ValueError:
            raise CalibrationError(
                f"{path}, line {entries[key][1]}: {key} is not an ISO time: {text!r}"
            ) from None
    return out[0], out[1]


def _file_name(source: str) -> str:
    """Return the file name of a ``source`` path (reprs name files, not folders)."""
    return Path(source).name if source else "?"


def _span(start: object, end: object) -> str:
    """Return ``start .. end`` with open ends as ``-``."""
    return f"{start if start is not None else '-'} .. {end if end is not None else '-'}"


@dataclass(frozen=True)
class Validity:
    """Validity interval ``[start, end]`` (UTC, ``None`` = open) of a calibration file."""

    source: str
    start: np.datetime64 | None = None
    end: np.datetime64 | None = None

    def check(self, first_utc: np.datetime64, last_utc: np.datetime64) -> None:
        """Raise `CalibrationRangeError` if ``[first_utc, last_utc]`` leaves the interval."""
        if (self.start is not None and first_utc < self.start) or (
            self.end is not None and last_utc > self.end
        ):
            raise CalibrationRangeError(
                f"{self.source}: valid {self.start} .. {self.end}, "
                f"data span {first_utc} .. {last_utc}"
            )


@dataclass(frozen=True)
class GroundCalibration:
    """Ground calibration of one RPC-MAG sensor (seed 003, sec. 3.3).

    Attributes
    ----------
    sensor : str
        ``"OB"`` or ``"IB"``.
    offset : ndarray, shape (2, 3)
        ``A_0`` (nT) and ``A_1`` (nT/K) of ``B_off = A_0 + A_1 T - B_res``.
    residual_field : ndarray, shape (3,)
        ``B_RES`` (nT), the coil-system residual field.
    sensitivity : ndarray, shape (2, 3)
        ``SIGMA_00`` and ``SIGMA_01`` (1/K): ``sigma^0(T) = SIGMA_00 + SIGMA_01 T``.
    angles : ndarray, shape (2, 3)
        ``XI_10`` (deg) and ``XI_11`` (deg/K), angles xi_xy, xi_xz, xi_yz at the off-centre
        position.
    k_inverse : ndarray, shape (3, 3)
        ``K^-1``, rows ``K_0``, ``K_1``, ``K_2``.
    thermistor : ndarray, shape (4,)
        ``T_0`` .. ``T_3``, the thermistor polynomial T(U) in deg C (sec. 3.3.3).
    thermistor_offset : float
        ``T_OFF`` (deg C): ``T^c = T^r - T_OFF``.
    source, version : str
        File and version, for provenance.
    validity : Validity
        Validity interval from the file header.
    residual_in_offset : bool
        Key ``B_RES_IN_OFFSET`` (1 default, 0): whether ``B_RES`` is subtracted in the
        offset (sec. 3.3.1.1 / 3.3.2.1 and 3.2.2.1 write it, sec. 3.3 "Combining all this"
        and 4.2.3.2 item 2 do not); docs/decisions/rosetta.md, decision 25.
    reduced_temperature : str
        Key ``REDUCED_TEMPERATURE``: the variable of the daily extended-temperature
        polynomial of sec. 4.2.3.3, ``CALIBRATED`` (default, ``T~ = T^c``) or
        ``CALIBRATED_MINUS_T_OFF`` (``T~ = T^c - T^O``); decision 26.

    References
    ----------
    .. [1] RO-IGEP-TR0028 (seed 003), sec. 3.3.1, 3.3.2 (tables), 3.3.3, 4.2.3.3.
    """

    sensor: str
    offset: np.ndarray
    residual_field: np.ndarray
    sensitivity: np.ndarray
    angles: np.ndarray
    k_inverse: np.ndarray
    thermistor: np.ndarray
    thermistor_offset: float
    source: str = ""
    version: str = ""
    validity: Validity = field(default_factory=lambda: Validity(""))
    residual_in_offset: bool = True
    reduced_temperature: str = "CALIBRATED"

    def __repr__(self) -> str:
        """One line: sensor, file, version, validity, the two readings (decisions 25, 26)."""
        return (f"GroundCalibration({self.sensor}, {_file_name(self.source)} "
                f"v{self.version or '?'}, valid {_span(self.validity.start, self.validity.end)}, "
                f"B_RES_IN_OFFSET={int(self.residual_in_offset)}, "
                f"REDUCED_TEMPERATURE={self.reduced_temperature})")

    def extended_model_temperature(self, calibrated: np.ndarray) -> np.ndarray:
        """Return the reduced temperature ``T~`` of sec. 4.2.3.3 from the calibrated ``T^c``."""
        t = np.asarray(calibrated, dtype=float)
        if self.reduced_temperature == "CALIBRATED_MINUS_T_OFF":
            return t - self.thermistor_offset
        return t


#: Values of the ``REDUCED_TEMPERATURE`` key (decision 26).
REDUCED_TEMPERATURES = ("CALIBRATED", "CALIBRATED_MINUS_T_OFF")


def _switch(entries: dict, key: str, allowed: tuple[str, ...], default: str, path: Path) -> str:
    value = (_text(entries, key) or default).upper()
    if value not in allowed:
        raise CalibrationError(
            f"{path}, line {entries[key][1]}: {key} = {value!r}, expected one of "
            + ", ".join(allowed)
        )
    return value


def read_ground_calibration(path: Path, sensor: str | None = None) -> GroundCalibration:
    """Parse a ground-calibration file (seed 003, sec. 3.3).

    Parameters
    ----------
    path : Path
        The file.
    sensor : str, optional
        Expected sensor; a different ``SENSOR`` key in the file is an error.

    Raises
    ------
    CalibrationError
        Missing key, wrong count of values, non-numeric value, unknown sensor.

    References
    ----------
    .. [1] RO-IGEP-TR0028 (seed 003), sec. 3.3.1.1-3.3.3 (labels A_0, A_1, SIGMA_00,
       SIGMA_01, XI_10, XI_11, K_0..K_2, T_0..T_3, T_OFF); the switches
       ``B_RES_IN_OFFSET`` and ``REDUCED_TEMPERATURE`` are fluxcal's (decisions 25, 26).
    """
    path = Path(path)
    entries = read_key_file(path)
    file_sensor = _text(entries, "SENSOR")
    if file_sensor is None:
        raise CalibrationError(f"{path}: missing key SENSOR (expected OB or IB)")
    file_sensor = check_sensor(file_sensor)
    if sensor is not None and check_sensor(sensor) != file_sensor:
        raise CalibrationError(f"{path}: SENSOR = {file_sensor}, but sensor {sensor} was requested")
    num = lambda key, n=3: _numbers(entries, key, n, path)  # noqa: E731
    start, end = _validity(entries, path)
    return GroundCalibration(
        sensor=file_sensor,
        offset=np.stack([num("A_0"), num("A_1")]),
        residual_field=num("B_RES"),
        sensitivity=np.stack([num("SIGMA_00"), num("SIGMA_01")]),
        angles=np.stack([num("XI_10"), num("XI_11")]),
        k_inverse=np.stack([num("K_0"), num("K_1"), num("K_2")]),
        thermistor=np.concatenate([num(f"T_{i}", 1) for i in range(4)]),
        thermistor_offset=float(num("T_OFF", 1)[0]),
        source=str(path),
        version=_text(entries, "VERSION", "unversioned") or "",
        validity=Validity(str(path), start, end),
        residual_in_offset=_switch(entries, "B_RES_IN_OFFSET", ("1", "0"), "1", path) == "1",
        reduced_temperature=_switch(
            entries, "REDUCED_TEMPERATURE", REDUCED_TEMPERATURES, "CALIBRATED", path
        ),
    )


def load_ground_calibration(sensor: str, calib_dir: Path | None = None) -> GroundCalibration:
    """Load the ground calibration of ``sensor`` from ``calib_dir`` or fluxcal's defaults."""
    sensor = check_sensor(sensor)
    return read_ground_calibration(resolve(GROUND_FILE[sensor], calib_dir), sensor)


def write_ground_calibration(cal: GroundCalibration, path: Path) -> Path:
    """Write ``cal`` as a ground-calibration file readable by `read_ground_calibration`."""
    vec = lambda v: " ".join(repr(float(x)) for x in np.ravel(v))  # noqa: E731
    lines = [
        "# RPC-MAG ground calibration written by fluxcal (RO-IGEP-TR0028, sec. 3.3 format)",
        f"VERSION = {cal.version or '001'}",
        f"SENSOR = {cal.sensor}",
        f"A_0 = {vec(cal.offset[0])}",
        f"A_1 = {vec(cal.offset[1])}",
        f"B_RES = {vec(cal.residual_field)}",
        f"SIGMA_00 = {vec(cal.sensitivity[0])}",
        f"SIGMA_01 = {vec(cal.sensitivity[1])}",
        f"XI_10 = {vec(cal.angles[0])}",
        f"XI_11 = {vec(cal.angles[1])}",
        *(f"K_{i} = {vec(cal.k_inverse[i])}" for i in range(3)),
        *(f"T_{i} = {vec(cal.thermistor[i])}" for i in range(4)),
        f"T_OFF = {cal.thermistor_offset!r}",
        f"B_RES_IN_OFFSET = {int(cal.residual_in_offset)}",
        f"REDUCED_TEMPERATURE = {cal.reduced_temperature}",
    ]
    atomic_write_bytes(Path(path), "\n".join(lines) + "\n", now=True)
    return Path(path)


# ----------------------------------------------------------------------------------------
# Extended temperature model (daily files)
# ----------------------------------------------------------------------------------------
@dataclass(frozen=True)
class DailyOffsetModel:
    """Daily extended-temperature offset polynomial of one sensor (seed 003, sec. 4.2.3.3).

    ``coefficients[k]`` holds ``P_k`` (x, y, z, nT per deg C^k); the polynomial's variable
    is the calibrated sensor temperature in deg C.  A file written by ``fluxcal rosetta
    fit`` also records where the polynomial was fitted, ``temperature_range`` (reduced
    temperature, deg C; key ``T_RANGE``), and its stated 1-sigma error there,
    ``curve_sigma`` (largest over the range, x y z nT; key ``SIGMA_CURVE``); both
    ``None`` for a file without them (the seed's files; issue 34).
    """

    day: np.datetime64
    sensor: str
    coefficients: np.ndarray
    source: str = ""
    temperature_range: tuple[float, float] | None = None
    curve_sigma: np.ndarray | None = None

    def __repr__(self) -> str:
        """One line: day, sensor, polynomial degree, file."""
        return (f"DailyOffsetModel({self.day}, {self.sensor}, degree "
                f"{len(self.coefficients) - 1}, {_file_name(self.source)})")


def read_daily_offset_model(path: Path) -> DailyOffsetModel:
    """Parse ``RPCMAG_<yymmdd>_006_CALIB_<IB|OB>.TXT`` (keys ``P_0`` .. ``P_5``).

    References
    ----------
    .. [1] RO-IGEP-TR0028 (seed 003), sec. 4.2.3.3.
    """
    path = Path(path)
    match = _DAILY_RE.match(path.name)
    if match is None:
        raise CalibrationError(
            f"{path}: name does not follow RPCMAG_<yymmdd>_006_CALIB_<IB|OB>.TXT (or .ASC) "
            "(sec. 4.2.3.3)"
        )
    yymmdd, sensor = match.group(1), match.group(2).upper()
    try:
        day = np.datetime64(dt.datetime.strptime(yymmdd, "%y%m%d").date(), "D")
    except ValueError:
        raise CalibrationError(f"{path}: {yymmdd!r} is not a date yymmdd") from None
    entries = read_key_file(path)
    file_sensor = _text(entries, "SENSOR")
    if file_sensor is not None and check_sensor(file_sensor) != sensor:
        raise CalibrationError(
            f"{path}: SENSOR = {file_sensor} contradicts the file name ({sensor})"
        )
    coeffs = np.stack([_numbers(entries, f"P_{k}", 3, path) for k in range(6)])
    t_range = None
    if "T_RANGE" in entries:
        lo, hi = _numbers(entries, "T_RANGE", 2, path)
        if not lo <= hi:
            raise CalibrationError(f"{path}, line {entries['T_RANGE'][1]}: T_RANGE {lo:g} "
                                   f"{hi:g} is not 'lowest highest' (deg C)")
        t_range = (float(lo), float(hi))
    sigma = _numbers(entries, "SIGMA_CURVE", 3, path) if "SIGMA_CURVE" in entries else None
    return DailyOffsetModel(day=day, sensor=sensor, coefficients=coeffs, source=str(path),
                            temperature_range=t_range, curve_sigma=sigma)


def find_daily_offset_models(
    calib_dir: Path | None, sensor: str
) -> dict[np.datetime64, DailyOffsetModel]:
    """Return the daily extended-temperature models of ``sensor`` found in ``calib_dir``."""
    sensor = check_sensor(sensor)
    out: dict[np.datetime64, DailyOffsetModel] = {}
    calib_dir = user_folder(calib_dir)
    if calib_dir is None:
        return out
    refuse_unread_archive_files(calib_dir)
    for path in sorted(Path(calib_dir).glob("*")):
        match = _DAILY_RE.match(path.name)
        if match and match.group(2).upper() == sensor:
            model = read_daily_offset_model(path)
            if model.day in out:  # e.g. the .TXT and the .ASC of one day
                raise CalibrationError(
                    f"{calib_dir}: both {Path(out[model.day].source).name} and {path.name} "
                    f"hold the {sensor} model of {model.day}: keep one"
                )
            out[model.day] = model
    return out


def write_daily_offset_model(
    model: DailyOffsetModel, folder: Path, *, comments: tuple[str, ...] | list[str] = ()
) -> Path:
    """Write ``model`` as ``RPCMAG_<yymmdd>_006_CALIB_<sensor>.TXT`` in ``folder``.

    ``comments`` are written as ``#`` lines after the header (e.g. fit provenance).
    """
    day = model.day.astype(dt.date)
    path = Path(folder) / f"RPCMAG_{day:%y%m%d}_006_CALIB_{model.sensor}.TXT"
    lines = [
        "# RPC-MAG extended temperature model 006 (RO-IGEP-TR0028, sec. 4.2.3.3), nT per degC^k",
        *("# " + " ".join(str(c).split()) for c in comments),
        f"SENSOR = {model.sensor}",
    ]
    lines += [
        f"P_{k} = " + " ".join(repr(float(v)) for v in model.coefficients[k]) for k in range(6)
    ]
    if model.temperature_range is not None:
        lines.append("T_RANGE = " + " ".join(repr(float(v)) for v in model.temperature_range))
    if model.curve_sigma is not None:
        lines.append("SIGMA_CURVE = " + " ".join(repr(float(v)) for v in model.curve_sigma))
    atomic_write_bytes(path, "\n".join(lines) + "\n", now=True)
    return path


# ----------------------------------------------------------------------------------------
# Alignment
# ----------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Alignment:
    """Rotation matrices R_UVW2SC (sec. 4.3.1).

    ``matrices`` is keyed ``(sensor, boom)`` with boom ``"deployed"`` or ``"stowed"``.
    """

    matrices: dict[tuple[str, str], np.ndarray]
    source: str = ""
    version: str = ""
    placeholder: bool = False

    def __repr__(self) -> str:
        """One line: file, version, the sensor/boom matrices held, placeholder or not."""
        keys = ", ".join(f"{s}/{b}" for s, b in sorted(self.matrices))
        return (f"Alignment({_file_name(self.source)} v{self.version or '?'}: {keys}"
                f"{'; PLACEHOLDER' if self.placeholder else ''})")

    def matrix(self, sensor: str, boom: str = "deployed") -> np.ndarray:
        """Return R_UVW2SC of ``sensor`` for boom state ``boom``."""
        key = (check_sensor(sensor), str(boom).lower())
        if key not in self.matrices:
            raise CalibrationError(f"{self.source}: no alignment for {key[0]} with boom {key[1]!r}")
        return self.matrices[key]


def read_alignment(path: Path, *, tolerance: float = 1e-4) -> Alignment:
    """Parse the alignment file ``RPCMAG_SC_ALIGN.TXT``.

    Keys ``OB_DEPLOYED``, ``OB_STOWED``, ``IB_DEPLOYED``, ``IB_STOWED``, nine numbers
    each (row-major R_UVW2SC).

    A matrix that is not a rotation within ``tolerance`` (``|R R^T - I|``, ``det R``) is a
    `CalibrationError`.

    References
    ----------
    .. [1] RO-IGEP-TR0028 (seed 003), sec. 4.3.1.
    """
    path = Path(path)
    entries = read_key_file(path)
    matrices = {}
    for sensor in SENSORS:
        for boom in ("deployed", "stowed"):
            key = f"{sensor}_{boom.upper()}"
            m = _numbers(entries, key, 9, path).reshape(3, 3)
            err = np.abs(m @ m.T - np.eye(3)).max()
            if err > tolerance or np.linalg.det(m) < 0:
                raise CalibrationError(
                    f"{path}, line {entries[key][1]}: {key} is not a rotation matrix "
                    f"(|R R^T - I| = {err:.2g}, det = {np.linalg.det(m):.6f})"
                )
            matrices[(sensor, boom)] = m
    placeholder = _text(entries, "PLACEHOLDER", "0") not in ("0", "", None)
    return Alignment(
        matrices, str(path), _text(entries, "VERSION", "unversioned") or "", placeholder
    )


def load_alignment(calib_dir: Path | None = None) -> Alignment:
    """Load ``RPCMAG_SC_ALIGN.TXT`` from ``calib_dir`` or fluxcal's default (placeholder)."""
    return read_alignment(resolve(ALIGN_FILE, calib_dir))


def write_alignment(alignment: Alignment, path: Path) -> Path:
    """Write ``alignment`` in the ``RPCMAG_SC_ALIGN.TXT`` format."""
    lines = [
        "# RPC-MAG R_UVW2SC, row-major (RO-IGEP-TR0028, sec. 4.3.1), written by fluxcal",
        f"VERSION = {alignment.version or '001'}",
    ]
    for (sensor, boom), m in sorted(alignment.matrices.items()):
        lines.append(f"{sensor}_{boom.upper()} = " + " ".join(repr(float(v)) for v in m.ravel()))
    atomic_write_bytes(Path(path), "\n".join(lines) + "\n", now=True)
    return Path(path)


# ----------------------------------------------------------------------------------------
# CSV tables: time shifts and offset jumps
# ----------------------------------------------------------------------------------------
def _csv_rows(path: Path) -> list[tuple[int, dict[str, str]]]:
    try:
        lines = read_text(path, "a CSV calibration table", CalibrationError).splitlines()
    except OSError as exc:
        raise CalibrationError(f"cannot read calibration table {path}: {exc}") from None
    numbered = [
        (i, line)
        for i, line in enumerate(lines, start=1)
        if line.strip() and not line.startswith("#")
    ]
    if not numbered:
        raise CalibrationError(f"{path}: empty table")
    reader = csv.DictReader([line for _, line in numbered])
    return [(numbered[k + 1][0], row) for k, row in enumerate(reader)]


@dataclass(frozen=True)
class TimeShiftTable:
    """Filter-mode time shifts (s) to add to the time stamps (seed 003, sec. 4.2.3.5).

    ``primary[sid]`` and ``secondary[sid]`` are NaN where the seed's table has no entry.
    """

    sid: np.ndarray
    primary: np.ndarray
    secondary: np.ndarray
    source: str = ""

    def __repr__(self) -> str:
        """One line: file and the primary shift (s) of each SID."""
        shifts = ", ".join(f"SID{int(i)} {p:g}" for i, p in zip(self.sid, self.primary,
                                                               strict=True))
        return f"TimeShiftTable({_file_name(self.source)}: primary s {shifts})"


def read_time_shift_table(path: Path) -> TimeShiftTable:
    """Parse ``RPCMAG_FILTER_TIMESHIFT.csv`` (columns sid, primary_shift_s, secondary_shift_s)."""
    rows = _csv_rows(path)
    sid, primary, secondary = [], [], []
    for number, row in rows:
        try:
            sid.append(int(row["sid"]))
            primary.append(float(row["primary_shift_s"]) if row["primary_shift_s"] else np.nan)
            secondary.append(
                float(row["secondary_shift_s"]) if row["secondary_shift_s"] else np.nan
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise CalibrationError(
                f"{path}, line {number}: bad time-shift row {row}: {exc}"
            ) from None
        for name, value in (("primary_shift_s", primary[-1]), ("secondary_shift_s", secondary[-1])):
            if value < 0:  # NaN (no entry) passes
                raise CalibrationError(
                    f"{path}, line {number}, field '{name}': negative filter time shift "
                    f"({value} s) for SID {sid[-1]}; the shifts are filter delays >= 0 "
                    "(RO-IGEP-TR0028 sec. 4.2.3.5)"
                )
    return TimeShiftTable(np.array(sid), np.array(primary), np.array(secondary), str(path))


def load_time_shift_table(calib_dir: Path | None = None) -> TimeShiftTable:
    """Load the filter-mode time-shift table from ``calib_dir`` or fluxcal's default."""
    return read_time_shift_table(resolve(TIMESHIFT_FILE, calib_dir))


@dataclass(frozen=True)
class OffsetJumpTable:
    """Post-hibernation offset jumps (seed 003, Appendix B), applied on ``[start, end)``.

    Attributes
    ----------
    start_utc, end_utc : ndarray of str
        Interval limits (UTC, ISO).
    jumps : dict[str, ndarray]
        ``{"OB": (m, 3), "IB": (m, 3)}`` in nT (NaN = unknown).
    """

    start_utc: np.ndarray
    end_utc: np.ndarray
    jumps: dict[str, np.ndarray]
    source: str = ""

    def __repr__(self) -> str:
        """One line: file, number of intervals, the span they cover, sensors."""
        span = _span(min(self.start_utc), max(self.end_utc)) if len(self.start_utc) else "-"
        return (f"OffsetJumpTable({_file_name(self.source)}: {len(self.start_utc)} intervals "
                f"{span}, sensors {', '.join(sorted(self.jumps))})")


def read_offset_jump_table(path: Path) -> OffsetJumpTable:
    """Parse ``RPCMAG_OFFSET_JUMPS.csv`` (Appendix B of seed 003)."""
    rows = _csv_rows(path)
    start, end, ob, ib = [], [], [], []
    for number, row in rows:
        try:
            a, b = np.datetime64(row["start_utc"], "s"), np.datetime64(row["end_utc"], "s")
            ob.append([float(row[f"ob_{c}"]) for c in "xyz"])
            ib.append([float(row[f"ib_{c}"]) for c in "xyz"])
        except (KeyError, TypeError, ValueError) as exc:
            raise CalibrationError(f"{path}, line {number}: bad offset-jump row: {exc}") from None
        if b <= a:
            raise CalibrationError(
                f"{path}, line {number}: interval end {b} is not after start {a}"
            )
        start.append(row["start_utc"])
        end.append(row["end_utc"])
    return OffsetJumpTable(
        np.array(start), np.array(end), {"OB": np.array(ob), "IB": np.array(ib)}, str(path)
    )


def load_offset_jump_table(calib_dir: Path | None = None) -> OffsetJumpTable:
    """Load the offset-jump table from ``calib_dir`` or fluxcal's default."""
    return read_offset_jump_table(resolve(JUMPS_FILE, calib_dir))


# ----------------------------------------------------------------------------------------
# Nominal conversion constants
# ----------------------------------------------------------------------------------------
def load_nominal_conversion(calib_dir: Path | None = None) -> dict:
    """Load the nominal ADC conversion constants (sec. 4.2.1-4.2.3.1) as a dict of sections."""
    path = resolve(NOMINAL_FILE, calib_dir)
    try:
        return tomllib.loads(read_text(path, "a TOML calibration file", CalibrationError))
    except tomllib.TOMLDecodeError as exc:
        raise CalibrationError(f"{path}: {exc}") from None
