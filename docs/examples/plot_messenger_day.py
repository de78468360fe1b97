"""
MESSENGER: calibrate simulated telemetry in one call
====================================================

`fluxcal.calibrate_messenger` runs the whole EDR -> CDR chain (MESSENGER MAG EDR-to-CDR
Processing, sec. 5-12) on the three telemetry streams and returns, per frame, the
content of that frame's product (the names `fluxcal.read_product` reads back), indexed by
UTC time.  The streams and SPICE kernels here come from fluxcal's forward model
(``fluxcal simulate messenger``): ten minutes of 20 Hz science from a known field.
"""

import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

import fluxcal
from fluxcal.cli import main

work = Path(tempfile.mkdtemp())
main(["-q", "simulate", "messenger", "--out", str(work), "--duration", "600"])
inputs = work / "inputs"

ds = fluxcal.calibrate_messenger(
    [inputs / "MAG_science.csv"], [inputs / "MAG_heater.csv"],
    [inputs / "MAG_temperature.csv"], work / "kernels" / "messenger_synthetic.tm",
    frames=("mso",))["mso"]
print(ds["b"])

# %%
# The result is indexed by time: select a slice, average to 10 s.
b = ds["b"]
ten_s = b.resample(time="10s").mean()
fig, (ax, ax_mag) = plt.subplots(2, 1, sharex=True, figsize=(8, 5), layout="constrained")
for k, axis in enumerate("XYZ"):
    ax.plot(b.time, b[:, k], lw=0.4, alpha=0.5, label=f"$B_{axis}$ MSO (20 Hz)")
    ax.plot(ten_s.time, ten_s[:, k], "k.", ms=2)
ax.set_ylabel("B (nT)")
ax.legend(loc="upper right", fontsize=8, ncols=3)
ax_mag.plot(b.time, np.linalg.norm(b.values, axis=1), lw=0.6)
ax_mag.set_ylabel("|B| (nT)")
ax_mag.set_xlabel("UTC")
fig.suptitle("MESSENGER MAG, simulated: calibrated field in MSO (dots: 10 s means)")
