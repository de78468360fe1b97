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
``--<field-name>``; the first is the one messages name, the others are aliases),
``parse`` (callable applied to the command-line value, e.g. "<= 0 disables"),
``choices`` (allowed values; each element of a tuple field is checked), ``empty_ok``
(False: a tuple field needs at least one value), ``check`` (callable taking the final
value and returning what is wrong with it as text, or None).

Every value is checked where the option is declared, whichever way it comes (command
line, ``--config`` file, or the dataclass built directly by the Python API): the
dataclass's ``__post_init__`` calls `check_fields`, so all three refuse the same values
with the same message (`InputFormatError` naming the first flag).  Beyond a field's own
``check``, every number must be finite (``nan``/``inf`` never switch a check off), a
whole-number field takes whole numbers only, and a name field takes names only.

Every such command also takes ``--config FILE.toml`` (`read_config`): a run-configuration
file whose keys are the fields (``max_offset_step``) or their long options
(``max-offset-step``, ``average``); its values are merged *under* the command line (an
option given on the command line wins) and go through the same checks.  An unknown key,
a value of the wrong type or an unreadable file is one error naming the file, the key and
its line (exit 2), before anything is read or written (docs/guide/run_config.md).
"""

from __future__ import annotations

import dataclasses
import functools
import inspect
import math
import numbers
import re
import tomllib
import types
import typing
from collections.abc import Callable, Sequence
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


#: Longest averaging interval (s) an option may ask for: one day, the span of a daily
#: product (an average over more than the product holds has no sample).
MAX_AVERAGE_S = 86_400


def _whole(value: Any) -> bool:
    return isinstance(value, numbers.Integral) and not isinstance(value, bool)


def _problem(f: dataclasses.Field, kind: str, optional: bool, value: Any) -> str | None:
    """Return what is wrong with a field's final value (type, finite, choices, empty), else None."""
    if value is None:
        return None if optional or kind in ("path", "str") else "a value is required"
    if kind == "float" and not (isinstance(value, numbers.Real)
                                and not isinstance(value, bool)):
        return f"{value!r}: expected a number"
    if kind == "float" and not math.isfinite(value):
        return f"{value}: expected a finite number"
    if kind == "int" and not _whole(value):
        return f"{value!r}: expected a whole number"
    if kind == "bool" and not isinstance(value, bool):
        return f"{value!r}: expected true or false"
    if kind in ("strs", "ints") and not isinstance(value, tuple):
        return f"{value!r}: expected a list of {'names' if kind == 'strs' else 'numbers'}"
    if kind == "ints" and not all(_whole(v) for v in value):
        return f"{_shown(value)}: expected whole numbers"
    if kind in ("strs", "str"):
        values = tuple(value) if kind == "strs" else (value,)
        if not all(isinstance(v, str) for v in values):
            return f"{_shown(value)}: expected names"
        choices = f.metadata.get("choices")
        if choices is not None:
            canonical = {str(c).lower() for c in choices}
            bad = [v for v in values if v.lower() not in canonical]
            if bad:
                return (f"unknown value{'s' if len(bad) > 1 else ''} {', '.join(bad)}; "
                        f"choose from {','.join(map(str, choices))}")
            if kind == "strs" and not values and not f.metadata.get("empty_ok", True):
                return f"give at least one of {','.join(map(str, choices))}"
    check = f.metadata.get("check")
    return check(value) if check is not None else None


def _shown(value: Any) -> str:
    """Return a value as a user writes it: a list comma-separated, not a Python repr."""
    if isinstance(value, (tuple, list)):
        return ",".join(map(str, value)) or "''"
    return str(value)


def _normal(kind: str, value: Any) -> Any:
    """Return a value of the API in the form the command line gives (list -> tuple, str -> Path)."""
    if kind in ("strs", "ints") and isinstance(value, (list, tuple)):
        return tuple(int(v) if kind == "ints" and _whole(v) else v for v in value)
    if kind == "strs" and isinstance(value, str):  # one name, not its letters
        return tuple(v.strip() for v in value.split(",") if v.strip())
    if kind == "path" and isinstance(value, str):
        return Path(value)
    if kind == "float" and _whole(value):
        return float(value)
    return value


