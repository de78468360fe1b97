"""
IMAP: write an L1B product and read it back
===========================================

``fluxcal imap calibrate`` decodes real IMAP MAG CCSDS packets and writes L1B CDF
products; `fluxcal.read_product` opens any product, fluxcal's or an archived one, as a
Dataset indexed by UTC time.  fluxcal ships none of the IMAP MAG team's files: the
packets, the SCLK kernel, the calibration and the packet definition are read from
``../shared/data/imap/`` beside the checkout (the team's public test files); without
them this example says so and draws an empty figure.
"""

import tempfile
from pathlib import Path

import matplotlib.pyplot as plt

import fluxcal
from fluxcal.cli import main
from fluxcal.missions.imap.sources import TEAM_FILES, missing_team_files, shared_folder

team = shared_folder()
fig, ax = plt.subplots(figsize=(8, 3.5), layout="constrained")
if team is None:
    print(missing_team_files())
    ax.text(0.5, 0.5, "IMAP MAG team files not found beside the checkout", ha="center")
else:
    out = Path(tempfile.mkdtemp())
    main(["-q", "imap", "calibrate", "--input", str(team / TEAM_FILES["norm"]),
          "--kernels", str(team / TEAM_FILES["sclk"]), "--calib", str(team / TEAM_FILES["calib"]),
          "--xtce", str(team / TEAM_FILES["xtce"]), "--out", str(out)])
    products = sorted(p.name for p in out.glob("*.cdf"))
    print("\n".join(products))

    # %%
    # Read the outboard sensor's product: a time-indexed Dataset, attributes included.
    (path,) = out.glob("*mago*.cdf")
    ds = fluxcal.read_product(path)
    print(ds)

    for k, axis in enumerate("XYZ"):
        ax.plot(ds.time, ds["b"][:, k], ".-", ms=3, lw=0.6, label=axis)
    ax.set_ylabel(f"B ({ds['b'].attrs.get('units', '')})")
    ax.set_xlabel("UTC")
    ax.legend(fontsize=8, ncols=3)
    ax.set_title(f"{path.name}: L1B field in the sensor frame")
