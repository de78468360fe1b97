"""Constructed MESSENGER calibration inputs for the fit tests (issue 34).

Builders the fit tests share, neither of which calls the fit or its judgement:

* `tables_with_header_lines`: the packaged calibration tables (seed 000, Tables 2-8) copied
  into a test folder with a header line (``# T_RANGE: ...``, ``# D_RANGE: ...``) put in by
  text, as a fitted table states it, so that `load_calibration` is tested on files written
  here rather than by ``fit_write``.
* `scattered_laws`: Table 2 laws resampled with normal scatter of stated widths on their
  coefficients, drawn here (numpy only).
* `applied_law`: the Table 2 law as a table applies it (eq. 3a below T_m, 3b above,
  T_m of eq. 4), written here from the seed, not the pipeline's law function.
* `table_bootstrap`: a bootstrap (the resampled laws, D0, tau and dt that
  ``fit_merit.assess`` reads) built from arrays the test draws itself, with tau and dt held
  at the table's values; `with_law_resamples`: a fit result carrying such a bootstrap of
  resampled laws only, over samples at temperatures the test draws (no relaxation).
"""

from __future__ import annotations

import dataclasses
import shutil
from pathlib import Path
from typing import Any

import numpy as np

from fluxcal.missions.messenger.calibration_data import data_dir
from fluxcal.missions.messenger.fit_variance import offset_moments


def tables_with_header_lines(folder: Path, lines: dict[str, str | None]) -> Path:
    """The packaged tables copied to ``folder / "cal"``, a header line added to some.

    ``lines`` maps a table's file name to the line put in as its fourth (after the title,
    source and seed lines; ``None``: the file left as packaged).
    """
    out = folder / "cal"
    shutil.copytree(data_dir(), out)
    for name, line in lines.items():
        path = out / name
        text = path.read_text().splitlines()
        if line is not None:
            text.insert(3, line)
        path.write_text("\n".join(text) + "\n")
    return out


def scattered_laws(law: np.ndarray, rng: np.random.Generator, k: int,
                   widths: tuple[Any, Any, Any, Any], *, shared: bool = False) -> np.ndarray:
    """``k`` resamples of the law (3 axes, 4 coefficients): ``law`` plus ``widths[c]`` times
    a standard normal draw on coefficient ``c`` (a width may be one per axis; coefficients
    of width 0 are not drawn), drawn coefficient by coefficient from ``rng``; ``shared``:
    one draw per resample for all three axes, else one per axis."""
    out = np.repeat(law[None], k, axis=0)
    for c, width in enumerate(widths):
        if np.any(width):
            out[:, :, c] += width * rng.standard_normal((k, 1 if shared else 3))
    return out


def applied_law(c: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Table 2 law (counts), shape ``(t, axis)``, as the table applies it.

    ``c`` is ``(axis, (A0, B0, A1, B1))``: ``A0 + B0 T`` up to ``T_m = (A0 - A1) / (B1 -
    B0)`` (eq. 4), ``A1 + B1 T`` above (eq. 3a, 3b; MESSENGER MAG EDR-to-CDR Processing
    v2i, sec. 7).  Not the larger of the two lines: that is the same only while ``B1 >
    B0``; a fitted upper slope below the lower one (16-day Mercury orbit, seed 3507) read
    as the larger line is 10 000 counts off below the break (verification section 24).
    Parallel lines (``B1 = B0``): the lower line everywhere.
    """
    c = np.asarray(c, dtype=float)
    t = np.asarray(t, dtype=float)[:, None]
    with np.errstate(divide="ignore", invalid="ignore"):
        tm = (c[:, 0] - c[:, 2]) / (c[:, 3] - c[:, 1])
    tm = np.where(c[:, 3] == c[:, 1], np.inf, tm)
    return np.where(t <= tm, c[:, 0] + c[:, 1] * t, c[:, 2] + c[:, 3] * t)


def table_bootstrap(res: Any, law: np.ndarray, d0: np.ndarray | None = None) -> dict:
    """A bootstrap of the given resampled laws (and D0), tau and dt at the table's values.

    ``law`` is (resamples, 3 axes, 4 coefficients); ``d0`` (resamples, 3) defaults to the
    calibration's D0 in every resample.
    """
    k = law.shape[0]
    rel = res.calibration.constants["relaxation"]
    d0 = (np.repeat(np.asarray(res.calibration.duty_cycle_d0, dtype=float)[None], k, 0)
          if d0 is None else d0)
    return {"law": law, "d0": d0, "tau": np.full(k, float(rel["tau_s"])),
            "dt": np.full(k, float(rel["delay_s"]))}


def with_law_resamples(res: Any, law: np.ndarray, temp: np.ndarray) -> Any:
    """``res`` with the bootstrap of the resampled laws ``law`` (`table_bootstrap`) and the
    offset moments of samples at the temperatures ``temp`` with no relaxation (r = 0), no
    waveform error.  ``res.variance`` is changed in place (as the tests did before)."""
    zero = np.zeros(temp.size)
    res.variance.offset_moments = offset_moments(temp, zero, zero, zero)
    return dataclasses.replace(res, bootstrap=table_bootstrap(res, law), waveform_error=None)
