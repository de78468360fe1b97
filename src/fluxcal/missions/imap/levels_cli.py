"""``fluxcal imap l1c`` and ``fluxcal imap l2``: the levels above L1B, from L1B/L1C files.

Inputs are recognised by content (`fluxcal.missions.imap.team_layout.read_l1b`):
fluxcal's L1B/L1C products, the team's CDFs, or the team's validation CSVs.  Errors are
`FluxcalError` subclasses (one line, exit 2) raised before anything is written.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import typer

from fluxcal import preflight
from fluxcal.errors import InputFormatError
from fluxcal.products.format_names import FORMATS
from fluxcal.runs.options import with_options

LAYOUTS = ("fluxcal", "team")


@dataclass(frozen=True)
class LevelOptions:
    """Options of ``imap l1c`` and ``imap l2``."""

    formats: tuple[str, ...] = field(default=("cdf",), metadata={
        "help": "Product formats (fluxcal layout): cdf, nc, tab, zarr.", "choices": FORMATS,
        "empty_ok": False})
    layout: str = field(default="fluxcal", metadata={
        "help": "fluxcal (b in nT, Epoch) or team (the IMAP MAG team's CDF variables: "
                "epoch, vectors, compression_flags ...).", "choices": LAYOUTS})


def _check(options: LevelOptions) -> None:
    if options.layout == "team" and tuple(options.formats) != ("cdf",):
        raise InputFormatError("--layout team writes the team's CDFs only: leave out "
                               "--formats or give --formats cdf", field="--formats")


def _write(datasets: dict, out: Path, options: LevelOptions, inputs: list[Path],
           calibration: dict | None = None, kernels: list[Path] | None = None) -> list[Path]:
    """Write the level's products (`fluxcal.runs.driver.write`: provenance, all or nothing)."""
    from fluxcal.missions.imap.routes import LevelRun
    from fluxcal.runs import driver

    return driver.write(LevelRun(calibration or {}), datasets, out, options, inputs=inputs,
                        kernel_list=[str(k) for k in kernels or []])