def check_fields(options: Any) -> None:
    """Check every field of a run-options dataclass instance (its ``__post_init__``).

    Normalises what the Python API may pass (a list for a tuple, a str for a path), then
    checks each value as the command line does (`_problem`).

    Raises
    ------
    InputFormatError
        Naming the field's first flag and the value: a number that is not finite, a
        value of the wrong type, an unknown choice, an empty list where one is needed,
        or what the field's ``check`` refuses.
    """
    hints = typing.get_type_hints(type(options))
    for f in dataclasses.fields(options):
        kind, optional = _kind(hints[f.name])
        value = _normal(kind, getattr(options, f.name))
        problem = _problem(f, kind, optional, value)
        if problem is not None:
            raise InputFormatError(problem, field=flags(f)[0])
        object.__setattr__(options, f.name, _canonical(f, kind, value))  # frozen: normal form


def _canonical(f: dataclasses.Field, kind: str, value: Any) -> Any:
    """Return a checked name (or names) as its choice is spelled ('CDF' -> 'cdf')."""
    choices = f.metadata.get("choices")
    if choices is None or value is None or kind not in ("strs", "str"):
        return value
    canonical = {str(c).lower(): c for c in choices}
    return (tuple(canonical[v.lower()] for v in value) if kind == "strs"
            else canonical[value.lower()])


def _parse_one(f: dataclasses.Field, kind: str, optional: bool, value: Any) -> Any:
    flag = flags(f)[0]
    if kind in ("strs", "ints"):
        items = [v.strip() for v in str(value).split(",") if v.strip()]
        if kind == "ints":
            try:
                items = [int(v) for v in items]
            except ValueError:
                raise InputFormatError(f"{value}: expected whole numbers separated by "
                                       "commas", field=flag) from None
        value = None if optional and not items else tuple(items)
    elif kind == "str":
        value = str(value).strip()
        if optional and not value:
            value = None
    elif kind == "float" and value is not None and not math.isfinite(value):
        # before ``parse``: "<= 0 disables" must not turn nan or -inf into "off"
        raise InputFormatError(f"{value}: expected a finite number", field=flag)
    problem = _problem(f, kind, optional, value) if kind in ("strs", "str") else None
    if problem is not None:
        raise InputFormatError(problem, field=flag)
    value = _canonical(f, kind, value)
    parse = f.metadata.get("parse")
    value = parse(value) if parse is not None else value
    problem = _problem(f, kind, optional, value)
    if problem is not None:
        raise InputFormatError(problem, field=flag)
    return value


def from_command_line(cls: type[T], values: dict[str, Any],
                      preset: dict[str, Any] | None = None) -> T:
    """Build ``cls`` from the command-line values of its fields (missing ones: defaults).

    ``preset`` holds values already parsed (a run-configuration file's, `read_config`)
    for the fields not in ``values``.

    Raises
    ------
    InputFormatError
        If a value does not parse or is not one of the field's choices (names the flag).
    """
    hints = typing.get_type_hints(cls)
    kwargs = dict(preset or {})
    for f in dataclasses.fields(cls):
        if f.name in values:
            kind, optional = _kind(hints[f.name])
            kwargs[f.name] = _parse_one(f, kind, optional, values[f.name])
    return cls(**kwargs)


#: The option naming a run-configuration file (every command made by `with_options`).
CONFIG_FLAG = "--config"
#: What each field kind takes in a run-configuration file (for the error message).
_TOML_TYPES = {"strs": "an array of strings", "ints": "an array of whole numbers",
               "bool": "true or false", "int": "a whole number", "float": "a number",
               "path": "a path string", "str": "a string"}


def config_keys(cls: type) -> dict[str, dataclasses.Field]:
    """Map every key a run-configuration file may use for ``cls`` to its field.

    A field is named by its name (``max_offset_step``) or by any of its long options
    without the dashes (``max-offset-step``, ``average`` for ``averages``); ``-`` and
    ``_`` are the same.
    """
    keys: dict[str, dataclasses.Field] = {}
    for f in dataclasses.fields(cls):
        for name in (f.name, *(n.lstrip("-") for n in flags(f) if n.startswith("--"))):
            keys[name.replace("-", "_")] = f
    return keys


