"""A mission's run options as one dataclass, and the command-line options made from it.

A mission declares its run options once, as a frozen dataclass whose fields carry their
help text (``field(metadata={"help": ...})``).  `with_options` turns a command
function that takes ``options: <that dataclass>`` into one that takes every field as a
command-line option, so a single-run command and ``fluxcal batch <mission>`` offer the
same options with the same defaults, parsing and checks.

Field types and their command-line form:

=============================  ========================================================
field type                     command line
=============================  ========================================================
``tuple[str, ...]``            ``--frames mso,rtn`` (comma-separated; ``''`` for none)
``tuple[int, ...]``            ``--average 1,5,10`` (whole numbers, comma-separated)
``bool``                       ``--quicklook`` (a flag)
``Path | None``                ``--calib DIR``
``str``, ``int``, ``float``    one value (``| None``: empty or absent means None)
=============================  ========================================================

Metadata keys: ``help`` (required), ``flags`` (tuple of option names, default
``--<field-name>``), ``parse`` (callable applied to the parsed value, e.g. "<= 0
disables"), ``choices`` (allowed values; each element of a tuple field is checked).
"""

from __future__ import annotations

import dataclasses
import functools
import inspect
import types
import typing
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

import typer

from fluxcal.errors import InputFormatError

T = TypeVar("T")


def flags(f: dataclasses.Field) -> tuple[str, ...]:
    """Command-line names of a field (``metadata["flags"]`` or ``--field-name``)."""
    return tuple(f.metadata.get("flags", ("--" + f.name.replace("_", "-"),)))


def _kind(hint: Any) -> tuple[str, bool]:
    """Return (kind, optional) of a field's type hint."""
    optional = False
    origin = typing.get_origin(hint)
    if origin in (typing.Union, types.UnionType):
        args = [a for a in typing.get_args(hint) if a is not type(None)]
        optional = len(args) < len(typing.get_args(hint))
        hint = args[0]
        origin = typing.get_origin(hint)
    if origin is tuple:
        (element, *_rest) = typing.get_args(hint)
        return ("ints" if element is int else "strs"), optional
    return {bool: "bool", int: "int", float: "float", Path: "path"}.get(hint, "str"), optional


def _default(f: dataclasses.Field) -> Any:
    if f.default is not dataclasses.MISSING:
        return f.default
    if f.default_factory is not dataclasses.MISSING:
        return f.default_factory()
    raise TypeError(f"run option {f.name} needs a default")


def _cli_default(value: Any, kind: str) -> Any:
    if kind in ("strs", "ints"):
        return "" if value is None else ",".join(str(v) for v in value)
    if kind == "str" and value is None:
        return ""
    return value


def _annotation(kind: str, optional: bool, default: Any) -> Any:
    base = {"strs": str, "ints": str, "bool": bool, "int": int, "float": float,
            "path": Path, "str": str}[kind]
    if kind in ("path", "int", "float") and (optional or default is None):
        return base | None
    return base


def parameters(cls: type) -> list[inspect.Parameter]:
    """Return the keyword-only command parameters (typer options) of ``cls``'s fields."""
    hints = typing.get_type_hints(cls)
    params = []
    for f in dataclasses.fields(cls):
        kind, optional = _kind(hints[f.name])
        default = _default(f)
        names = flags(f)
        help_text = f.metadata.get("help", "")
        option = typer.Option(_cli_default(default, kind), *names, help=help_text)
        params.append(inspect.Parameter(f.name, inspect.Parameter.KEYWORD_ONLY, default=option,
                                        annotation=_annotation(kind, optional, default)))
    return params


def _parse_one(f: dataclasses.Field, kind: str, optional: bool, value: Any) -> Any:
    flag = flags(f)[0]
    if kind in ("strs", "ints"):
        items = [v.strip() for v in str(value).split(",") if v.strip()]
        if kind == "ints":
            try:
                items = [int(v) for v in items]
            except ValueError:
                raise InputFormatError(f"{value!r}: expected whole numbers separated by "
                                       "commas", field=flag) from None
        value = None if optional and not items else tuple(items)
        values = value or ()
    elif kind == "str":
        value = str(value).strip()
        if optional and not value:
            value = None
        values = () if value is None else (value,)
    else:
        values = (value,)
    choices = f.metadata.get("choices")
    if choices is not None:  # canonical lower-case names; 'CDF' means 'cdf'
        canonical = {str(c).lower(): c for c in choices}
        bad = [v for v in values if str(v).lower() not in canonical]
        if bad or (kind == "strs" and not values and not f.metadata.get("empty_ok", True)):
            raise InputFormatError(f"{value!r}: unknown value(s) {bad}; choose from "
                                   f"{','.join(map(str, choices))}", field=flag)
        if kind == "strs":
            value = tuple(canonical[str(v).lower()] for v in value)
        elif value is not None:
            value = canonical[str(value).lower()]
    parse = f.metadata.get("parse")
    return parse(value) if parse is not None else value


def from_command_line(cls: type[T], values: dict[str, Any]) -> T:
    """Build ``cls`` from the command-line values of its fields (missing ones: defaults).

    Raises
    ------
    InputFormatError
        If a value does not parse or is not one of the field's choices (names the flag).
    """
    hints = typing.get_type_hints(cls)
    kwargs = {}
    for f in dataclasses.fields(cls):
        if f.name in values:
            kind, optional = _kind(hints[f.name])
            kwargs[f.name] = _parse_one(f, kind, optional, values[f.name])
    return cls(**kwargs)


def with_options(cls: type, name: str = "options") -> Callable[[Callable], Callable]:
    """Give a command every field of ``cls`` as a command-line option.

    The decorated function takes ``<name>: cls``; the returned command takes the fields
    as typer options instead, builds ``cls`` with `from_command_line` and passes it on.

    Examples
    --------
    >>> from dataclasses import dataclass, field
    >>> @dataclass(frozen=True)
    ... class Opts:
    ...     frames: tuple[str, ...] = field(default=("mso",), metadata={"help": "Frames."})
    >>> @with_options(Opts)
    ... def run(out: str, options: Opts) -> Opts:
    ...     return options
    >>> run(out="x", frames="mso,rtn")
    Opts(frames=('mso', 'rtn'))
    """
    def decorate(func: Callable) -> Callable:
        signature = inspect.signature(func)
        own = [p for p in signature.parameters.values() if p.name != name]
        extra = parameters(cls)
        field_names = {p.name for p in extra}

        @functools.wraps(func)
        def command(*args: Any, **kwargs: Any) -> Any:
            values = {k: kwargs.pop(k) for k in list(kwargs) if k in field_names}
            kwargs[name] = from_command_line(cls, values)
            return func(*args, **kwargs)

        hints = typing.get_type_hints(func)
        command.__signature__ = signature.replace(  # type: ignore[attr-defined]
            parameters=[p.replace(annotation=hints.get(p.name, p.annotation)) for p in own]
            + extra)
        command.__annotations__ = {**{k: v for k, v in hints.items() if k != name},
                                   **{p.name: p.annotation for p in extra}}
        del command.__wrapped__  # typer must see the new signature, not the function's
        return command

    return decorate


def as_keywords(options: Any) -> dict[str, Any]:
    """Return a run-options dataclass as keyword arguments (field name -> value)."""
    return {f.name: getattr(options, f.name) for f in dataclasses.fields(options)}