def register(app: typer.Typer) -> None:
    """Add the ``l1c`` and ``l2`` commands to the ``fluxcal imap`` group."""

    @app.command("l1c")
    @with_options(LevelOptions)
    def l1c_command(
        inputs: list[Path] = typer.Option(
            ..., "--input", help="L1B files, normal and burst mode of one or both sensors "
            "(fluxcal's products, the team's CDFs or CSVs); repeat for several."),
        out: Path = typer.Option(..., "--out", help="Folder for the products."),
        day: str | None = typer.Option(
            None, "--day", help="UTC day (YYYY-MM-DD) whose edges (+-30 min) are filled "
            "from burst (default: the day of the middle normal-mode sample)."),
        options: LevelOptions = None,  # type: ignore[assignment] - from the command line
    ) -> None:
        """Merge normal and burst L1B per sensor: gaps filled from burst (CIC, linear).

        Products are named imap_mag_l1c_norm-<mago|magi>_<yyyymmdd>_v001; each row is
        flagged normal (0), interpolated from burst (1) or missing (-1).
        """
        import xarray as xr

        from fluxcal.missions.imap import l1c, team_layout

        _check(options)
        for path in inputs:
            preflight.existing_file(path, "--input")
        preflight.writable_folder(out, "--out")
        parts: dict[tuple[str, str], list[xr.Dataset]] = {}
        for path in inputs:
            ds = team_layout.read_l1b(path)
            parts.setdefault((ds.attrs.get("mode", "norm"), ds.attrs.get("sensor", "mago")),
                             []).append(ds)
        joined = {k: _join(v) for k, v in parts.items()}
        sensors = sorted({s for m, s in joined if m == "norm"})
        if not sensors:
            raise InputFormatError("no normal-mode L1B among the inputs: L1C starts from "
                                   "normal mode", field="--input")
        merged = {}
        for sensor in sensors:
            norm = joined[("norm", sensor)]
            merged[("norm", sensor)] = l1c.merge(norm, joined.get(("burst", sensor)),
                                                 _day(day, norm))
        paths = _write(merged, out, options, list(inputs))
        n = sum(ds.sizes["time"] for ds in merged.values())
        dup = sum(ds.attrs["duplicates_dropped"] for ds in joined.values())
        typer.echo(f"L1C: {n} rows; {len(paths)} files in {out}"
                   + (f" ({dup} repeated input rows dropped)" if dup else ""))

    @app.command("l2")
    @with_options(LevelOptions)
    def l2_command(
        inputs: list[Path] = typer.Option(
            ..., "--input", help="L1C (normal mode) or L1B (burst) file of one sensor "
            "(fluxcal's, the team's CDF or CSV)."),
        matrices: Path = typer.Option(..., "--l2-matrices", help="The team's L2 matrices "
                                      "CDF (URFTOORFO/URFTOORFI, 3x3 per range)."),
        offsets: Path = typer.Option(..., "--l2-offsets", help="The team's L2 offsets CDF "
                                     "for this input (offsets, timedeltas, quality)."),
        out: Path = typer.Option(..., "--out", help="Folder for the products."),
        frame: list[str] = typer.Option(
            ["sensor"], "--frame", help="Output frame(s): sensor (IMAP_MAG_BASE, no "
            "kernel), srf (needs the IMAP frames kernel), dsrf, gse, gsm, rtn (need the "
            "frames, attitude and ephemeris kernels); repeat for several."),
        kernels: list[Path] | None = typer.Option(
            None, "--kernels", help="IMAP SPICE kernels (frames .tf, CK, SPK, LSK) or a "
                                    "meta-kernel, for the frames other than sensor."),
        day: str | None = typer.Option(None, "--day", help="UTC day kept (default: the "
                                       "day of the middle vector)."),
        options: LevelOptions = None,  # type: ignore[assignment] - from the command line
    ) -> None:
        """Apply the L2 matrices and offsets; write the field in each --frame.

        Products are named imap_mag_l2_<mode>-<mago|magi|frame>_<yyyymmdd>_v001.
        """
        from fluxcal.geometry.kernels import KernelPool
        from fluxcal.missions.imap import l2, team_layout

        _check(options)
        for path in inputs:
            preflight.existing_file(path, "--input")
        preflight.existing_file(matrices, "--l2-matrices")
        preflight.existing_file(offsets, "--l2-offsets")
        for path in kernels or []:
            preflight.existing_file(path, "--kernels")
        preflight.writable_folder(out, "--out")
        with KernelPool(list(kernels or []), fluxcal_frames=False):
            l2.check_frames(list(frame))
            cal = l2.load_l2_calibration(matrices, offsets)
            parts = [team_layout.read_l1b(p) for p in inputs]
            kinds = {(d.attrs.get("mode", "norm"), d.attrs.get("sensor", "mago"))
                     for d in parts}
            if len(kinds) > 1:
                raise InputFormatError(f"the inputs mix {sorted(kinds)}: give one mode and "
                                       "sensor per run", field="--input")
            ds = _join(parts)
            sensor, mode = ds.attrs.get("sensor", "mago"), ds.attrs.get("mode", "norm")
            sensor_frame = l2.calibrate(ds, cal, _day(day, ds))
            results = {(mode, sensor if name == "sensor" else name):
                       l2.to_frame(sensor_frame, name) for name in dict.fromkeys(frame)}
        paths = _write(results, out, options, list(inputs), {
            "imap_mag_l2_matrices": matrices, "imap_mag_l2_offsets": offsets}, kernels)
        n = sum(d.sizes["time"] for d in results.values())
        typer.echo(f"L2: {n} vectors in {len(results)} frame(s); {len(paths)} files in {out}")


def _join(parts: list) -> object:
    """One dataset of several L1B parts of one mode and sensor, sorted by time.

    Rows repeated exactly (same time and field, e.g. a file given twice) are dropped; their
    count is ``attrs["duplicates_dropped"]``.
    """
    import numpy as np
    import xarray as xr

    ds = parts[0] if len(parts) == 1 else xr.concat(parts, dim="time",
                                                     combine_attrs="override")
    ds = ds.isel(time=np.argsort(ds["epoch"].values, kind="stable"))
    t, b = ds["epoch"].values, ds["b"].values
    same = np.r_[False, (np.diff(t) == 0) & (b[1:] == b[:-1]).all(axis=1)]
    ds = ds.isel(time=~same)
    ds.attrs["duplicates_dropped"] = int(same.sum())
    return ds


def _day(day: str | None, ds: object) -> object:
    """``--day`` as a date, else the UTC day of the middle sample of ``ds``."""
    import numpy as np

    from fluxcal.geometry.time import tt2000_to_datetime64
    from fluxcal.products.timeindex import default_lsk

    if day is not None:
        try:
            return np.datetime64(day, "D")
        except ValueError:
            raise InputFormatError(f"--day {day!r}: expected YYYY-MM-DD",
                                   field="--day") from None
    epoch = np.asarray(ds["epoch"].values, dtype=np.int64)
    middle = np.array([epoch[epoch.size // 2]])
    return tt2000_to_datetime64(middle, default_lsk())[0].astype("M8[D]")
