"""``fluxcal plot`` and ``fluxcal batch`` commands (placeholder, filled by the products issue)."""

from __future__ import annotations

import typer


def plot() -> None:
    """Render a quicklook PNG of a product."""
    raise typer.Exit(code=1)


def batch() -> None:
    """Process many days on Dask."""
    raise typer.Exit(code=1)
