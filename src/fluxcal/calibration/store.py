"""One calibration store: versioned, dated tables, a user folder over shipped defaults.

A *table* is a calibration file known by a name.  Its file is named either

- ``<name>_v<version>.<ext>`` (versioned names; several versions may sit side by side),
- ``<name>`` itself (a fixed name, e.g. an archive's file name; the version is in the header),
- or one of the *aliases* a mission registers for ``<name>`` (e.g. the name an archive
  gives the same file, another extension, lower case).

Every text table carries the same header (docs/decisions/calibration_store.md):

- lines ``# key: value`` among the comment lines (any text format: CSV, ``KEY = values``,
  TOML), the first occurrence of a key counting;
- or, for the header fields only, a line ``key = value`` before the first ``[section]``
  (a TOML file's top-level keys, a ``KEY = values`` file's ``VERSION = 001``), keys read
  case-blind; such a line wins over a comment line of the same key.

The header fields are ``name`` (optional, the file name gives it), ``version`` (a whole
number, compared as one; any other text is kept but cannot be ordered; it must equal the
file name's where the name carries one), ``valid_from`` and
``valid_to`` (ISO UTC, interval ``[valid_from, valid_to)``, either end open when absent) and
``source`` (where the values come from).  The store adds the SHA-256 ``checksum`` of the
file's bytes.

Resolution (`CalibrationStore.resolve`): the user folder, where it holds *any* file of a
table, hides every shipped file of that table (file-by-file override at the level of a
table); within that folder, among the files whose interval covers the requested time, the
highest version wins; two files of one table with that same version is an error naming
both.  The user folder is an explicit argument, or the folder named by the environment
variable ``FLUXCAL_CALIBRATION_DIR`` (`user_folder`); nothing is cached between calls.

The decisions behind these rules (and what each mission registers) are in
docs/decisions/calibration_store.md.
"""

from __future__ import annotations

import hashlib
import os
import re
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from fluxcal.errors import CalibrationError, CalibrationRangeError
from fluxcal.textfile import decode_text

#: The environment variable naming a user calibration folder when none is given explicitly.
ENV_VAR = "FLUXCAL_CALIBRATION_DIR"
#: The header fields of every table (``checksum`` is computed, not written).
HEADER_FIELDS = ("name", "version", "valid_from", "valid_to", "source")
#: A versioned file name: ``<name>_v<version>.<ext>``.
VERSIONED_NAME = re.compile(r"^(?P<name>.+)_v(?P<version>\d+)\.(?P<ext>[A-Za-z0-9]+)$")
_COMMENT_FIELD = re.compile(r"^#\s*(?P<key>[A-Za-z][A-Za-z0-9_ -]*?)\s*:\s*(?P<value>.*)$")
_ASSIGN_FIELD = re.compile(r"^(?P<key>[A-Za-z][A-Za-z0-9_.]*)\s*=\s*(?P<value>[^#]*)")


def user_folder(explicit: Path | str | None,
                environ: Mapping[str, str] | None = None) -> Path | None:
    """Return the user calibration folder: ``explicit``, else ``$FLUXCAL_CALIBRATION_DIR``.

    Parameters
    ----------
    explicit : Path or str, optional
        A folder given by the caller (e.g. ``--calib DIR``); it always wins.
    environ : mapping, optional
        The environment to read (default `os.environ`, read at this call: nothing is kept).

    Returns
    -------
    Path or None
        ``None`` when neither names a folder (shipped defaults only).
    """
    if explicit is not None:
        return Path(explicit)
    value = (os.environ if environ is None else environ).get(ENV_VAR, "").strip()
    return Path(value) if value else None


def _key(name: str) -> str:
    """Normalise a header key: case-blind, spaces and hyphens read as ``_``."""
    return re.sub(r"[\s-]+", "_", name.strip().lower())


def _value(text: str) -> str:
    """Strip blanks and one pair of surrounding quotes (TOML strings)."""
    text = text.strip()
    if len(text) >= 2 and text[0] == text[-1] and text[0] in "\"'":
        return text[1:-1]
    return text


