"""Weighted, constrained fits of binned averages (seed 000 sec. 6 and 7 forms).

* `fit_two_segment`: two lines joined continuously at a free break (eq. 3a, 3b, 4;
  Table 2 form ``A0, B0, A1, B1, T_m``).
* `fit_line_fixed_intercept`: a line held through one point (eq. 5a with the intercept at
  d = 0 held at ``c_T(-50 C)``; Table 3 form ``C0, D0``).
* `fit_relaxation`: exponential relaxation after a (delayed) step, fitted to a normalised
  superposed epoch of duty-cycle changes (sec. 7, tau = 872 s).
* `fit_periodic_spline`: a periodic smoothing cubic spline of a waveform (sec. 6,
  Appendix Tables 6-8, evaluated on t = 0..100 s), smoothing by GCV;
  `fit_periodic_splines` fits several waveforms on the same phases at once.

Weights
-------
``weights`` are *amplitude* weights, ``1/sigma`` up to a common factor: the fits minimise
``chi2 = sum (w_i (y_i - f(x_i)))**2`` (the convention of ``numpy.polyfit``).  The
seed's "square root of the number of samples in each bin as a weight" is then exactly the
inverse standard error of a bin mean with a common scatter.  Because such weights are only
relative, parameter errors are by default scaled by ``chi2 / dof`` (as
``scipy.optimize.curve_fit(absolute_sigma=False)``); pass ``absolute_weights=True`` when
``w = 1/sigma`` exactly.  See docs/decisions/fits.md.

References
----------
.. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 6, sec. 7 eq. 3a, 3b, 4, 5a,
   Tables 2, 3, Appendix Tables 6-8.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.interpolate import BSpline
from scipy.linalg import cholesky, eigh, solve_triangular
from scipy.optimize import least_squares, minimize_scalar

from fluxcal.errors import FluxcalError, InputFormatError

__all__ = [
    "LineFit",
    "PeriodicSplineFit",
    "RelaxationFit",
    "TwoSegmentFit",
    "fit_line_fixed_intercept",
    "fit_periodic_spline",
    "fit_periodic_splines",
    "fit_relaxation",
    "fit_two_segment",
]


class FitError(FluxcalError, ValueError):
    """A fit cannot be made from the data given (too few points, degenerate)."""


def _prepare(
    x: np.ndarray, y: np.ndarray, weights: np.ndarray | None, min_points: int, what: str,
    extra_ok: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Return finite, positive-weight points sorted by x, and their input indices.

    ``extra_ok`` (shape of ``x``) drops further points (e.g. a bin without distribution).
    """
    x = np.asarray(x, dtype=np.float64).ravel()
    y = np.asarray(y, dtype=np.float64).ravel()
    w = np.ones_like(x) if weights is None else np.asarray(weights, dtype=np.float64).ravel()
    if not (x.shape == y.shape == w.shape):
        raise InputFormatError(
            f"{what}: x, y and weights must have the same length, got "
            f"{x.shape}, {y.shape}, {w.shape}",
            field="weights",
        )
    if np.any(w < 0):
        raise InputFormatError(f"{what}: weights must be >= 0", field="weights")
    ok = np.isfinite(x) & np.isfinite(y) & np.isfinite(w) & (w > 0)
    if extra_ok is not None:
        ok &= np.asarray(extra_ok, dtype=bool).ravel()
    index = np.flatnonzero(ok)
    x, y, w = x[ok], y[ok], w[ok]
    if x.size < min_points:
        raise FitError(
            f"{what}: needs at least {min_points} points with finite values and weight > 0, "
            f"got {x.size}"
        )
    order = np.argsort(x, kind="stable")
    return x[order], y[order], w[order], index[order]


def _covariance(jac_w: np.ndarray, chi2: float, dof: int, absolute: bool) -> np.ndarray:
    """Parameter covariance from the weighted Jacobian; inf where not determined."""
    jtj = jac_w.T @ jac_w
    try:
        cov = np.linalg.inv(jtj)
    except np.linalg.LinAlgError:
        return np.full(jtj.shape, np.inf)
    if not np.all(np.isfinite(cov)) or np.linalg.cond(jtj) > 1e14:
        return np.full(jtj.shape, np.inf)
    if not absolute:
        cov = cov * (chi2 / dof if dof > 0 else np.inf)
    return cov


def _errors(cov: np.ndarray) -> np.ndarray:
    with np.errstate(invalid="ignore"):
        return np.sqrt(np.abs(np.diag(cov)))


# -------------------------------------------------------------------------------------
# two-segment line (eq. 3a, 3b, 4)
# -------------------------------------------------------------------------------------
@dataclass(frozen=True)
class TwoSegmentFit:
    """Two lines joined at ``x_m`` (eq. 3a/3b, 4), Table 2 form.

    ``y = a0 + b0 x`` for ``x <= x_m`` and ``y = a1 + b1 x`` for ``x >= x_m`` with
    ``x_m = (a0 - a1) / (b1 - b0)``.

    Attributes
    ----------
    a0, b0, a1, b1, x_m : float
        Coefficients (Table 2's A0, B0, A1, B1, T_m).
    a0_err, b0_err, a1_err, b1_err, x_m_err : float
        Standard errors (inf where the data do not determine a parameter, e.g. x_m when
        the slopes are equal).
    covariance : ndarray, shape (5, 5)
        Covariance of ``(a0, b0, a1, b1, x_m)``.
    chi2 : float
        ``sum (w r)**2`` at the optimum.
    dof : int
        Points minus 4 free parameters.
    """

    a0: float
    b0: float
    a1: float
    b1: float
    x_m: float
    a0_err: float
    b0_err: float
    a1_err: float
    b1_err: float
    x_m_err: float
    covariance: np.ndarray
    chi2: float
    dof: int

    def __call__(self, x: np.ndarray) -> np.ndarray:
        """Evaluate the fit."""
        x = np.asarray(x, dtype=np.float64)
        return np.where(x <= self.x_m, self.a0 + self.b0 * x, self.a1 + self.b1 * x)

    def table_row(self) -> dict[str, float]:
        """Return Table 2's columns ``A_0, B_0, A_1, B_1, T_m``."""
        return {"A_0": self.a0, "B_0": self.b0, "A_1": self.a1, "B_1": self.b1, "T_m": self.x_m}


