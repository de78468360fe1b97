"""The IMAP part of ``make demo``: the team's real packets -> L1A and L1B products.

fluxcal ships none of the IMAP MAG team's files: the demo reads their ground-test packets,
SCLK kernel, calibration and packet definition from ``../shared/data/imap/`` beside the
checkout (`fluxcal.missions.imap.sources.shared_folder`); without it the part says in one
line what is missing and skips.
"""

from __future__ import annotations

from pathlib import Path

from fluxcal.missions.imap.pipeline import process, write_products
from fluxcal.missions.imap.sources import TEAM_FILES, missing_team_files, shared_folder
from fluxcal.products.provenance import provenance_attrs


def _run(out: Path, level: str, quicklook: bool) -> tuple[str, int] | None:
    """One level of the team's normal and burst packets into ``out``; None without them."""
    folder = shared_folder()
    if folder is None:
        return None
    inputs = [folder / TEAM_FILES["norm"], folder / TEAM_FILES["burst"]]
    calib = folder / TEAM_FILES["calib"]
    datasets = process(inputs, level=level, calib=calib, kernels=folder / TEAM_FILES["sclk"],
                       xtce=folder / TEAM_FILES["xtce"])
    prov = provenance_attrs(inputs, {"imap_mag_l1b": calib} if level == "l1b" else {},
                            [folder / TEAM_FILES["sclk"]])
    paths = write_products(datasets, out, ["cdf"], prov, quicklook=quicklook)
    counts = ", ".join(f"{m}-{s} {ds.sizes['time']}" for (m, s), ds in datasets.items())
    return counts, len(paths)


def run_demo(out: Path) -> str:
    """Decode, time and calibrate the team's IMAP MAG packets; return a summary."""
    out = Path(out)
    lines = []
    for level in ("l1a", "l1b"):
        done = _run(out / level, level, quicklook=level == "l1b")
        if done is None:
            return f"IMAP MAG part skipped: {missing_team_files()}"
        counts, n_files = done
        lines.append(f"{level.upper()} from real IMAP MAG ground-test packets: {counts} "
                     f"vectors; {n_files} files in {out / level}")
    return "\n".join(lines)


def run_quick_demo(out: Path) -> str:
    """``make demo``: the team's real packets -> L1B CDFs, quicklooks and the HTML report."""
    from fluxcal.products.html_report import write_run_report

    out = Path(out)
    done = _run(out, "l1b", quicklook=True)
    if done is None:
        return f"IMAP MAG part skipped: {missing_team_files()}"
    counts, n_files = done
    report = write_run_report(out, title="fluxcal demo: IMAP MAG L1B from real packets")
    return (f"IMAP MAG L1B from real ground-test packets: {counts} vectors; {n_files} "
            f"files in {out}\n  report: {report}")
