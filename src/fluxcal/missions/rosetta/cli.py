"""``fluxcal rosetta`` and ``fluxcal simulate rosetta`` commands (placeholder, filled by the rosetta issue)."""

from __future__ import annotations

import typer

app = typer.Typer(help="Rosetta pipeline commands.", no_args_is_help=True)


def simulate() -> None:
    """Write simulated raw Rosetta telemetry and kernels from a known field."""
    raise typer.Exit(code=1)
