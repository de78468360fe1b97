"""
Tutorial: from telemetry to a product you can check and share
==============================================================

A first run from start to end, as a mission scientist makes one:

1. make raw MESSENGER MAG telemetry from a known field (the forward model, so the answer
   is known);
2. calibrate it with the command line and a run-configuration file, into CDF products,
   a quicklook and the run's HTML report;
3. open the product in Python, indexed by UTC time;
4. ask the product what it was made from (its provenance);
5. check the calibrated field against the field the telemetry was made from.

Each step is what you would type or run on your own data; only step 1 is replaced by
your EDRs (``fluxcal messenger edr2cdr --edr FOLDER --mapping MAPPING``, see the
MESSENGER guide).  The chain is MESSENGER MAG EDR-to-CDR Processing, sec. 5-13.
"""

import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

import fluxcal
from fluxcal.cli import main

work = Path(tempfile.mkdtemp())

# %%
# 1. Telemetry from a known field
# -------------------------------
# ``fluxcal simulate messenger`` writes the three telemetry streams (science counts,
# heater bits, sensor temperatures), SPICE kernels for the spacecraft, and the true field
# in MSO (``MAG_truth.csv``): five minutes at 20 Hz here.
main(["-q", "simulate", "messenger", "--out", str(work / "raw"), "--duration", "300"])
inputs = work / "raw" / "inputs"
kernels = work / "raw" / "kernels" / "messenger_synthetic.tm"
print(sorted(p.name for p in inputs.iterdir()))

# %%
# 2. Calibrate with a run-configuration file
# ------------------------------------------
# The options of a run can live in a TOML file, by option name; what the command line
# gives wins.  Here: MSO and RTN, CDF only, 1-s and 60-s averages, a quicklook.
config = work / "run.toml"
config.write_text('frames = ["mso", "rtn"]\nformats = ["cdf"]\naverage = [1, 60]\n'
                  "quicklook = true\n")
code = main(["-q", "messenger", "edr2cdr", "--config", str(config),
             "--input", str(inputs / "MAG_science.csv"),
             "--heater", str(inputs / "MAG_heater.csv"),
             "--temperature", str(inputs / "MAG_temperature.csv"),
             "--kernels", str(kernels), "--out", str(work / "products")])
assert code == 0
for path in sorted((work / "products").iterdir()):
    print(path.name)

# %%
# ``index.html`` is the run's report: open it in a browser from the folder (no server),
# it links every product and shows the quicklooks and the data quality.
#
# 3. Open the product, indexed by time
# ------------------------------------
# `fluxcal.read_product` reads every format fluxcal writes (and the archive's tables);
# the result is an xarray Dataset with a UTC ``time`` index, so ``.sel`` and
# ``.resample`` work as on any time series.
sci = next((work / "products").glob("*mso-sci*.cdf"))
ds = fluxcal.read_product(sci)
print(ds)
minute = ds.sel(time=slice(ds.time[0].values, ds.time[0].values + np.timedelta64(60, "s")))
print(f"first minute: {minute.sizes['time']} vectors")

# %%
# 4. What was this product made from?
# -----------------------------------
# Every product names its inputs, calibration tables and kernels by file name and
# SHA-256 (never by the folder they sat in), and the command that made it.
main(["provenance", str(sci)])

# %%
# 5. Check against the field the telemetry was made from
# ------------------------------------------------------
# The simulator's truth is in MSO at the same sample times.  In the fine range the
# differences are the instrument's quantisation: counts of about 0.05 nT, so an rms of
# 0.05 / sqrt(12) ~ 0.014 nT per component, the limit any calibration can reach.
truth = np.genfromtxt(inputs / "MAG_truth.csv", delimiter=",", names=True,
                      dtype=None, encoding="ascii")
t_true = truth["epoch_tt2000"].astype(np.int64)
t_prod = ds["epoch"].values  # TT2000 ns of each calibrated vector
k = np.clip(np.searchsorted(t_true, t_prod), 1, len(t_true) - 1)
k -= (t_prod - t_true[k - 1]) < (t_true[k] - t_prod)  # the nearest truth sample
same = np.abs(t_true[k] - t_prod) < 1_000_000  # within 1 ms: the same sample
fine = same & (truth["range"][k] == 0)  # the fine range (0.05 nT counts)
b = ds["b"]
true_b = np.column_stack([truth["bx_mso"], truth["by_mso"], truth["bz_mso"]])[k]
diff = np.where(fine[:, None], b.values - true_b, np.nan)
print(f"{fine.sum()} of {b.sizes['time']} vectors compared; calibrated - true rms x y z "
      f"[nT]: {np.sqrt(np.nanmean(diff ** 2, axis=0)).round(4)}")

fig, (ax, ax_d) = plt.subplots(2, 1, sharex=True, figsize=(8, 5), layout="constrained")
for c, axis in enumerate("XYZ"):
    ax.plot(b.time, b.values[:, c], lw=0.5, label=f"$B_{axis}$ MSO")
    ax_d.plot(b.time, diff[:, c], lw=0.4, label=f"$\\Delta B_{axis}$")
ax.set_ylabel("B (nT)")
ax.legend(loc="upper right", fontsize=8, ncols=3)
ax_d.set_ylabel("calibrated - true (nT)")
ax_d.set_xlabel("UTC")
ax_d.legend(loc="upper right", fontsize=8, ncols=3)
fig.suptitle("MESSENGER MAG, simulated: calibrated field and its error against the truth")
