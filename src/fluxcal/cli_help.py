"""Help pages of the ``fluxcal`` command groups: never cut (issue 25).

Imported by every module that builds a command group (`fluxcal.cli` and the missions'
``cli`` modules), so it imports nothing of fluxcal's.
"""

from __future__ import annotations

import inspect
from typing import Any

from typer.core import TyperGroup


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


class HelpGroup(TyperGroup):
    """A command group whose list of commands wraps each summary instead of cutting it."""

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
