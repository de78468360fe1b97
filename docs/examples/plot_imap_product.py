"""
IMAP: write an L1B product and read it back
===========================================

``fluxcal imap calibrate`` decodes real IMAP MAG CCSDS packets (shipped with fluxcal,
from the IMAP MAG team) and writes L1B CDF products; `fluxcal.read_product` opens any
product, fluxcal's or an archived one, as a Dataset indexed by UTC time.
"""

import tempfile
from pathlib import Path

import matplotlib.pyplot as plt

import fluxcal
from fluxcal.cli import main
from fluxcal.missions.imap.packets import data_file

out = Path(tempfile.mkdtemp())
main(["-q", "imap", "calibrate", "--input", str(data_file("mag_sample_norm.pkts")),
      "--out", str(out)])
products = sorted(p.name for p in out.glob("*.cdf"))
print("\n".join(products))

# %%
# Read the outboard sensor's product: a time-indexed Dataset, attributes included.
(path,) = out.glob("*mago*.cdf")
ds = fluxcal.read_product(path)
print(ds)

fig, ax = plt.subplots(figsize=(8, 3.5), layout="constrained")
for k, axis in enumerate("XYZ"):
    ax.plot(ds.time, ds["b"][:, k], ".-", ms=3, lw=0.6, label=axis)
ax.set_ylabel(f"B ({ds['b'].attrs.get('units', '')})")
ax.set_xlabel("UTC")
ax.legend(fontsize=8, ncols=3)
ax.set_title(f"{path.name}: L1B field in the sensor frame")
