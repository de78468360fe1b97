"""The ``fluxcal`` command line.

Sub-commands are defined next to the code they drive (``missions/<m>/cli.py``,
``products/cli.py``) and registered here.  `main` takes ``argv`` so tests can call it.
"""

from __future__ import annotations

import logging
import sys
from collections.abc import Sequence
from pathlib import Path

import typer

from fluxcal import __version__

app = typer.Typer(
    name="fluxcal",
    help="Calibrate fluxgate-magnetometer telemetry into science-ready magnetic-field products.",
    no_args_is_help=True,
    add_completion=False,
)
simulate_app = typer.Typer(
    help="Forward models: write raw telemetry and kernels from a known field."
)
app.add_typer(simulate_app, name="simulate")


@app.callback()
def _root(
    verbose: bool = typer.Option(False, "--verbose", "-v", help="Log progress to stderr."),
) -> None:
    logging.basicConfig(
        level=logging.INFO if verbose else logging.WARNING,
        format="%(levelname)s %(name)s: %(message)s",
    )


@app.command()
def version() -> None:
    """Print the fluxcal version."""
    typer.echo(__version__)


@app.command()
def demo(
    out: Path = typer.Option(Path("demo-output"), help="Folder for the demo products."),
) -> None:
    """Run the main job on the embedded default data and say where the products are."""
    from fluxcal.demo import run_demo

    run_demo(out)


def _register() -> None:
    from fluxcal.missions.messenger import cli as messenger_cli
    from fluxcal.missions.rosetta import clean_cli
    from fluxcal.missions.rosetta import cli as rosetta_cli
    from fluxcal.products import cli as products_cli

    app.add_typer(messenger_cli.app, name="messenger")
    rosetta_cli.app.command("clean")(clean_cli.clean)
    app.add_typer(rosetta_cli.app, name="rosetta")
    simulate_app.command("messenger")(messenger_cli.simulate)
    simulate_app.command("rosetta")(rosetta_cli.simulate)
    app.command("plot")(products_cli.plot)
    app.command("batch")(products_cli.batch)


_register()


def main(argv: Sequence[str] | None = None) -> int:
    """Run the CLI with ``argv`` (default: ``sys.argv[1:]``) and return the exit code.

    Usage errors print click's message and return its code (2); a `FluxcalError` prints
    ``fluxcal: error: ...`` and returns 2; ``typer.Exit(code)`` returns ``code``.
    """
    from fluxcal.errors import FluxcalError

    args = list(sys.argv[1:] if argv is None else argv)
    try:
        code = app(args=args, prog_name="fluxcal", standalone_mode=False)
    except SystemExit as exc:
        return int(exc.code or 0)
    except FluxcalError as exc:
        typer.echo(f"fluxcal: error: {exc}", err=True)
        return 2
    except typer.Abort:
        typer.echo("Aborted.", err=True)
        return 1
    except Exception as exc:
        # click's (and typer's vendored click's) usage errors and Exit carry exit_code
        exit_code = getattr(exc, "exit_code", None)
        if exit_code is None:
            raise
        show = getattr(exc, "show", None)
        if callable(show):
            show()
        return int(exit_code)
    return int(code) if isinstance(code, int) else 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
