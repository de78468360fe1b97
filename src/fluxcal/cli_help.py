"""Help pages of the ``fluxcal`` command groups (never cut, issue 25) and their displays.

Imported by every module that builds a command group (`fluxcal.cli` and the missions'
``cli`` modules), so it imports nothing of fluxcal's (rich and numba only inside the
displays).  `quiet_requested` and `progress_wanted` read ``fluxcal -q`` from the command
line being run (the displays of a running command: `fluxcal.runs.display_cli`).
"""

from __future__ import annotations

import inspect
import sys
from contextvars import ContextVar
from typing import Any

from typer.core import TyperGroup

#: Help is wrapped to the terminal, up to this many columns (click's default: 80).
HELP_WIDTH = 120


#: ``fluxcal -q/--quiet`` of the command being run: set by the root callback, given back
#: by `fluxcal.cli.main` when the command ends (outside a command it is False).
QUIET: ContextVar[bool] = ContextVar("fluxcal_quiet", default=False)


def quiet_requested() -> bool:
    """Return whether the running command was started as ``fluxcal -q/--quiet``."""
    return QUIET.get()


def progress_wanted() -> bool:
    """Return whether a command may show a progress display (a bar, a spinner) on stderr.

    False under ``fluxcal -q/--quiet`` and when stderr is not a terminal (logs, pipes).
    """
    return not quiet_requested() and sys.stderr.isatty()


def command_summary(cmd: Any) -> str:
    """Return a command's summary for its group's list: the whole first paragraph.

    Click's list keeps the first sentence and cuts it with ``...`` at the terminal's
    width (and takes ``sec. 4.2`` for a sentence end); here the first paragraph of the
    help (or ``short_help`` when given) is kept whole and the list wraps it.

    Parameters
    ----------
    cmd : click.Command
        A command or group of the ``fluxcal`` tree.

    Returns
    -------
    str
        The summary on one line (the help formatter wraps it).
    """
    text = cmd.short_help or cmd.help or ""
    first = inspect.cleandoc(text).split("\n\n")[0]
    return " ".join(first.replace("\b", "").split())


#: Old option names kept working but not shown in help: every command names its main input
#: ``--input`` (was ``--sci`` for MESSENGER, ``--science`` for Rosetta), and a product's
#: version is ``--product-version`` (``--version`` is fluxcal's own, ``fluxcal --version``).
HIDDEN_ALIASES = ("--sci", "--science", "--version")


def hide_aliases(command: Any) -> Any:
    """Leave `HIDDEN_ALIASES` out of ``command``'s help where an option has another name.

    The names still parse (click's parser is built from every name); only the help
    record of such an option lists the other names.
    """
    for param in getattr(command, "params", ()):
        opts = list(getattr(param, "opts", ()))
        if not any(o in HIDDEN_ALIASES for o in opts) or all(o in HIDDEN_ALIASES for o in opts):
            continue
        if getattr(param, "_fluxcal_aliases_hidden", False):
            continue
        shown = [o for o in opts if o not in HIDDEN_ALIASES]
        for method in ("get_help_record", "get_error_hint"):  # help, and "Missing option"
            if hasattr(param, method):
                setattr(param, method, _with_opts(param, shown, getattr(param, method)))
        param._fluxcal_aliases_hidden = True
    return command


def _with_opts(param: Any, shown: list[str], original: Any) -> Any:
    """Return ``original`` (a bound method of ``param``) run with only ``shown`` names."""
    def call(*args: Any, **kwargs: Any) -> Any:
        saved = param.opts
        param.opts = shown
        try:
            return original(*args, **kwargs)
        finally:
            param.opts = saved

    return call


class HelpGroup(TyperGroup):
    """A command group whose list of commands wraps each summary instead of cutting it.

    Its commands' help leaves out the old option names (`hide_aliases`).
    """

    def get_command(self, ctx: Any, cmd_name: str) -> Any:
        """Return the command, its old option names left out of its help."""
        return hide_aliases(super().get_command(ctx, cmd_name))

    def format_commands(self, ctx: Any, formatter: Any) -> None:
        """Write the ``Commands:`` section: name and whole first paragraph of each."""
        rows = []
        for name in self.list_commands(ctx):
            cmd = self.get_command(ctx, name)
            if cmd is not None and not cmd.hidden:
                rows.append((name, command_summary(cmd)))
        if rows:
            with formatter.section("Commands"):
                formatter.write_dl(rows)
