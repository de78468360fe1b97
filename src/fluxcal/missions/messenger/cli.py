"""``fluxcal messenger edr2cdr`` and ``fluxcal simulate messenger`` commands."""

from __future__ import annotations

import typer

app = typer.Typer(help="Messenger pipeline commands.", no_args_is_help=True)


def simulate() -> None:
    """Write simulated raw Messenger telemetry and kernels from a known field."""
    raise typer.Exit(code=1)
