"""PDS3 labels (ODL) written and read with `pvl`, and the attribute encoding they carry.

Writing goes through `pvl.PDSLabelEncoder` (uppercase keywords, ``OBJECT``/
``END_OBJECT`` blocks, CRLF, ``END``), with one change: every text value is
double-quoted and bare symbols are marked explicitly with `Symbol`, so a string never
turns into another type on reading.  The encoder remembers the text of each OBJECT and
GROUP block by content (`_frozen`): the COLUMN objects and shared attributes of a day's
products are encoded once, not once per product.  Reading goes through ``pvl.loads`` with the PDS
grammar and decoder.

PDS3 text strings cannot hold a double quote and readers fold whitespace, so a string
is written as is only when it is "plain" (printable ASCII, no ``"`` or backslash, no
leading, trailing or repeated whitespace); any other string is percent-encoded (RFC 3986
style, ``%22`` for ``"``) and flagged with ``ENCODING = PERCENT``.  Dataset attributes (any
JSON-like value: numbers, text, lists, dicts, ``None``) become nested ``ATTRIBUTE``
objects (`attributes_object` / `decode_attributes`), so a label has no JSON and no
backslash escapes, and ``decode_attributes(attributes_object(a)) == a``.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping
from functools import lru_cache
from pathlib import Path
from typing import Any
from urllib.parse import quote, unquote

import numpy as np
import pvl
from pvl.decoder import PDSLabelDecoder
from pvl.grammar import PDSGrammar

from fluxcal.errors import InputFormatError

_PRINTABLE = "".join(chr(c) for c in range(33, 127) if chr(c) not in '"%\\')
ATTRIBUTE = "ATTRIBUTE"


class Symbol(str):
    """A bare (unquoted) ODL symbol such as ``ASCII_REAL`` or ``PDS3``."""


def is_plain(s: str) -> bool:
    """Tell whether ``s`` survives a PDS3 quoted string unchanged (see module docstring)."""
    return (
        s.isascii()
        and s.isprintable()
        and '"' not in s
        and "\\" not in s  # a backslash before the closing quote reads as an escape
        and s == s.strip()
        and "  " not in s
    )


def percent_encode(s: str) -> str:
    """Percent-encode ``s`` (UTF-8): all but printable ASCII, and blank, quote, % and backslash."""
    return quote(s, safe=_PRINTABLE)


class _Grammar(PDSGrammar):
    """`PDSGrammar` whose ``char_allowed`` is a set lookup.

    pvl's encoder checks ``char_allowed`` on every character of the finished label
    text; for a big label that check was half of the encoding time.  The set holds the
    characters below 256 that `PDSGrammar.char_allowed` accepts; it accepts none above
    (ODL is ASCII), so the verdicts are the same.
    """

    def __init__(self) -> None:
        super().__init__()
        check = PDSGrammar.char_allowed
        allowed = frozenset(chr(o) for o in range(256) if check(self, chr(o)))
        self.char_allowed = allowed.__contains__  # type: ignore[method-assign]


class _Encoder(pvl.PDSLabelEncoder):
    """PDS3 encoder that double-quotes every text value and writes `Symbol` bare."""

    def __init__(self) -> None:
        super().__init__(grammar=_Grammar(), symbol_single_quote=False)
        self._blocks: dict[tuple[Any, ...], str] = {}

    def _import_quantities(self) -> None:
        """Register no astropy or pint quantity class (pvl's hook, called by its encoder).

        pvl imports ``astropy.units`` and pint, when installed, to encode their quantity
        objects. fluxcal's labels hold none (a value with units is pvl's own `Quantity`,
        which stays registered), and importing ``astropy.units`` cost 0.4 s of a
        ``edr2cdr`` run (docs/decisions/products.md, decision 51).
        """

    def encode_module(self, module: Mapping[str, Any], level: int = 0) -> str:
        """One ``KEY = value`` per line, not padded to align (stable, greppable lines)."""
        lines = [
            self.encode_aggregation_block(k, v, level) if isinstance(v, Mapping)
            else self.encode_assignment(k, v, level)
            for k, v in module.items()
        ]
        return self.newline.join(lines)

    def encode_aggregation_block(self, key: str, value: Mapping[str, Any],
                                 level: int = 0) -> str:
        """Return pvl's text of the block, remembered by content.

        Identical blocks (the COLUMN objects of every frame and day, the shared
        ATTRIBUTE objects) are encoded once.
        """
        content = _frozen(value)
        if content is None:
            return super().encode_aggregation_block(key, value, level)
        memo_key = (key, level, type(value), content)
        text = self._blocks.get(memo_key)
        if text is None:
            text = super().encode_aggregation_block(key, value, level)
            if len(self._blocks) >= _MAX_BLOCKS:
                self._blocks.clear()
            self._blocks[memo_key] = text
        return text

    def encode_string(self, value: Any) -> str:
        s = str(value)
        if isinstance(value, Symbol):
            if not self.decoder.is_identifier(s):
                raise ValueError(f"{s!r} is not an ODL symbol")
            return s
        if '"' in s or not s.isascii():
            raise ValueError(f"text {s!r} cannot be a PDS3 string (double quote or non-ASCII)")
        return '"' + s + '"'


_MAX_BLOCKS = 4096  # remembered block texts (a few MB at most)


def _frozen(value: Any) -> tuple[Any, ...] | None:
    """Return a hashable image of a label value that tells apart every encoding.

    Types are kept (a `Symbol` is not the text of the same letters, ``True`` is not
    ``1``) and floats by their ``repr`` (``-0.0`` is not ``0.0``); None for a value of
    another kind (such a block is not remembered).
    """
    if isinstance(value, Mapping):
        items = []
        for k, v in value.items():
            f = _frozen(v)
            if f is None:
                return None
            items.append((k, f))
        return (type(value), tuple(items))
    if isinstance(value, (list, tuple)):
        parts = [_frozen(v) for v in value]
        return None if any(p is None for p in parts) else (type(value), tuple(parts))
    if type(value) in (str, Symbol, int, bool):
        return (type(value), value)
    if type(value) is float:
        return (float, repr(value))
    return None


@lru_cache(maxsize=1)
def _encoder() -> _Encoder:
    """One encoder for every label (building one costs about 25 ms).

    Its only state is the text of blocks already encoded
    (`_Encoder.encode_aggregation_block`), a pure function of their content.
    """
    return _Encoder()


def render_label(module: pvl.PVLModule) -> str:
    """Render a label (keywords, objects, groups) to PDS3 ODL text with CRLF line ends.

    Raises
    ------
    InputFormatError
        A keyword that is not an ODL identifier (or longer than 30 characters), an
        empty sequence, or a text value PDS3 cannot hold.
    """
    check_unique_keys(module)
    try:
        return pvl.dumps(module, encoder=_encoder())
    except (ValueError, TypeError) as exc:
        raise InputFormatError(f"cannot write the PDS3 label: {exc}") from exc


def parse_label(text: str, path: str | None = None) -> pvl.PVLModule:
    """Parse PDS3 ODL text with pvl's PDS grammar and decoder.

    Raises
    ------
    InputFormatError
        If pvl cannot parse the text.
    """
    try:
        return pvl.loads(text, grammar=PDSGrammar(), decoder=PDSLabelDecoder())
    except Exception as exc:  # pvl raises its own lexer/parser exception types
        raise InputFormatError(f"not a PDS3 label: {exc}", path=path) from exc


def read_label(path: Path | str) -> pvl.PVLModule:
    """Parse a ``.LBL`` file (see `parse_label`)."""
    return parse_label(Path(path).read_text(encoding="ascii"), path=str(path))


def check_unique_keys(block: Mapping[str, Any], where: str = "label") -> None:
    """Raise if a keyword is assigned twice in one block (objects may repeat, e.g. COLUMN).

    Raises
    ------
    InputFormatError
        Naming the repeated keyword and the enclosing object.
    """
    seen: set[str] = set()
    for key, value in _items(block):
        if isinstance(value, Mapping):
            check_unique_keys(value, f"{where}/{key}")
            continue
        k = str(key).upper()
        if k in seen:
            raise InputFormatError(f"keyword {k} assigned twice in {where}", field=k)
        seen.add(k)


def _items(block: Mapping[str, Any]) -> Iterator[tuple[str, Any]]:
    return iter(block.items())  # pvl's multi-dicts list every (key, value), repeats included


def find_objects(block: Mapping[str, Any], name: str) -> list[Mapping[str, Any]]:
    """Return the direct child objects (or groups) of ``block`` called ``name``, in order."""
    return [v for k, v in _items(block) if k == name and isinstance(v, Mapping)]


def as_dict(block: Mapping[str, Any]) -> dict[str, Any]:
    """Keyword assignments of one block as a dict (objects skipped)."""
    return {k: v for k, v in _items(block) if not isinstance(v, Mapping)}


def text_value(s: str) -> tuple[str, bool]:
    """``(value, encoded)``: ``s`` itself when plain, else its percent-encoding."""
    return (s, False) if is_plain(s) else (percent_encode(s), True)


# --- dataset attributes as nested ATTRIBUTE objects -----------------------------------


def _scalar_plain(v: Any) -> bool:
    if isinstance(v, bool):
        return False
    if isinstance(v, int):
        return True
    if isinstance(v, float):
        return math.isfinite(v)
    return isinstance(v, str) and is_plain(v)


def _normalise(value: Any) -> Any:
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    return value


def attribute_object(name: str | None, value: Any) -> pvl.PVLObject:
    """One attribute (name optional) as an ``ATTRIBUTE`` object; containers nest."""
    obj = pvl.PVLObject()
    if name is not None:
        text, enc = text_value(str(name))
        obj["NAME"] = text
        if enc:
            obj["NAME_ENCODING"] = Symbol("PERCENT")
    value = _normalise(value)
    if value is None:
        obj["TYPE"] = Symbol("NO_VALUE")
    elif isinstance(value, bool):
        obj["TYPE"] = Symbol("BOOLEAN")
        obj["VALUE"] = Symbol("TRUE" if value else "FALSE")
    elif isinstance(value, (int, float)) and _scalar_plain(value):
        obj["VALUE"] = value
    elif isinstance(value, float):  # NaN, +-inf
        obj["TYPE"] = Symbol("REAL")
        obj["VALUE"] = repr(value)
    elif isinstance(value, str):
        text, enc = text_value(value)
        obj["VALUE"] = text
        if enc:
            obj["ENCODING"] = Symbol("PERCENT")
    elif isinstance(value, Mapping):
        obj["TYPE"] = Symbol("DICT")
        for k, v in value.items():
            obj.append(ATTRIBUTE, attribute_object(str(k), v))
    elif isinstance(value, (list, tuple)):
        items = [_normalise(v) for v in value]
        if items and all(_scalar_plain(v) for v in items):
            obj["VALUE"] = items
        else:
            obj["TYPE"] = Symbol("LIST")
            for v in items:
                obj.append(ATTRIBUTE, attribute_object(None, v))
    else:  # e.g. a datetime: kept as its text (as JSON encoding did)
        return attribute_object(name, str(value))
    return obj


def attributes_object(attrs: Mapping[str, Any]) -> pvl.PVLObject:
    """Every attribute of ``attrs`` as a child ``ATTRIBUTE`` object, in order."""
    obj = pvl.PVLObject()
    for k, v in attrs.items():
        obj.append(ATTRIBUTE, attribute_object(str(k), v))
    return obj


def decode_attribute(obj: Mapping[str, Any]) -> tuple[str | None, Any]:
    """Inverse of `attribute_object`: ``(name, value)``."""
    name = obj.get("NAME")
    if name is not None:
        name = str(name)
        if obj.get("NAME_ENCODING") == "PERCENT":
            name = unquote(name)
    kind = obj.get("TYPE")
    children = find_objects(obj, ATTRIBUTE)
    if kind == "NO_VALUE":
        return name, None
    if kind == "BOOLEAN":
        return name, obj["VALUE"] in (True, "TRUE")
    if kind == "REAL":
        return name, float(obj["VALUE"])
    if kind == "DICT":
        return name, {n: v for n, v in map(decode_attribute, children)}
    if kind == "LIST":
        return name, [v for _, v in map(decode_attribute, children)]
    value = obj["VALUE"]
    if obj.get("ENCODING") == "PERCENT":
        value = unquote(str(value))
    return name, value


def decode_attributes(obj: Mapping[str, Any]) -> dict[str, Any]:
    """Inverse of `attributes_object`."""
    return {str(n): v for n, v in map(decode_attribute, find_objects(obj, ATTRIBUTE))}