def _fields(text: str) -> tuple[dict[str, str], dict[str, int]]:
    """Header fields of a text table and the line of each.

    The first occurrence of a key counts; a ``key = value`` line (the file's own data, e.g.
    a TOML top-level key) wins over a ``# key: value`` comment of the same key.
    """
    found: dict[bool, tuple[dict[str, str], dict[str, int]]] = {True: ({}, {}), False: ({}, {})}
    for number, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        if line.startswith("["):  # a TOML section: top-level keys are over
            break
        comment = line.startswith("#")
        match = (_COMMENT_FIELD if comment else _ASSIGN_FIELD).match(line)
        if match is None or (not comment and _key(match["key"]) not in HEADER_FIELDS):
            continue
        fields, lines = found[comment]
        if _key(match["key"]) not in lines:
            fields[match["key"].strip()] = _value(match["value"])
            lines[_key(match["key"])] = number
    fields, lines = found[True]
    for key, value in found[False][0].items():  # assignments over comments
        fields = {k: v for k, v in fields.items() if _key(k) != _key(key)}
        fields[key] = value
    return fields, {**lines, **found[False][1]}


@dataclass(frozen=True)
class TableHeader:
    """The header of one calibration file: the one format every table carries.

    Attributes
    ----------
    name : str
        The table's name (not the file's: an alias resolves to its table).
    version : int, str or None
        Version: a whole number (``001`` reads 1), else the text as written (e.g.
        ``sim-1``, which `CalibrationStore.resolve` cannot order against another file);
        ``None`` when neither the header nor the file name gives one.
    valid_from, valid_to : numpy.datetime64 or None
        Validity ``[valid_from, valid_to)`` (UTC, s); ``None`` is an open end.
    source : str
        Where the values come from (header ``source``; ``""`` when absent).
    checksum : str
        SHA-256 of the file's bytes (hex).
    path : Path
        The file.
    fields : dict
        Every header field as written (key -> value), e.g. ``units`` or ``based on``.
    """

    name: str
    version: int | str | None
    valid_from: np.datetime64 | None
    valid_to: np.datetime64 | None
    source: str
    checksum: str
    path: Path
    fields: Mapping[str, str] = field(default_factory=dict, repr=False, compare=False)

    def __repr__(self) -> str:
        """One line: name, version, validity, file name and the checksum's head."""
        return (f"TableHeader({self.name} v{'?' if self.version is None else self.version}, "
                f"valid {_end(self.valid_from)} .. {_end(self.valid_to)}, {self.path.name}, "
                f"sha256 {self.checksum[:12]})")

    def covers(self, when: np.datetime64 | str) -> bool:
        """Whether instant ``when`` (UTC) lies in ``[valid_from, valid_to)``."""
        t = np.datetime64(when, "s")
        return bool((self.valid_from is None or self.valid_from <= t)
                    and (self.valid_to is None or t < self.valid_to))

    def field(self, key: str, default: str | None = None) -> str | None:
        """Return header field ``key`` (case-blind, spaces read as ``_``) or ``default``."""
        wanted = _key(key)
        for k, v in self.fields.items():
            if _key(k) == wanted:
                return v
        return default


def _rank(header: TableHeader) -> int:
    """Order of versions for listing: none < text < 0 < 1 < ... (text never competes)."""
    if header.version is None:
        return -2
    return header.version if isinstance(header.version, int) else -1


def _end(value: np.datetime64 | None) -> str:
    return "-" if value is None else str(value)


