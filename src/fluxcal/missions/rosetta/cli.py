"""``fluxcal rosetta ...`` commands and ``fluxcal simulate rosetta``.

``calibrate`` and ``simulate`` follow "RO-IGEP-TR0028 Rosetta RPC-MAG calibration"
(sec. 3-4.8); the cleaning commands are added here by the cleaning issue.

References
----------
.. [1] RO-IGEP-TR0028 (seed 003), sec. 4.1 (calibration files), 4.3.1 (alignment).
"""

from __future__ import annotations

import datetime as _dt
from pathlib import Path

import typer

from fluxcal.errors import InputFormatError

#: Levels computed from LEVEL_B, i.e. through the sensor-to-spacecraft alignment.
ALIGNED_LEVELS = frozenset("BCFG")


def warn_placeholder_alignment(calib_dir: Path | None) -> bool:
    """Warn on stderr when the alignment in use is fluxcal's placeholder identity.

    The shipped ``RPCMAG_SC_ALIGN.TXT`` is marked ``PLACEHOLDER``: the measured
    URF -> spacecraft rotations (RO-IGEP-TR0028 sec. 4.3.1) are not public.  Every run
    that uses it says so here (the products say so in their ``alignment`` attribute and
    label).  Returns whether it warned.
    """
    from fluxcal.missions.rosetta import calib

    alignment = calib.load_alignment(calib_dir)
    if alignment.placeholder:
        typer.echo(
            f"fluxcal: warning: the alignment {alignment.source} is fluxcal's PLACEHOLDER "
            "identity, not the measured sensor-to-spacecraft rotation (RO-IGEP-TR0028 "
            "sec. 4.3.1): LEVEL_B, C, F, G directions are only as good as that; give "
            "--calib FOLDER holding the real RPCMAG_SC_ALIGN.TXT, or "
            "--alignment-from-kernels", err=True)
    return alignment.placeholder

app = typer.Typer(help="Rosetta pipeline commands.", no_args_is_help=True)


@app.command()
def calibrate(
    science: Path = typer.Option(
        ..., "--science", help="Raw science CSV of one sensor (RO-IGEP-TR0028 sec. 4.1.2)."
    ),
    sensor: str = typer.Option(..., "--sensor", help="OB or IB."),
    out: Path = typer.Option(..., "--out", help="Folder for the products."),
    levels: str = typer.Option("A,B", "--levels", help="Comma-separated levels: A,B,C,E,F,G."),
    hk: Path | None = typer.Option(
        None, "--hk", help="Raw HK CSV (sec. 4.1.1), converted to HK LEVEL_A."
    ),
    calib: Path | None = typer.Option(
        None, "--calib", help="Folder with calibration files overriding fluxcal's defaults."
    ),
    kernels: Path | None = typer.Option(
        None, "--kernels", help="Meta-kernel (SCLK -226, CK, SPK): times from OBT; needed for C, G."
    ),
    primary: str = typer.Option("OB", "--primary", help="Primary sensor (time-shift table)."),
    average: float = typer.Option(1.0, "--average", help="Averaging interval of E, F, G (s)."),
    frame: str = typer.Option(
        "auto", "--frame",
        help="LEVEL_C frame: ECLIPJ2000, CSEQ, or auto (CSEQ from 2014-01-20, sec. 4.4.1).",
    ),
    centre: str = typer.Option(
        "auto", "--centre",
        help="Body the LEVEL_C position is relative to (auto: the comet for CSEQ, else SUN).",
    ),
    boom: str = typer.Option("deployed", "--boom", help="Boom state: deployed or stowed."),
    stitch_gap_hours: float = typer.Option(
        3.0, "--stitch-gap-hours", help="No midnight stitching across longer gaps (sec. 4.2.3.3)."
    ),
    stitch_state: Path | None = typer.Option(
        None,
        "--stitch-state",
        help="JSON file carrying the midnight-stitching state from one day's run to the next.",
    ),
    alignment_from_kernels: bool = typer.Option(
        False,
        "--alignment-from-kernels",
        help="Take URF -> s/c from the frames ROS_RPC_MAG_OB/IB (needs the boom CK) "
        "instead of RPCMAG_SC_ALIGN.TXT.",
    ),
    no_jumps: bool = typer.Option(False, "--no-jumps", help="Skip the Appendix B offset jumps."),
    formats: str = typer.Option("tab,cdf", "--formats", help="Product formats: tab,cdf,nc."),
    quicklook: bool = typer.Option(
        False,
        "--quicklook",
        help="Also write RPCMAG_QL_<sensor>_<yyyymmdd>.png per day (field of the highest "
        "level made among C, B, A; sensor temperature; quality; distance).",
    ),
) -> None:
    """Calibrate raw RPC-MAG telemetry into LEVEL_A, B, C, E, F, G products.

    Follows "RO-IGEP-TR0028 Rosetta RPC-MAG calibration" sec. 4.1-4.8.
    """
    from fluxcal import preflight
    from fluxcal.missions.rosetta.pipeline import calibrate_files, parse_levels

    preflight.plain_text_file(science, "--science")
    if hk is not None:
        preflight.plain_text_file(hk, "--hk")
    if calib is not None:
        preflight.existing_folder(calib, "--calib")
    if kernels is not None:
        preflight.existing_file(kernels, "--kernels")
    preflight.writable_folder(out, "--out")
    level_list = parse_levels(levels)
    result = calibrate_files(
        science,
        sensor,
        out,
        levels=level_list,
        hk_file=hk,
        calib_dir=calib,
        kernels=kernels,
        primary=primary,
        average_s=average,
        frame=frame,
        centre=centre,
        boom=boom,
        stitch_gap_s=stitch_gap_hours * 3600.0,
        stitch_state=stitch_state,
        alignment_from_kernels=alignment_from_kernels,
        jumps=not no_jumps,
        formats=[f.strip() for f in formats.split(",") if f.strip()],
        quicklook=quicklook,
    )
    if ALIGNED_LEVELS & set(level_list) and not alignment_from_kernels:
        warn_placeholder_alignment(calib)
    a = result.levels["A"]
    typer.echo(
        f"{a.sizes['time']} vectors calibrated ({a.attrs['n_dropped_quality']} dropped for "
        f"quality); {len(result.paths)} files in {out}"
    )


