r"""A small PDS3-like ODL (Object Description Language) writer and parser.

Statements are ``KEY = value`` and ``OBJECT = NAME`` ... ``END_OBJECT = NAME`` blocks,
closed by ``END``.  Values: quoted strings (``\\`` and ``"`` escaped with a
backslash), integers, reals, bare symbols (``ASCII_REAL``), and sequences
``(v1, v2, ...)``.  Dicts and nested containers are written as quoted strings with
the ``json:`` prefix of `fluxcal.products.attrs`.  `parse_label` reverses
`render_label` exactly for those value types.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from typing import Any

from fluxcal.errors import InputFormatError
from fluxcal.products.attrs import encode_value

Statement = tuple[str, Any]  # (key, value) or ("OBJECT", (name, [statements]))

_KEY = re.compile(r"^[A-Za-z_^][A-Za-z0-9_:.\-]*$")


class Symbol(str):
    """A bare (unquoted) ODL symbol such as ``ASCII_REAL`` or ``PDS3``."""


def _quote(s: str) -> str:
    return '"' + s.replace("\\", "\\\\").replace('"', '\\"') + '"'


def _render_value(value: Any) -> str:
    if isinstance(value, Symbol):
        return str(value)
    if isinstance(value, (list, tuple)) and value and all(
        isinstance(v, (str, int, float)) and not isinstance(v, bool) for v in value
    ):
        return "(" + ", ".join(_render_value(v) for v in value) + ")"
    v = encode_value(value)
    if isinstance(v, str):
        return _quote(v)
    return repr(v)


def render_label(statements: Sequence[Statement], indent: int = 0) -> str:
    """Render ODL statements to text with CRLF line ends (``END`` added at top level)."""
    pad = "  " * indent
    lines: list[str] = []
    for key, value in statements:
        if key == "OBJECT":
            name, body = value
            lines.append(f"{pad}OBJECT = {name}")
            lines.append(render_label(body, indent + 1).rstrip("\r\n"))
            lines.append(f"{pad}END_OBJECT = {name}")
        else:
            if not _KEY.match(key):
                raise InputFormatError(f"label keyword {key!r} is not a valid ODL name",
                                       field=key)
            lines.append(f"{pad}{key} = {_render_value(value)}")
    if indent == 0:
        lines.append("END")
    return "\r\n".join(line for line in lines if line) + "\r\n"


_TOKEN = re.compile(
    r'\s*(?:(?P<comment>/\*.*?\*/)|(?P<str>"(?:[^"\\]|\\.)*")|(?P<punct>[=(),])'
    r'|(?P<bare>[^\s=(),"]+))',
    re.S,
)


def _tokens(text: str) -> list[tuple[str, str]]:
    out = []
    pos = 0
    text = text.rstrip()
    while pos < len(text):
        m = _TOKEN.match(text, pos)
        if m is None:
            raise InputFormatError(f"cannot parse label near {text[pos:pos + 30]!r}")
        pos = m.end()
        kind = m.lastgroup
        if kind == "comment":
            continue
        out.append((kind, m.group(kind)))
    return out


def _bare(tok: str) -> Any:
    for conv in (int, float):
        try:
            return conv(tok)
        except ValueError:
            pass
    return Symbol(tok)


def _unquote(tok: str) -> str:
    return re.sub(r"\\(.)", r"\1", tok[1:-1], flags=re.S)


def parse_label(text: str) -> list[Statement]:
    """Parse ODL text into statements (objects nested as ``("OBJECT", (name, body))``)."""
    toks = _tokens(text)
    i = 0

    def value() -> Any:
        nonlocal i
        kind, tok = toks[i]
        i += 1
        if kind == "str":
            return _unquote(tok)
        if tok == "(":
            items = []
            while toks[i][1] != ")":
                if toks[i][1] == ",":
                    i += 1
                    continue
                items.append(value())
            i += 1
            return items
        return _bare(tok)

    def block(end: str | None) -> list[Statement]:
        nonlocal i
        body: list[Statement] = []
        while i < len(toks):
            kind, key = toks[i]
            if key == "END" and end is None:
                i += 1
                return body
            if i + 2 > len(toks) or toks[i + 1][1] != "=":
                raise InputFormatError(f"label: expected '=' after {key!r}", field=key)
            i += 2
            if key == "OBJECT":
                name = toks[i][1]
                i += 1
                body.append(("OBJECT", (name, block(name))))
            elif key == "END_OBJECT":
                name = toks[i][1]
                i += 1
                if name != end:
                    raise InputFormatError(f"label: END_OBJECT = {name} closes {end}",
                                           field=name)
                return body
            else:
                body.append((key, value()))
        if end is not None:
            raise InputFormatError(f"label: OBJECT {end} not closed", field=end)
        return body

    return block(None)


def find_objects(statements: Sequence[Statement], name: str) -> list[list[Statement]]:
    """Bodies of the direct child objects called ``name``."""
    return [v[1] for k, v in statements if k == "OBJECT" and v[0] == name]


def as_dict(statements: Sequence[Statement]) -> dict[str, Any]:
    """Keyword statements of one level as a dict (objects skipped)."""
    return {k: v for k, v in statements if k != "OBJECT"}
