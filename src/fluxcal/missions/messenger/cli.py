"""``fluxcal messenger edr2cdr`` and ``fluxcal simulate messenger`` commands."""

from __future__ import annotations

from pathlib import Path

import typer

app = typer.Typer(help="Messenger pipeline commands.", no_args_is_help=True)


def _split(text: str) -> list[str]:
    return [t.strip() for t in text.split(",") if t.strip()]


@app.command("edr2cdr")
def edr2cdr(
    sci: list[Path] = typer.Option(..., "--sci", help="Science CSV file(s)."),
    heater: list[Path] = typer.Option(..., "--heater", help="Heater-bit CSV file(s)."),
    temperature: list[Path] = typer.Option(..., "--temperature", help="Temperature CSV file(s)."),
    kernels: list[Path] = typer.Option(..., "--kernels", help="Meta-kernel or kernel files."),
    out: Path = typer.Option(..., "--out", help="Output folder."),
    frames: str = typer.Option("mso,j2000,mbf,rtn,sc", help="Frames (also: vso)."),
    formats: str = typer.Option("tab,cdf", help="Product formats."),
    average: str = typer.Option("1,5,10,60", help="Averaging intervals (s); '' for none."),
    max_offset_step: float = typer.Option(
        2.0, help="Sec. 13 smoothness threshold (fine-range counts); <= 0 disables."
    ),
    quicklook: bool = typer.Option(
        False, "--quicklook", help="Also write a quicklook PNG per day (field, |B|, offsets, "
        "quality flag, distance from Mercury)."
    ),
    quicklook_frame: str = typer.Option(
        "", "--quicklook-frame", help="Frame of the quicklook's field (default: the first "
        "of --frames)."
    ),
) -> None:
    """Calibrate MESSENGER MAG EDR streams into CDR products (seed 000 sec. 5-13)."""
    from fluxcal.errors import InputFormatError
    from fluxcal.missions.messenger.run import run_edr2cdr

    try:
        averages = [int(a) for a in _split(average)]
    except ValueError:
        raise InputFormatError(
            f"{average!r}: expected whole seconds separated by commas", field="--average"
        ) from None
    if any(a <= 0 for a in averages):
        raise InputFormatError(f"{average!r}: intervals must be positive", field="--average")
    written = run_edr2cdr(
        sci, heater, temperature, kernels, out,
        frames=_split(frames), formats=_split(formats),
        averages=averages,
        max_offset_step=max_offset_step if max_offset_step > 0 else None,
        quicklook=quicklook, quicklook_frame=quicklook_frame.strip() or None,
    )
    typer.echo(f"wrote {len(written)} files to {out}")


def simulate(
    out: Path = typer.Option(Path("messenger-sim"), "--out", help="Output folder."),
    start: str = typer.Option("2012-06-01T00:00:00", help="Start (ISO UTC)."),
    duration: float = typer.Option(7200.0, help="Length (s)."),
) -> None:
    """Write simulated raw Messenger telemetry and kernels from a known field."""
    from fluxcal.missions.messenger.demo import simulate_to_dir

    paths = simulate_to_dir(out, start, duration)
    for key, path in paths.items():
        typer.echo(f"{key}: {path}")