def read_header(path: Path | str, name: str | None = None, *,
                require: Iterable[str] = ()) -> TableHeader:
    """Read the header of calibration file ``path`` (the one format of this module).

    Parameters
    ----------
    path : Path or str
        The file (text: CSV, ``KEY = values`` or TOML).
    name : str, optional
        The table's name (default: from a versioned file name, else the file name).
    require : iterable of str
        Header fields the file must carry (e.g. ``("version", "valid_from", "valid_to")``).

    Returns
    -------
    TableHeader

    Raises
    ------
    CalibrationError
        One line naming the file, the line and the field: not text, a required field
        absent, a version that differs from the file name's, a
        validity end that is not an ISO UTC time, an interval that ends before it starts.
    """
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise CalibrationError(f"{path}: cannot read the calibration file: "
                               f"{exc.strerror or exc}") from None
    text = decode_text(data, path, "a text calibration table", CalibrationError)
    fields, lines = _fields(text)
    by_key = {_key(k): v for k, v in fields.items()}
    for key in require:
        if _key(key) not in by_key:
            raise CalibrationError(f"{path}: header field '{key}' is missing "
                                   f"(a line '# {key}: ...')")
    named = VERSIONED_NAME.match(path.name)
    version: int | str | None = None
    if "version" in by_key:
        text_version = by_key["version"]
        version = int(text_version) if text_version.isdigit() else text_version
        if named is not None and version != int(named["version"]):
            raise CalibrationError(f"{path}, line {lines['version']}: header field 'version' "
                                   f"{text_version} differs from the file name's "
                                   f"v{named['version']}")
    elif named is not None:
        version = int(named["version"])
    valid: dict[str, np.datetime64 | None] = {}
    for key in ("valid_from", "valid_to"):
        valid[key] = None
        if key in by_key:
            try:
                valid[key] = np.datetime64(by_key[key], "s")
            except ValueError:
                raise CalibrationError(
                    f"{path}, line {lines[key]}: header field '{key}' {by_key[key]!r} is not "
                    "an ISO UTC time such as 2004-08-03T00:00:00") from None
    if (valid["valid_from"] is not None and valid["valid_to"] is not None
            and valid["valid_to"] <= valid["valid_from"]):
        raise CalibrationError(f"{path}, line {lines['valid_to']}: header field 'valid_to' "
                               f"{valid['valid_to']} is not after valid_from "
                               f"{valid['valid_from']}")
    if name is None:
        name = by_key.get("name") or (named["name"] if named is not None else path.name)
    return TableHeader(
        name=name,
        version=version,
        valid_from=valid["valid_from"],
        valid_to=valid["valid_to"],
        source=by_key.get("source", ""),
        checksum=hashlib.sha256(data).hexdigest(),
        path=path,
        fields=fields,
    )