def simulate(
    out: Path = typer.Option(Path("rosetta-sim"), "--out", help="Folder for the simulated inputs."),
    start: str = typer.Option("2014-08-01T00:00:00", "--start", help="First time stamp (UTC)."),
    hours: float = typer.Option(1.0, "--hours", help="Length of the simulation (h)."),
    rate: float = typer.Option(20.0, "--rate", help="Vector rate (Hz)."),
    primary: str = typer.Option("OB", "--primary", help="Primary sensor."),
    seed: int = typer.Option(0, "--seed", help="Random seed (bad-quality vectors)."),
) -> None:
    """Write simulated raw Rosetta telemetry, calibration files and kernels from a known field."""
    from fluxcal import preflight
    from fluxcal.missions.rosetta.simulate import write_simulation

    check_simulation_options(start, hours, rate, primary)
    preflight.writable_folder(out, "--out")

    paths = write_simulation(
        out, start_utc=start, hours=hours, rate_hz=rate, primary=primary, seed=seed
    )
    for name, path in paths.items():
        typer.echo(f"{name}: {path}")


def check_simulation_options(start: str, hours: float, rate: float, primary: str) -> None:
    """Check ``fluxcal simulate rosetta``'s options before anything is written.

    Raises
    ------
    InputFormatError
        Naming the option: a start that is not ISO UTC, a non-positive or longer than
        31-day length, a rate outside (0, 1000] Hz, a primary other than OB/IB.
    """
    try:
        _dt.datetime.fromisoformat(start)
    except ValueError:
        raise InputFormatError(f"{start!r} is not an ISO UTC time such as "
                               "2014-08-01T00:00:00", field="--start") from None
    if not 0.0 < hours <= 31 * 24:
        raise InputFormatError(f"{hours} h: give a length above 0 and at most 744 h (31 days)",
                               field="--hours")
    if not 0.0 < rate <= 1000.0:
        raise InputFormatError(f"{rate} Hz: give a vector rate above 0 and at most 1000 Hz",
                               field="--rate")
    if primary.upper() not in ("OB", "IB"):
        raise InputFormatError(f"{primary!r}: the primary sensor is OB or IB", field="--primary")