def _profile_chi2(design: np.ndarray, y: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Chi2 of the weighted linear fit for a stack of designs ``(G, n, p)``, shape (G,).

    Batched normal equations (a 1e-12 relative ridge keeps a degenerate grid point
    solvable); used only to screen grid values, the chosen one is refitted with lstsq.
    """
    dw = design * w[None, :, None]
    yw = y * w
    dwt = np.swapaxes(dw, 1, 2)
    normal = dwt @ dw
    ridge = 1e-12 * np.trace(normal, axis1=1, axis2=2)[:, None, None] + 1e-300
    normal = normal + ridge * np.eye(design.shape[2])[None]
    rhs = dwt @ yw
    p = np.linalg.solve(normal, rhs[..., None])[..., 0]
    r = yw[None, :] - (dw @ p[..., None])[..., 0]
    return np.sum(r * r, axis=1)


def _hinge_design(x: np.ndarray, xm: np.ndarray,
                  average: np.ndarray | None = None) -> np.ndarray:
    """Designs ``(1, min(x - xm, 0), max(x - xm, 0))`` for each break, ``(G, n, 3)``.

    With ``average`` (shape (n, m), rows summing to 1) ``x`` holds the m sub-bin
    abscissae and each row of the design is the ``average``-weighted mean over them.
    """
    u = x[None, :] - np.asarray(xm, dtype=np.float64).reshape(-1, 1)
    lo, hi = np.minimum(u, 0.0), np.maximum(u, 0.0)
    if average is not None:
        lo, hi = lo @ average.T, hi @ average.T
    return np.stack((np.ones_like(lo), lo, hi), axis=-1)


def _hinge_break_column(x: np.ndarray, xm: float, b0: float, b1: float,
                        average: np.ndarray | None) -> np.ndarray:
    """Return the derivative of the (averaged) hinge model in ``x_m``, shape (n,)."""
    col = np.where(x - xm <= 0, -b0, -b1)
    return col if average is None else average @ col


def _hinge_linear(
    x: np.ndarray, y: np.ndarray, w: np.ndarray, xm: float,
    average: np.ndarray | None = None,
) -> tuple[np.ndarray, float]:
    """Weighted LS of ``y = c + b0 min(x-xm, 0) + b1 max(x-xm, 0)``; return params, chi2."""
    design = _hinge_design(x, np.array([xm]), average)[0]
    dw = design * w[:, None]
    p, *_ = np.linalg.lstsq(dw, y * w, rcond=None)
    r = (y - design @ p) * w
    return p, float(r @ r)


def _polish_hinge(
    x: np.ndarray,
    y: np.ndarray,
    w: np.ndarray,
    start: tuple[float, float, float, float],
    chi2: float,
    lo: float,
    hi: float,
    average: np.ndarray | None = None,
) -> tuple[float, float, float, float, float]:
    """Refine ``(c, b0, b1, x_m)`` by least squares; keep the start if not better."""

    def resid(p: np.ndarray) -> np.ndarray:
        return (y - _hinge_design(x, np.array([p[3]]), average)[0] @ p[:3]) * w

    def jac(p: np.ndarray) -> np.ndarray:
        design = _hinge_design(x, np.array([p[3]]), average)[0]
        cols = np.column_stack((design, _hinge_break_column(x, p[3], p[1], p[2], average)))
        return -cols * w[:, None]

    p0 = np.array(start, dtype=np.float64)
    if not hi > lo:
        return (*start, chi2)
    p0[3] = min(max(p0[3], lo), hi)
    sol = least_squares(resid, p0, jac=jac, bounds=([-np.inf] * 3 + [lo], [np.inf] * 3 + [hi]),
                        xtol=1e-15, ftol=1e-15, gtol=1e-15)
    r = resid(sol.x)
    c2 = float(r @ r)
    if c2 <= chi2:
        return float(sol.x[0]), float(sol.x[1]), float(sol.x[2]), float(sol.x[3]), c2
    return (*start, chi2)


def _bin_distribution(
    x_distribution: tuple[np.ndarray, np.ndarray], n: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Check ``(sub_x, weights_per_bin)`` and return its parts.

    Returns the used sub-bins, the row-normalised averaging matrix (n, m') and a mask
    of the bins that have a distribution.
    """
    sub = np.asarray(x_distribution[0], dtype=np.float64).ravel()
    wts = np.asarray(x_distribution[1], dtype=np.float64)
    if wts.shape != (n, sub.size):
        raise InputFormatError(
            f"fit_two_segment: x_distribution weights must have shape (n bins, n sub-bins) "
            f"= ({n}, {sub.size}), got {wts.shape}", field="x_distribution")
    if np.any(wts < 0) or not np.all(np.isfinite(wts)):
        raise InputFormatError("fit_two_segment: x_distribution weights must be finite and "
                               ">= 0", field="x_distribution")
    used = wts.sum(axis=0) > 0
    if not np.all(np.isfinite(sub[used])):
        raise InputFormatError("fit_two_segment: x_distribution sub-bin abscissae of used "
                               "sub-bins must be finite", field="x_distribution")
    total = wts.sum(axis=1)
    has = total > 0
    with np.errstate(invalid="ignore", divide="ignore"):
        average = np.where(has[:, None], wts[:, used] / total[:, None], 0.0)
    return sub[used], average, has


def fit_two_segment(
    x: np.ndarray,
    y: np.ndarray,
    weights: np.ndarray | None = None,
    *,
    absolute_weights: bool = False,
    n_grid: int = 400,
    x_distribution: tuple[np.ndarray, np.ndarray] | None = None,
) -> TwoSegmentFit:
    """Fit two lines joined continuously at a free break (eq. 3a, 3b, 4).

    Parameters
    ----------
    x : ndarray, shape (n,)
        Bin coordinate (e.g. the bins' mean temperatures, C).  With ``x_distribution``
        it only orders the bins and bounds the break (between the second and the
        second-to-last bin).
    y : ndarray, shape (n,)
        Bin averages (e.g. offsets, counts).
    weights : ndarray, shape (n,), optional
        Amplitude weights (the seed uses ``sqrt(N)`` per bin).  Non-finite points and
        zero weights are dropped.
    absolute_weights : bool
        If True, ``weights = 1/sigma`` exactly and errors are not rescaled by chi2/dof.
    n_grid : int
        Break values tried before the bounded refinement.
    x_distribution : (sub_x, weights_per_bin), optional
        The distribution of the samples' coordinate inside each bin: ``sub_x`` shape
        (m,) the abscissae of fine sub-bins (e.g. their mean temperatures), and
        ``weights_per_bin`` shape (n, m) the samples of bin ``i`` in sub-bin ``k``.
        The model of bin ``i`` is then the bin average of the law,
        ``sum_k weights[i, k] f(sub_x[k]) / sum_k weights[i, k]``, instead of
        ``f(x[i])``: a bin average of the convex (or concave) two-segment law lies off
        the law at the bin's mean coordinate wherever the break falls inside the bin
        (docs/decisions/messenger_fit.md, entry 8).  Bins without weight are dropped.
        Without it, each bin is modelled at ``x`` (the seed's estimator).

    Returns
    -------
    TwoSegmentFit

    Raises
    ------
    FitError
        With fewer than 5 usable points.
    InputFormatError
        If ``x_distribution`` has the wrong shape or negative weights.

    Examples
    --------
    Table 2's X-axis line sampled at 10-C bin centres is recovered:

    >>> import numpy as np
    >>> t = np.arange(-65.0, 40.0, 10.0)
    >>> y = np.maximum(-10.802 + 1.2043 * t, 2.8435 + 2.5445 * t)
    >>> fit = fit_two_segment(t, y, np.ones(t.size))
    >>> print(f"{fit.a0:.3f} {fit.b0:.4f} {fit.a1:.4f} {fit.b1:.4f} {fit.x_m:.4f}")
    -10.802 1.2043 2.8435 2.5445 -10.1817

    Notes
    -----
    For a fixed break the model ``c + b0 min(x - x_m, 0) + b1 max(x - x_m, 0)`` (or its
    bin average over ``x_distribution``) is linear; chi2 is profiled over ``x_m`` on a
    grid between the second and the second-to-last point (each segment keeps at least
    two points), then refined by a bounded scalar minimisation around the best grid
    value.  Errors come from the Jacobian of all four parameters ``(c, b0, b1, x_m)`` at
    the optimum, propagated to ``(A0, B0, A1, B1, x_m)``.

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 7, eq. 3a, 3b, 4, Table 2.
    """
    n_in = np.asarray(x).size
    average = None
    has = None
    if x_distribution is not None:
        sub, average_all, has = _bin_distribution(x_distribution, n_in)
    x, y, w, index = _prepare(x, y, weights, 5, "fit_two_segment", extra_ok=has)
    lo, hi = x[1], x[-2]
    if not hi > lo:
        raise FitError("fit_two_segment: the points span no interval for a break")
    if x_distribution is not None:
        average = average_all[index]
        keep = average.sum(axis=0) > 0
        sx, average = sub[keep], average[:, keep]
    else:
        sx = x
    grid = np.linspace(lo, hi, n_grid)
    chi = _profile_chi2(_hinge_design(sx, grid, average), y, w)
    i = int(np.argmin(chi))
    a, b = grid[max(i - 1, 0)], grid[min(i + 1, n_grid - 1)]
    res = minimize_scalar(
        lambda g: _hinge_linear(sx, y, w, g, average)[1],
        bounds=(a, b),
        method="bounded",
        options={"xatol": 1e-10 * max(1.0, abs(hi - lo))},
    )
    xm = float(res.x) if res.fun <= chi[i] else float(grid[i])
    (c, b0, b1), chi2 = _hinge_linear(sx, y, w, xm, average)
    # Brent on chi2 resolves x_m only to ~sqrt(eps); Gauss-Newton on the residuals
    # (least_squares, x_m bounded to the same interval) takes it to ~eps.
    c, b0, b1, xm, chi2 = _polish_hinge(sx, y, w, (c, b0, b1, xm), chi2, lo, hi, average)
    jac = np.column_stack((_hinge_design(sx, np.array([xm]), average)[0],
                           _hinge_break_column(sx, xm, b0, b1, average)))
    dof = x.size - 4
    cov_p = _covariance(jac * w[:, None], chi2, dof, absolute_weights)
    a0, a1 = c - b0 * xm, c - b1 * xm
    # d(a0, b0, a1, b1, xm) / d(c, b0, b1, xm)
    tr = np.array(
        [
            [1.0, -xm, 0.0, -b0],
            [0.0, 1.0, 0.0, 0.0],
            [1.0, 0.0, -xm, -b1],
            [0.0, 0.0, 1.0, 0.0],
            [0.0, 0.0, 0.0, 1.0],
        ]
    )
    if np.all(np.isfinite(cov_p)):
        cov = tr @ cov_p @ tr.T
    else:
        # x_m not determined (equal slopes): report the slopes and intercepts of the
        # joined line with the break held, and an infinite error on the break.
        cov3 = _covariance(jac[:, :3] * w[:, None], chi2, x.size - 3, absolute_weights)
        cov = np.full((5, 5), np.inf)
        cov[:4, :4] = tr[:4, :3] @ cov3 @ tr[:4, :3].T
    err = _errors(cov)
    return TwoSegmentFit(
        a0=float(a0),
        b0=float(b0),
        a1=float(a1),
        b1=float(b1),
        x_m=xm,
        a0_err=float(err[0]),
        b0_err=float(err[1]),
        a1_err=float(err[2]),
        b1_err=float(err[3]),
        x_m_err=float(err[4]),
        covariance=cov,
        chi2=chi2,
        dof=dof,
    )


# -------------------------------------------------------------------------------------
# line through a fixed point (eq. 5a)
# -------------------------------------------------------------------------------------
@dataclass(frozen=True)
class LineFit:
    """A line ``y = intercept + slope x`` held through ``(x0, y0)`` (eq. 5a, Table 3 form).

    Attributes
    ----------
    slope, slope_err : float
        Table 3's D0 and its standard error.
    intercept : float
        Value at x = 0 (Table 3's C0 when ``x0 = 0``); exact, not fitted, when ``x0 = 0``.
    intercept_err : float
        Standard error of ``intercept`` (``|x0| slope_err``; 0 when x0 = 0).
    x0, y0 : float
        The fixed point.
    chi2 : float
    dof : int
        Points minus 1.
    """

    slope: float
    slope_err: float
    intercept: float
    intercept_err: float
    x0: float
    y0: float
    chi2: float
    dof: int

    def __call__(self, x: np.ndarray) -> np.ndarray:
        """Evaluate the line."""
        return self.y0 + self.slope * (np.asarray(x, dtype=np.float64) - self.x0)


def fit_line_fixed_intercept(
    x: np.ndarray,
    y: np.ndarray,
    weights: np.ndarray | None,
    x0: float,
    y0: float,
    *,
    absolute_weights: bool = False,
) -> LineFit:
    """Fit ``y = y0 + D (x - x0)``: a weighted line through a fixed point.

    Parameters
    ----------
    x, y : ndarray, shape (n,)
        Bin coordinate (duty cycle, ppt) and bin averages.
    weights : ndarray, shape (n,) or None
        Amplitude weights (``sqrt(N)`` per bin in the seed).
    x0, y0 : float
        The fixed point: ``x0 = 0`` and ``y0 = c_T(-50 C)`` for eq. 5a.
    absolute_weights : bool
        See `fit_two_segment`.

    Returns
    -------
    LineFit

    Notes
    -----
    Closed form: ``D = sum w^2 u v / sum w^2 u^2`` with ``u = x - x0``, ``v = y - y0``;
    ``var D = s^2 / sum w^2 u^2`` where ``s^2 = chi2/dof`` (relative weights) or 1.

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 7, eq. 5a, Table 3 ("the
       intercept at 0 duty cycle was held fixed to the -50 C values").
    """
    x, y, w, _ = _prepare(x, y, weights, 2, "fit_line_fixed_intercept")
    u, v, w2 = x - x0, y - y0, w * w
    suu = float(np.sum(w2 * u * u))
    if suu <= 0.0:
        raise FitError("fit_line_fixed_intercept: every point lies at x0; slope undetermined")
    slope = float(np.sum(w2 * u * v)) / suu
    r = (v - slope * u) * w
    chi2 = float(r @ r)
    dof = x.size - 1
    s2 = 1.0 if absolute_weights else chi2 / dof
    slope_err = float(np.sqrt(s2 / suu))
    return LineFit(
        slope=slope,
        slope_err=slope_err,
        intercept=float(y0 - slope * x0),
        intercept_err=float(abs(x0) * slope_err),
        x0=float(x0),
        y0=float(y0),
        chi2=chi2,
        dof=dof,
    )


# -------------------------------------------------------------------------------------
# relaxation after a step (sec. 7)
# -------------------------------------------------------------------------------------
@dataclass(frozen=True)
class RelaxationFit:
    """Exponential relaxation after a delayed step, optionally on a decaying background.

    ``y = y0 + A g + B h`` with ``g = 1 - exp(-max(lag - dt, 0) / tau)`` (the step,
    flat before ``dt``) and, only with ``prior_decay``, ``h = exp(-lag / tau)`` (what
    is left at lag 0 of the relaxations after earlier changes, same ``tau``).

    Attributes
    ----------
    tau, tau_err : float
        Relaxation time (s) and error.
    dt, dt_err : float
        Delay of the step (s); ``dt_err = 0`` when held.
    amplitude, amplitude_err : float
        Steady-state step ``A`` (per unit of the normalisation).
    y0, y0_err : float
        Asymptotic level before the step.
    prior_amplitude, prior_amplitude_err : float
        ``B`` (0 and 0 when ``prior_decay`` was False).
    fit_delay, prior_decay : bool
        Which optional parameters were fitted.
    covariance : ndarray
        Covariance of ``(y0, A[, B], tau[, dt])``.
    chi2 : float
    dof : int
    """

    tau: float
    tau_err: float
    dt: float
    dt_err: float
    amplitude: float
    amplitude_err: float
    y0: float
    y0_err: float
    fit_delay: bool
    covariance: np.ndarray
    chi2: float
    dof: int
    prior_amplitude: float = 0.0
    prior_amplitude_err: float = 0.0
    prior_decay: bool = False

    def __call__(self, lag: np.ndarray) -> np.ndarray:
        """Evaluate the model."""
        lag = np.asarray(lag, dtype=np.float64)
        lin = [self.y0, self.amplitude] + ([self.prior_amplitude] if self.prior_decay else [])
        return _relax_design(lag, self.tau, self.dt, self.prior_decay) @ np.array(lin)


def _relax_design(lag: np.ndarray, tau: float, dt: float, prior: bool) -> np.ndarray:
    """Columns ``(1, g[, h])`` of the model linear part, shape (n, 2 or 3)."""
    cols = [np.ones_like(lag), -np.expm1(-np.maximum(lag - dt, 0.0) / tau)]
    if prior:
        cols.append(np.exp(-lag / tau))
    return np.column_stack(cols)


def fit_relaxation(
    lag: np.ndarray,
    y: np.ndarray,
    weights: np.ndarray | None = None,
    *,
    fit_delay: bool = True,
    delay: float = 0.0,
    prior_decay: bool = False,
    absolute_weights: bool = False,
) -> RelaxationFit:
    """Fit an exponential relaxation to a normalised superposed epoch of steps.

    Parameters
    ----------
    lag : ndarray, shape (n,)
        Lag from the commanded change (s), e.g. the bin centres of a `superposed_epoch`
        over -200..1000 s.
    y : ndarray, shape (n,)
        Normalised epoch averages (offset change per unit duty-cycle step).
    weights : ndarray, shape (n,), optional
        Amplitude weights (``1 / standard error`` or ``sqrt(N)``).
    fit_delay : bool
        Fit the heater delay ``dt`` (sec. 7: 10 s); otherwise hold it at ``delay``.
    delay : float
        The held delay (s) when ``fit_delay`` is False, and ignored otherwise.
    prior_decay : bool
        Add ``B exp(-lag / tau)``: the still-running relaxation after earlier changes.
        With the controller's 1000-s evaluations the previous change lies 1000 s
        before each event and has relaxed only ``1 - exp(-1000/872) = 68 %``; its
        remainder (correlated with the normalised step) bends the pre-step baseline
        with the same ``tau``.  Off by default (the seed's flat-baseline reading).
    absolute_weights : bool
        See `fit_two_segment`.

    Returns
    -------
    RelaxationFit

    Raises
    ------
    FitError
        With too few points or no lag after the step.

    Notes
    -----
    Starting values are robust by construction: for fixed ``(tau, dt)`` the model is
    linear in ``(y0, A[, B])``, so chi2 is profiled on a log grid of ``tau`` (from the
    lag spacing to 20 times the span after the step) times a grid of ``dt`` (over the
    first third of the lags), and ``scipy.optimize.least_squares`` polishes all
    parameters (``tau`` as its logarithm) from the best grid point.  A ``tau`` much
    longer than the window is poorly determined (``A`` and ``tau`` trade off); the
    errors then say so.  Errors come from the analytic Jacobian at the optimum.

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 7 (1200-s superposed epoch
       starting 200 s before each duty-cycle change; tau = 872 s; dt = 10 s).
    """
    n_lin = 3 if prior_decay else 2
    n_par = n_lin + 1 + int(fit_delay)
    lag, y, w, _ = _prepare(lag, y, weights, n_par + 1, "fit_relaxation")
    span = float(lag[-1] - lag[0])
    if span <= 0:
        raise FitError("fit_relaxation: the lags span no interval")
    start = 0.0 if fit_delay else float(delay)
    if np.count_nonzero(lag > start) < 3:
        raise FitError("fit_relaxation: fewer than 3 points after the step")
    post_span = float(lag[-1] - max(start, lag[0]))
    step = float(np.median(np.diff(lag)))
    taus = np.geomspace(max(step, 1e-3 * post_span) / 2.0, 20.0 * post_span, 60)
    if fit_delay:
        dts = np.linspace(max(lag[0], -0.1 * post_span), lag[0] + 0.35 * span, 25)
    else:
        dts = np.array([float(delay)])
    tt, dd = (a.ravel() for a in np.meshgrid(taus, dts, indexing="ij"))
    g = -np.expm1(-np.maximum(lag[None, :] - dd[:, None], 0.0) / tt[:, None])
    cols = [np.ones_like(g), g]
    if prior_decay:
        cols.append(np.exp(-lag[None, :] / tt[:, None]))
    chi = _profile_chi2(np.stack(cols, axis=-1), y, w)
    k = int(np.argmin(chi))
    tau_s, dt_s = float(tt[k]), float(dd[k])
    design = _relax_design(lag, tau_s, dt_s, prior_decay)
    lin_s, *_ = np.linalg.lstsq(design * w[:, None], y * w, rcond=None)

    def unpack(p: np.ndarray) -> tuple[np.ndarray, float, float]:
        dt_p = float(p[n_lin + 1]) if fit_delay else float(delay)
        return p[:n_lin], float(np.exp(p[n_lin])), dt_p

    def resid(p: np.ndarray) -> np.ndarray:
        lin, tau_p, dt_p = unpack(p)
        return (y - _relax_design(lag, tau_p, dt_p, prior_decay) @ lin) * w

    p0 = np.concatenate((lin_s, [np.log(tau_s)], [dt_s] if fit_delay else []))
    lb = np.r_[np.full(n_lin, -np.inf), np.log(taus[0]) - 3, [lag[0] - span] if fit_delay else []]
    ub = np.r_[np.full(n_lin, np.inf), np.log(taus[-1]) + 3, [lag[-1]] if fit_delay else []]
    p0 = np.clip(p0, lb + 1e-12, ub - 1e-12)
    sol = least_squares(resid, p0, bounds=(lb, ub), x_scale="jac", xtol=1e-12, ftol=1e-12)
    lin, tau, dt = unpack(sol.x)
    r = resid(sol.x)
    chi2 = float(r @ r)
    # analytic Jacobian of the model in (y0, A[, B], tau[, dt]) for the covariance
    amp = float(lin[1])
    s = lag - dt
    after = s > 0
    e = np.where(after, np.exp(-np.maximum(s, 0.0) / tau), 1.0)
    jcols = list(_relax_design(lag, tau, dt, prior_decay).T)
    d_tau = np.where(after, -amp * e * s / tau**2, 0.0)
    if prior_decay:
        d_tau = d_tau + lin[2] * np.exp(-lag / tau) * lag / tau**2
    jcols.append(d_tau)
    if fit_delay:
        jcols.append(np.where(after, -amp * e / tau, 0.0))
    jac = np.column_stack(jcols) * w[:, None]
    dof = lag.size - n_par
    cov = _covariance(jac, chi2, dof, absolute_weights)
    err = _errors(cov)
    return RelaxationFit(
        tau=tau,
        tau_err=float(err[n_lin]),
        dt=dt,
        dt_err=float(err[n_lin + 1]) if fit_delay else 0.0,
        amplitude=amp,
        amplitude_err=float(err[1]),
        y0=float(lin[0]),
        y0_err=float(err[0]),
        fit_delay=fit_delay,
        covariance=cov,
        chi2=chi2,
        dof=dof,
        prior_amplitude=float(lin[2]) if prior_decay else 0.0,
        prior_amplitude_err=float(err[2]) if prior_decay else 0.0,
        prior_decay=prior_decay,
    )


# -------------------------------------------------------------------------------------
# periodic smoothing spline (sec. 6, Tables 6-8)
# -------------------------------------------------------------------------------------
@dataclass(frozen=True)
class PeriodicSplineFit:
    """A periodic smoothing cubic spline of a waveform over one cycle.

    Attributes
    ----------
    period : float
        Period (s).
    spline : scipy.interpolate.BSpline
        The fitted curve, ``extrapolate="periodic"`` (any time folds into the cycle);
        value, slope and curvature are continuous across the wrap.
    lam : float
        Smoothing parameter: the fit minimises ``sum w^2 r^2 / mean(w^2) +
        lam * integral over one period of f''^2``.
    n_knots : int
        Uniform knots over one period (also the number of free coefficients).
    coef_cov : ndarray, shape (n_knots, n_knots)
        Covariance of the periodic coefficients (scaled by chi2/dof unless
        ``absolute_weights``).
    phase : ndarray, shape (n,)
        The data phases (folded into ``[0, period)``, sorted).
    value_err : ndarray, shape (n,)
        Standard error of the fitted curve at ``phase``.
    chi2 : float
        ``sum (w r)**2``.
    dof : float
        ``n - trace(S)``, the effective residual degrees of freedom of the smoother.
    """

    period: float
    spline: BSpline
    lam: float
    n_knots: int
    coef_cov: np.ndarray
    phase: np.ndarray
    value_err: np.ndarray
    chi2: float
    dof: float

    def __call__(self, t: np.ndarray) -> np.ndarray:
        """Evaluate the waveform at cycle times ``t`` (folded by the period)."""
        return self.spline(np.mod(np.asarray(t, dtype=np.float64), self.period))

    def standard_error(self, t: np.ndarray) -> np.ndarray:
        """Return the standard error of the fitted curve at cycle times ``t``."""
        b = _periodic_design(np.atleast_1d(np.asarray(t, dtype=np.float64)), self.period,
                             self.n_knots)
        return np.sqrt(np.maximum(np.einsum("ij,jk,ik->i", b, self.coef_cov, b), 0.0))

    def table(self, step: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
        """Return ``(t, value)`` on ``t = 0, step, ..., period`` (Tables 6-8 form)."""
        t = np.arange(0.0, self.period + 0.5 * step, step)
        return t, self(t)


def _periodic_knots(period: float, m: int) -> np.ndarray:
    """Uniform cubic knot vector whose base interval ``[t[3], t[m+3]]`` is one period."""
    return (period / m) * np.arange(-3, m + 4, dtype=np.float64)


def _fold_columns(a: np.ndarray, m: int) -> np.ndarray:
    """Sum the m + 3 extended-basis columns into m periodic ones (column j -> j mod m)."""
    out = np.zeros((a.shape[0], m))
    for k in range(0, a.shape[1], m):  # m + 3 columns, m >= 4: two blocks, as np.add.at
        block = a[:, k:k + m]
        out[:, :block.shape[1]] += block
    return out


def _periodic_design(x: np.ndarray, period: float, m: int) -> np.ndarray:
    """Periodic cubic B-spline basis at ``x`` (folded into the period), shape (n, m)."""
    knots = _periodic_knots(period, m)
    xf = np.mod(x, period)
    xf = np.where(xf >= period, 0.0, xf)  # mod can round up to the period itself
    dm = BSpline.design_matrix(xf, knots, 3, extrapolate=False).toarray()
    return _fold_columns(dm, m)


@functools.lru_cache(maxsize=16)
def _periodic_penalty(period: float, m: int) -> np.ndarray:
    """``Omega[i, j] = integral over one period of B_i'' B_j''`` (periodic basis).

    The second derivatives are linear on each knot interval, so two-point
    Gauss-Legendre per interval is exact.  Cached (read-only): a waveform fit asks for
    the same period and knots per axis and duty-cycle bin, every pass.
    """
    knots = _periodic_knots(period, m)
    h = period / m
    g = np.array([-1.0, 1.0]) / np.sqrt(3.0)
    left = h * np.arange(m)
    xq = (left[:, None] + 0.5 * h * (1.0 + g[None, :])).ravel()
    basis = BSpline(knots, np.eye(m + 3), 3, extrapolate=False)
    d2 = _fold_columns(np.nan_to_num(basis.derivative(2)(xq)), m)
    omega = (d2.T * (0.5 * h)) @ d2  # both Gauss weights are 1, times h/2
    omega.flags.writeable = False
    return omega


def fit_periodic_spline(
    phase: np.ndarray,
    y: np.ndarray,
    weights: np.ndarray | None,
    period: float,
    smoothing: float | None = None,
    *,
    n_knots: int | None = None,
    absolute_weights: bool = False,
) -> PeriodicSplineFit:
    """Fit a periodic smoothing spline to a waveform over one cycle.

    Parameters
    ----------
    phase : ndarray, shape (n,)
        Cycle time of each point (s), e.g. the bin centres or mean phases of
        `phase_binned`; folded into ``[0, period)``.  Repeated phases are allowed.
    y : ndarray, shape (n,)
        Values (bin averages, or samples).
    weights : ndarray, shape (n,) or None
        Amplitude weights (``sqrt(N)`` or ``1/standard error``).
    period : float
        Period (s), 100 s for the heater of seed 000.
    smoothing : float, optional
        ``lam`` of the objective ``sum w^2 r^2 / mean(w^2) + lam * integral f''^2``.
        Default: chosen by generalised cross-validation (GCV).
    n_knots : int, optional
        Uniform knots per period.  Default: the number of distinct phases, at most 200
        (100 for the 1-s bins of Tables 6-8: the full smoothing spline).
    absolute_weights : bool
        See `fit_two_segment`.

    Returns
    -------
    PeriodicSplineFit

    Raises
    ------
    FitError
        With fewer than 5 points or more knots than distinct phases.

    Notes
    -----
    Penalised regression on a periodic cubic B-spline basis (uniform knots, the
    extended basis folded modulo the number of knots), so the curve and its first two
    derivatives are continuous across the wrap by construction.  For a given ``lam``
    the coefficients solve ``(B' W B + lam' Omega) c = B' W y`` with ``Omega`` the
    exact Gram matrix of second derivatives.  GCV: ``n RSS_w / (n - trace S)^2`` with
    ``trace S = trace((B' W B + lam' Omega)^-1 B' W B)``, minimised over log lam on a
    grid, then by bounded Brent; a Demmler-Reinsch diagonalisation makes each lam
    O(n m).  Errors: ``cov(c) = s^2 M^-1 B' W B M^-1``.

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 6 and Appendix Tables 6-8.
    .. [2] P. Craven, G. Wahba, "Smoothing noisy data with spline functions",
       Numer. Math. 31 (1979) 377-403 (GCV).
    """
    return fit_periodic_splines(phase, [y], weights, period, smoothing, n_knots=n_knots,
                                absolute_weights=absolute_weights)[0]


def fit_periodic_splines(
    phase: np.ndarray,
    ys: Sequence[np.ndarray],
    weights: np.ndarray | None,
    period: float,
    smoothing: float | None = None,
    *,
    n_knots: int | None = None,
    absolute_weights: bool = False,
) -> list[PeriodicSplineFit]:
    """`fit_periodic_spline` of each of ``ys`` on the same ``phase`` and ``weights``.

    The design matrix, the Cholesky factor and the Demmler-Reinsch eigenvectors depend
    on the points and weights, not on the values: they are computed once for every
    ``y`` whose usable points (finite, positive weight) are the same, and each fit is
    the one `fit_periodic_spline` returns for that ``y`` alone, bit for bit (the same
    arithmetic on the same numbers): e.g. the three axes of a sensor sampled on one
    phase grid with one weighting.

    Parameters
    ----------
    phase, weights, period, smoothing, n_knots, absolute_weights
        As `fit_periodic_spline`.
    ys : sequence of ndarray, each shape (n,)
        The values of each fit.

    Returns
    -------
    list of PeriodicSplineFit
        One per ``ys``, in order.

    Raises
    ------
    FitError, InputFormatError
        As `fit_periodic_spline`, for the first ``y`` that fails.

    References
    ----------
    .. [1] MESSENGER MAG EDR-to-CDR Processing v2i, sec. 6 and Appendix Tables 6-8.
    """
    if not (np.isfinite(period) and period > 0):
        raise InputFormatError(f"period must be positive, got {period}", field="period")
    phase = np.mod(np.asarray(phase, dtype=np.float64).ravel(), period)
    out = []
    shared: tuple[np.ndarray, np.ndarray, _PeriodicSmoother] | None = None
    for y in ys:
        x, yy, w, _ = _prepare(phase, y, weights, 5, "fit_periodic_spline")
        if shared is None or not (np.array_equal(shared[0], x)
                                  and np.array_equal(shared[1], w)):
            shared = (x, w, _periodic_smoother(x, w, period, n_knots))
        out.append(_periodic_fit(shared[2], x, yy, w, period, smoothing, absolute_weights))
    return out


@dataclass(frozen=True)
class _PeriodicSmoother:
    """The value-free part of a periodic smoothing spline (`_periodic_smoother`)."""

    m: int
    b: np.ndarray
    w2: np.ndarray
    mu: np.ndarray
    v: np.ndarray
    bv: np.ndarray


def _periodic_smoother(x: np.ndarray, w: np.ndarray, period: float,
                       n_knots: int | None) -> _PeriodicSmoother:
    """Design, weights and Demmler-Reinsch basis of prepared points ``x``, ``w``."""
    distinct = np.unique(x).size
    m = min(distinct, 200) if n_knots is None else int(n_knots)
    if m < 4 or m > distinct:
        raise FitError(
            f"fit_periodic_spline: {m} knots need between 4 and the {distinct} distinct "
            "phases given"
        )
    w2 = w * w / np.mean(w * w)
    b = _periodic_design(x, period, m)
    btwb = (b.T * w2) @ b
    omega = _periodic_penalty(period, m)
    # Demmler-Reinsch: with G = B'WB + Omega = L L' (positive definite: Omega's null
    # space, the constants, is seen by every point) and L^-1 Omega L^-T = U diag(mu) U',
    # M(lam) = B'WB + lam Omega = L U diag(1 + (lam - 1) mu) U' L'.  One Cholesky and
    # one eigh; every lam afterwards costs O(n m).
    try:
        chol = cholesky(btwb + omega, lower=True)
    except np.linalg.LinAlgError as exc:
        raise FitError(f"fit_periodic_spline: ill-posed system ({exc})") from exc
    k_mat = solve_triangular(chol, solve_triangular(chol, omega, lower=True).T, lower=True)
    mu, u = eigh(0.5 * (k_mat + k_mat.T))
    mu = np.clip(mu, 0.0, 1.0)
    v = solve_triangular(chol.T, u, lower=False)  # L^-T U
    return _PeriodicSmoother(m=m, b=b, w2=w2, mu=mu, v=v, bv=b @ v)


def _periodic_fit(sm: _PeriodicSmoother, x: np.ndarray, yy: np.ndarray, w: np.ndarray,
                  period: float, smoothing: float | None,
                  absolute_weights: bool) -> PeriodicSplineFit:
    """Fit the spline of values ``yy`` at the smoother's points (`fit_periodic_spline`)."""
    n, m, b, w2, mu, v, bv = x.size, sm.m, sm.b, sm.w2, sm.mu, sm.v, sm.bv
    z = v.T @ ((b.T * w2) @ yy)

    def diag(lam: float) -> np.ndarray:
        return 1.0 + (lam - 1.0) * mu

    def gcv(log_lam: float) -> float:
        d = diag(float(np.exp(log_lam)))
        r = yy - bv @ (z / d)
        tr = float(np.sum((1.0 - mu) / d))
        return float(n * np.sum(w2 * r * r) / max(n - tr, 1e-9) ** 2)

    if smoothing is None:
        lam = _gcv_lambda(gcv, period)
    else:
        lam = float(smoothing)
        if not lam >= 0:
            raise InputFormatError(f"smoothing must be >= 0, got {smoothing}", field="smoothing")
    d = diag(lam)
    if np.any(d <= 1e-12 * np.max(d)):
        raise FitError(
            f"fit_periodic_spline: lam={lam:g} leaves coefficients undetermined (knot "
            "intervals without data); use smoothing > 0 or fewer knots"
        )
    coef = v @ (z / d)
    r = (yy - b @ coef) * w
    chi2 = float(r @ r)
    dof = float(n - np.sum((1.0 - mu) / d))
    # cov(c) = M^-1 B'W Sigma W B M^-1, Sigma = s^2 diag(1/w^2), W = diag(w^2)/mean(w^2)
    s2 = 1.0 if absolute_weights else (chi2 / dof if dof > 0 else np.inf)
    coef_cov = (s2 / np.mean(w * w)) * ((v * ((1.0 - mu) / d**2)) @ v.T)
    value_err = np.sqrt(np.maximum(np.sum((b @ coef_cov) * b, axis=1), 0.0))
    spline = BSpline(_periodic_knots(period, m), coef[np.arange(m + 3) % m], 3,
                     extrapolate="periodic")
    return PeriodicSplineFit(
        period=float(period), spline=spline, lam=float(lam), n_knots=m, coef_cov=coef_cov,
        phase=x, value_err=value_err, chi2=chi2, dof=dof,
    )


def _gcv_lambda(score: Callable[[float], float], period: float) -> float:
    """``lam`` minimising the GCV score (Craven & Wahba 1979) over log lam."""
    # the penalty integral scales as period**-3: cover interpolation .. a constant
    base = np.log(period**3)
    grid = base + np.linspace(np.log(1e-12), np.log(1e6), 55)
    scores = np.array([score(g) for g in grid])  # a grid of lam values, not samples
    k = int(np.argmin(scores))
    a, c = grid[max(k - 1, 0)], grid[min(k + 1, grid.size - 1)]
    res = minimize_scalar(score, bounds=(a, c), method="bounded", options={"xatol": 1e-3})
    return float(np.exp(res.x if res.fun <= scores[k] else grid[k]))