def _key_line(text: str, key: str) -> int | None:
    """1-based line of ``key = ...`` (or of a table ``[key]``) in a TOML text, else None."""
    pattern = re.compile(r"^\s*\[?\s*[\"']?" + re.escape(key) + r"[\"']?\s*(=|\])")
    for number, line in enumerate(text.splitlines(), start=1):
        if pattern.match(line):
            return number
    return None


def _toml_value(kind: str, value: Any, folder: Path) -> Any:
    """Return a TOML value as a command-line value of ``kind`` (None: wrong type)."""
    def whole(v: Any) -> bool:
        return isinstance(v, int) and not isinstance(v, bool)

    if kind == "strs":
        if isinstance(value, str):
            return value
        if isinstance(value, list) and all(isinstance(v, str) for v in value):
            return ",".join(value)
    elif kind == "ints":
        if whole(value):
            return str(value)
        if isinstance(value, list) and all(whole(v) for v in value):
            return ",".join(str(v) for v in value)
    elif kind == "bool":
        if isinstance(value, bool):
            return value
    elif kind == "int":
        if whole(value):
            return value
    elif kind == "float":
        if whole(value) or isinstance(value, float):
            return float(value)
    elif kind == "path":
        if isinstance(value, str) and value.strip():
            path = Path(value).expanduser()
            return path if path.is_absolute() else folder / path
    elif isinstance(value, str):
        return value
    return None


def _load_toml(path: Path) -> tuple[str, dict[str, Any]]:
    """Return the text and the table of a run-configuration file.

    Raises
    ------
    InputFormatError
        Naming the file (and the line): unreadable, not UTF-8, or not TOML.
    """
    try:
        text = path.read_bytes().decode("utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        what = exc.strerror if isinstance(exc, OSError) and exc.strerror else (
            "not UTF-8 text" if isinstance(exc, UnicodeDecodeError) else str(exc))
        raise InputFormatError(f"cannot read the run-configuration file: {what} (give a "
                               "TOML file, docs/guide/run_config.md)",
                               path=str(path), field=CONFIG_FLAG) from None
    try:
        return text, tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        where = re.search(r"\(at line (\d+), column \d+\)", str(exc))
        line = int(where.group(1)) if where else None
        message = re.sub(r"\s*\(at (line .*|end of document)\)$", "", str(exc))
        raise InputFormatError(f"not valid TOML: {message}", path=str(path),
                               line=line) from None


def read_config(path: Path, cls: type) -> dict[str, Any]:
    r"""Read a run-configuration file (TOML) for the options dataclass ``cls``.

    Keys are the fields of ``cls`` or their long options (`config_keys`); values are
    TOML values of the field's kind (an array of strings or a comma-separated string
    for a list of names, an array of whole numbers, a number, true/false, a string); a
    relative path is relative to the file's folder.  Each value goes through the same
    checks as on the command line.

    Parameters
    ----------
    path : Path
        The ``--config`` file.
    cls : type
        The command's run-options dataclass.

    Returns
    -------
    dict
        Field name -> parsed value, for the fields the file sets.

    Raises
    ------
    InputFormatError
        Naming the file (and the key and its line): the file cannot be read or is not
        TOML, a key is not an option of the command, a key is given twice (as field and
        as option name), or a value has the wrong type or does not pass the option's
        checks.

    Examples
    --------
    >>> import tempfile
    >>> from dataclasses import dataclass, field
    >>> @dataclass(frozen=True)
    ... class Opts:
    ...     frames: tuple[str, ...] = field(default=("mso",), metadata={"help": "Frames."})
    ...     max_step: float = field(default=2.0, metadata={"help": "Threshold."})
    >>> folder = Path(tempfile.mkdtemp())
    >>> _ = (folder / "run.toml").write_text('frames = ["mso", "rtn"]\nmax-step = 3\n')
    >>> read_config(folder / "run.toml", Opts)
    {'frames': ('mso', 'rtn'), 'max_step': 3.0}
    """
    path = Path(path)
    text, table = _load_toml(path)
    keys = config_keys(cls)
    hints = typing.get_type_hints(cls)
    parsed: dict[str, Any] = {}
    seen: dict[str, str] = {}
    for key, value in table.items():
        line = _key_line(text, key)
        f = keys.get(key.replace("-", "_"))
        if f is None:
            known = sorted({f.name for f in dataclasses.fields(cls)})
            raise InputFormatError(f"unknown key; this command's run options are "
                                   f"{', '.join(known)} (other options go on the command "
                                   "line)", path=str(path), line=line, field=key)
        if f.name in seen:
            raise InputFormatError(f"sets {f.name} again (also as {seen[f.name]!r})",
                                   path=str(path), line=line, field=key)
        seen[f.name] = key
        kind, optional = _kind(hints[f.name])
        cli_value = _toml_value(kind, value, path.parent)
        if cli_value is None:
            raise InputFormatError(f"{value!r} ({type(value).__name__}): expected "
                                   f"{_TOML_TYPES[kind]}", path=str(path), line=line,
                                   field=key)
        try:
            parsed[f.name] = _parse_one(f, kind, optional, cli_value)
        except InputFormatError as exc:
            reason = str(exc).split(": ", 1)[-1]
            raise InputFormatError(reason, path=str(path), line=line, field=key) from None
    return parsed


