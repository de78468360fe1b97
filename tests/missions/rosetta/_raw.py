"""Hand-made raw RPC-MAG science CSV files (constant counts), no forward model involved."""

from pathlib import Path

import numpy as np

HEADER = "time_utc,obt,sid,bx,by,bz,t_ob,t_ib,quality"


def write_raw_csv(
    path: Path,
    start: str,
    n: int,
    step_s: float,
    *,
    counts=(1000, -2000, 3000),
    t_words=16384,
    sid: int | np.ndarray = 3,
    sensor: str = "OB",
) -> Path:
    """Write ``n`` records from ``start`` (ISO UTC, whole seconds) every ``step_s`` seconds.

    ``t_words`` (scalar or array of n) is the thermistor word of both sensors; ``sid`` is
    the filter mode (scalar or array); quality is 0 (OB) or 8 (IB).  OBT is the seconds
    since 2003-01-01 ignoring leap seconds (not used without kernels).
    """
    t0 = np.datetime64(start, "us")
    offs = (np.arange(n) * step_s * 1e6).astype("int64").astype("m8[us]")
    times = np.datetime_as_string(t0 + offs, unit="us")
    obt = (t0 + offs - np.datetime64("2003-01-01T00:00:00", "us")).astype(np.int64) / 1e6
    words = np.broadcast_to(np.asarray(t_words), (n,))
    sids = np.broadcast_to(np.asarray(sid), (n,))
    q = 8 if sensor == "IB" else 0
    rows = [
        f"{t},{o:.6f},{s},{counts[0]},{counts[1]},{counts[2]},{w},{w},{q}"
        for t, o, s, w in zip(times, obt, sids, words, strict=True)
    ]
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    Path(path).write_text("\n".join([HEADER, *rows]) + "\n")
    return Path(path)
