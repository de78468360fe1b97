"""The IMAP part of ``make demo``: the shipped real packets -> L1A and L1B products."""

from __future__ import annotations

from pathlib import Path

from fluxcal.missions.imap.calibration import DEFAULT_CALIBRATION
from fluxcal.missions.imap.packets import data_file
from fluxcal.missions.imap.pipeline import DEFAULT_SCLK, process, write_products
from fluxcal.products.provenance import provenance_attrs

#: The real packet samples shipped with fluxcal (data/PROVENANCE.md).
SAMPLES = ("mag_sample_norm.pkts", "mag_sample_burst.pkts")


def run_demo(out: Path) -> str:
    """Decode, time and calibrate the shipped IMAP MAG packets; return a summary."""
    out = Path(out)
    inputs = [data_file(name) for name in SAMPLES]
    lines = []
    for level in ("l1a", "l1b"):
        datasets = process(inputs, level=level)
        calibration = {"imap_mag_l1b": data_file(DEFAULT_CALIBRATION)} if level == "l1b" else {}
        prov = provenance_attrs(inputs, calibration, [data_file(DEFAULT_SCLK)])
        paths = write_products(datasets, out / level, ["cdf"], prov,
                               quicklook=level == "l1b")
        counts = ", ".join(f"{m}-{s} {ds.sizes['time']}" for (m, s), ds in datasets.items())
        lines.append(f"{level.upper()} from real IMAP MAG ground-test packets: {counts} "
                     f"vectors; {len(paths)} files in {out / level}")
    return "\n".join(lines)


def run_quick_demo(out: Path) -> str:
    """``make demo``: the shipped real packets -> L1B CDFs, quicklooks and the HTML report."""
    from fluxcal.products.html_report import write_run_report

    out = Path(out)
    inputs = [data_file(name) for name in SAMPLES]
    datasets = process(inputs, level="l1b")
    prov = provenance_attrs(inputs, {"imap_mag_l1b": data_file(DEFAULT_CALIBRATION)},
                            [data_file(DEFAULT_SCLK)])
    paths = write_products(datasets, out, ["cdf"], prov, quicklook=True)
    report = write_run_report(out, title="fluxcal demo: IMAP MAG L1B from real packets")
    counts = ", ".join(f"{m}-{s} {ds.sizes['time']}" for (m, s), ds in datasets.items())
    return (f"IMAP MAG L1B from real ground-test packets: {counts} vectors; {len(paths)} "
            f"files in {out}\n  report: {report}")