#: Name of the click context parameter `with_options` adds (the options' sources).
_CONTEXT = "fluxcal_run_context"


def _config_parameters() -> list[inspect.Parameter]:
    """Return the ``--config`` option and the context parameter of every options command."""
    config = typer.Option(None, CONFIG_FLAG, help="Run-configuration file (TOML): run "
                          "options by name, merged under the command line "
                          "(docs/guide/run_config.md).")
    return [inspect.Parameter("config", inspect.Parameter.KEYWORD_ONLY, default=config,
                              annotation=Path | None),
            inspect.Parameter(_CONTEXT, inspect.Parameter.KEYWORD_ONLY,
                              annotation=typer.Context)]


def _given(context: Any, name: str) -> bool:
    """Whether option ``name`` was given on the command line (not left at its default)."""
    if context is None:
        return True
    source = context.get_parameter_source(name)
    return source is not None and source.name not in ("DEFAULT", "DEFAULT_MAP")


def with_options(cls: type, name: str = "options",
                 report: bool = True) -> Callable[[Callable], Callable]:
    """Give a command every field of ``cls`` as a command-line option, and ``--config``.

    The decorated function takes ``<name>: cls``; the returned command takes the fields
    as typer options instead, builds ``cls`` with `from_command_line` and passes it on.
    ``--config FILE`` adds the file's values (`read_config`) for the options not given
    on the command line.  With ``report``, a command run from the command line with an
    ``out`` folder ends by writing the run's HTML report there, staged with the run's
    products (`fluxcal.products.html_report.write_run_report`).

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
            context = kwargs.pop(_CONTEXT, None)
            config = kwargs.pop("config", None)
            values = {k: kwargs.pop(k) for k in list(kwargs) if k in field_names}
            preset = {}
            if config is not None:  # the file's values under the command line's
                preset = read_config(Path(config), cls)
                values = {k: v for k, v in values.items()
                          if k not in preset or _given(context, k)}
            kwargs[name] = from_command_line(cls, values, preset)
            result = func(*args, **kwargs)
            if report and context is not None and kwargs.get("out") is not None:
                # numpy/xarray: not loaded by ``fluxcal --help`` (test_cli_startup)
                from fluxcal.products.html_report import write_run_report

                write_run_report(Path(kwargs["out"]))
            return result

        hints = typing.get_type_hints(func)
        extra += _config_parameters()
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


def _names_paths(hint: Any) -> bool:
    """Whether a type hint is a path (``Path``, ``Path | None``, ``list[Path]``)."""
    return hint is Path or any(_names_paths(a) for a in typing.get_args(hint))


def _command_config(ctx: Any, path: Path, exclude: Sequence[str],
                    paths: set[str]) -> dict[str, Any]:
    """Return a run-configuration file as click defaults of ``ctx.command``'s options.

    Keys are the options' names or long options without dashes (``-`` = ``_``), as for
    `read_config`; the options in ``exclude`` (inputs, ``--out``) stay on the command
    line.  Each value goes through the option's own conversion and checks; a relative
    path (an option named in ``paths``) is relative to the file's folder.

    Raises
    ------
    InputFormatError
        Naming the file, the key and its line: an unknown key, or a value the option
        does not take.
    """
    text, table = _load_toml(path)
    params = {}
    for param in ctx.command.params:
        if getattr(param, "param_type_name", "") != "option" or \
                param.name in (*exclude, "config"):
            continue
        for name in (param.name, *(o.lstrip("-") for o in param.opts if o.startswith("--"))):
            params[name.replace("-", "_")] = param
    defaults: dict[str, Any] = {}
    for key, value in table.items():
        line = _key_line(text, key)
        param = params.get(key.replace("-", "_"))
        if param is None:
            known = ", ".join(sorted({p.opts[0].lstrip("-") for p in params.values()}))
            raise InputFormatError(f"unknown key; this command's run options are {known} "
                                   "(inputs and --out go on the command line)",
                                   path=str(path), line=line, field=key)
        if param.name in defaults:
            raise InputFormatError(f"sets {param.opts[0]} again", path=str(path), line=line,
                                   field=key)
        items = value if param.multiple and isinstance(value, list) else (
            [value] if param.multiple else None)
        if param.name in paths:  # relative to the file's folder
            def near(v: Any) -> Any:
                return str(path.parent / v) if isinstance(v, str) and v and \
                    not Path(v).expanduser().is_absolute() else v
            items = None if items is None else [near(v) for v in items]
            value = near(value)
        if isinstance(value, (dict, list)) and items is None:
            raise InputFormatError(f"{value!r} ({type(value).__name__}): expected one value",
                                   path=str(path), line=line, field=key)
        try:
            defaults[param.name] = param.process_value(ctx, items if items is not None
                                                       else value)
        except typer.BadParameter as exc:
            raise InputFormatError(exc.format_message(), path=str(path), line=line,
                                   field=key) from None
    return defaults


def with_config(exclude: Sequence[str] = ("out",)) -> Callable[[Callable], Callable]:
    """Give a command of plain typer options ``--config FILE.toml`` (`read_config`'s rules).

    For commands without a run-options dataclass (``fit``, ``clean``): the file's values
    become the defaults of the command's options (click's ``default_map``), so an option
    given on the command line wins; the options named in ``exclude`` (parameter names:
    the inputs and ``out``) are not keys.  Errors name the file, the key and its line
    (exit 2) before the command runs (`_command_config`).
    """
    def decorate(func: Callable) -> Callable:
        signature = inspect.signature(func)
        hints = typing.get_type_hints(func)
        paths = {name for name, hint in hints.items() if _names_paths(hint)}

        def load(ctx: typer.Context, param: typer.CallbackParam, value: Any) -> Any:
            if value is not None:
                ctx.default_map = {**(ctx.default_map or {}),
                                   **_command_config(ctx, Path(value), exclude, paths)}
            return value

        option = typer.Option(None, CONFIG_FLAG, is_eager=True, callback=load,
                              help="Run-configuration file (TOML): options by name, "
                                   "merged under the command line (docs/guide/"
                                   "run_config.md).")

        @functools.wraps(func)
        def command(*args: Any, **kwargs: Any) -> Any:
            kwargs.pop("config", None)
            return func(*args, **kwargs)

        params = [p.replace(annotation=hints.get(p.name, p.annotation))
                  for p in signature.parameters.values()]
        params.append(inspect.Parameter("config", inspect.Parameter.KEYWORD_ONLY,
                                        default=option, annotation=Path | None))
        command.__signature__ = signature.replace(  # type: ignore[attr-defined]
            parameters=params)
        command.__annotations__ = {**hints, "config": Path | None}
        del command.__wrapped__  # typer must see the new signature
        return command

    return decorate