class CalibrationStore:
    """Calibration tables of a user folder over a folder of shipped defaults.

    Parameters
    ----------
    defaults : Path
        The shipped tables (e.g. a mission package's ``data`` folder).
    user : Path, optional
        A user folder whose tables replace the shipped ones table by table (see
        `user_folder` for the ``FLUXCAL_CALIBRATION_DIR`` variable); ``None``: defaults only.
    aliases : mapping, optional
        Table name -> other file names of that table (e.g. an archive's names).
    names : iterable of str, optional
        The tables this store serves (for `tables`); default: the aliases' keys.
    require : iterable of str
        Header fields every table must carry (`read_header`).

    Notes
    -----
    The store keeps no state between calls: every `resolve` lists the folders again, so a
    file added to the user folder is seen at the next call.

    Examples
    --------
    >>> store = CalibrationStore(Path("data"), Path("mine"), aliases={"A.TXT": ["A.ASC"]})
    >>> header = store.resolve("gain", "2012-06-01")  # doctest: +SKIP
    """

    def __init__(self, defaults: Path | str, user: Path | str | None = None, *,
                 aliases: Mapping[str, Iterable[str]] | None = None,
                 names: Iterable[str] | None = None, require: Iterable[str] = ()) -> None:
        self.defaults = Path(defaults)
        self.user = None if user is None else Path(user)
        self.aliases = {k: tuple(v) for k, v in (aliases or {}).items()}
        self.names = tuple(self.aliases if names is None else names)
        self.require = tuple(require)
        self._alias_of = {a: k for k, v in self.aliases.items() for a in v}

    def __repr__(self) -> str:
        """One line: the folders by name, in order of precedence, and the alias count."""
        where = f"{self.defaults.name}/" if self.user is None else (
            f"{self.user.name}/ over {self.defaults.name}/")
        return (f"CalibrationStore({where}, {len(self.names)} tables, "
                f"{sum(map(len, self.aliases.values()))} aliases)")

    @property
    def folders(self) -> tuple[Path, ...]:
        """The folders, highest precedence first."""
        return (self.defaults,) if self.user is None else (self.user, self.defaults)

    def table_of(self, file_name: str) -> str | None:
        """Return the table a file name belongs to (canonical, alias or versioned), or None."""
        if file_name in self._alias_of:
            return self._alias_of[file_name]
        if file_name in self.names or file_name in self.aliases:
            return file_name
        named = VERSIONED_NAME.match(file_name)
        if named is not None and (not self.names or named["name"] in self.names):
            return named["name"]
        return None

    def _files(self, folder: Path, name: str) -> list[Path]:
        """Return the files of table ``name`` in ``folder`` (sorted by file name)."""
        if not folder.is_dir():
            return []
        accepted = {name, *self.aliases.get(name, ())}
        out = []
        for path in sorted(folder.iterdir()):
            named = VERSIONED_NAME.match(path.name)
            if (path.name in accepted or (named is not None and named["name"] == name)) and (
                    path.is_file()):
                out.append(path)
        return out

    def versions(self, name: str) -> list[TableHeader]:
        """Return every file of table ``name`` in the folder providing it, lowest version first.

        Raises
        ------
        CalibrationError
            When the user folder is not a folder, no folder holds a file of the table, or
            a header is malformed.
        """
        if self.user is not None and not self.user.is_dir():
            raise CalibrationError(f"{self.user}: the user calibration folder does not exist "
                                   "or is not a folder")
        for folder in self.folders:
            files = self._files(folder, name)
            if files:
                headers = [read_header(p, name, require=self.require) for p in files]
                return sorted(headers, key=lambda h: (_rank(h), str(h.version), h.path.name))
        accepted = ", ".join(dict.fromkeys([f"{name}_v<N>.*", name, *self.aliases.get(name, ())]))
        if self.user is None:
            raise CalibrationError(f"calibration table {name} not found in {self.defaults} "
                                   f"(file names {accepted})")
        raise CalibrationError(f"calibration table {name} found neither in {self.user} nor in "
                               f"{self.defaults} (file names {accepted})")

    def resolve(self, name: str, when: np.datetime64 | str | None = None) -> TableHeader:
        """Return the header of the file of table ``name`` to use at ``when``.

        Parameters
        ----------
        name : str
            The table.
        when : numpy.datetime64 or str, optional
            An instant (UTC) the table must cover; ``None``: any (highest version).

        Returns
        -------
        TableHeader
            Its ``path`` is the file to read.

        Raises
        ------
        CalibrationRangeError
            When no file of the table covers ``when`` (the message lists every interval).
        CalibrationError
            When the table is missing, a header is malformed, or two files of the table
            share the winning version (ambiguous: the message names both).
        """
        candidates = self.versions(name)
        if when is not None:
            at = np.datetime64(when, "s")
            valid = [h for h in candidates if h.covers(at)]
            if not valid:
                spans = ", ".join(f"v{h.version} [{_end(h.valid_from)}, {_end(h.valid_to)}) "
                                  f"{h.path.name}" for h in candidates)
                raise CalibrationRangeError(
                    f"{candidates[0].path.parent}: calibration table {name}: {at} lies outside "
                    f"every validity interval ({spans})")
        else:
            valid = candidates
        text = [h for h in valid if isinstance(h.version, str)]
        if len(valid) > 1 and text:
            other = next(h for h in valid if h is not text[0])
            raise CalibrationError(
                f"{text[0].path}: version {text[0].version!r} is not a whole number, so it "
                f"cannot be ordered against {other.path.name} (version {other.version}), "
                f"another file of calibration table {name}: keep one")
        best = valid[-1]
        tied = [h for h in valid if _rank(h) == _rank(best)]
        if len(tied) > 1:
            a, b = tied[0].path, tied[1].path
            version = "(none)" if best.version is None else best.version
            at = "" if when is None else f" valid at {np.datetime64(when, 's')}"
            raise CalibrationError(f"{a.parent}: both {a.name} and {b.name} hold calibration "
                                   f"table {name} version {version}{at}: keep one")
        return best

    def tables(self, when: np.datetime64 | str | None = None) -> list[TableHeader]:
        """Return every file of every served table in both folders (used ones first).

        Returns the headers of the files `resolve` would pick at ``when`` for each table
        in `names`, followed by every other file of those tables (older versions,
        shadowed defaults), each group in table order.
        """
        used: list[TableHeader] = []
        others: list[TableHeader] = []
        for name in self.names:
            chosen = self.resolve(name, when)
            used.append(chosen)
            for folder in self.folders:
                others += [read_header(p, name) for p in self._files(folder, name)
                           if p != chosen.path]
        return used + others


def describe(headers: Sequence[TableHeader], used: int | None = None) -> list[str]:
    """Return one line per header (``*`` marks the first ``used`` ones): for listings.

    Each line: name, version, validity, file and folder names, checksum head, source.
    """
    used = len(headers) if used is None else used
    out = []
    for i, h in enumerate(headers):
        version = "-" if h.version is None else str(h.version)
        out.append(f"{'*' if i < used else ' '} {h.name:<34} v{version:<4} "
                   f"{_end(h.valid_from)[:10]} .. {_end(h.valid_to)[:10]}  "
                   f"{h.path.parent.name}/{h.path.name}  sha256 {h.checksum[:12]}"
                   f"{'  ' + h.source if h.source else ''}")
    return out
