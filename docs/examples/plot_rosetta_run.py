"""
Rosetta: raw counts to LEVEL_A and LEVEL_B in one call
======================================================

`fluxcal.calibrate_rosetta` makes the RPC-MAG levels of one sensor (RO-IGEP-TR0028,
sec. 4.1-4.8) from its raw file and returns each as a Dataset indexed by UTC time.  The
raw file is fluxcal's forward model of three minutes of outboard-sensor telemetry
(``fluxcal simulate rosetta``).
"""

import tempfile
from pathlib import Path

import matplotlib.pyplot as plt

import fluxcal
from fluxcal.cli import main

work = Path(tempfile.mkdtemp())
main(["-q", "simulate", "rosetta", "--out", str(work), "--hours", "0.05"])

levels = fluxcal.calibrate_rosetta(work / "RPCMAG_20140801_RAW_OB.csv", "OB",
                                   levels=("A", "B"), calib=work / "calib")
print(sorted(levels), levels["B"].sizes)

# %%
# LEVEL_A is the calibrated field in the sensor's coordinates (URF; sec. 4.2), LEVEL_B
# the same field rotated into the spacecraft frame (sec. 4.3).
a, b = levels["A"], levels["B"]
fig, axes = plt.subplots(2, 1, sharex=True, figsize=(8, 5), layout="constrained")
for k, axis in enumerate("XYZ"):
    axes[0].plot(a.time, a["b"][:, k], lw=0.5, label=axis)
    axes[1].plot(b.time, b["b"][:, k], lw=0.5, label=axis)
axes[0].set_ylabel(f"LEVEL_A ({a['b'].attrs.get('units', '')})")
axes[1].set_ylabel(f"LEVEL_B ({b['b'].attrs.get('units', '')})")
axes[1].set_xlabel("UTC")
axes[0].legend(loc="upper right", fontsize=8, ncols=3)
fig.suptitle("Rosetta RPC-MAG OB, simulated: sensor (LEVEL_A) and spacecraft (LEVEL_B) frame")
