"""In-flight calibration of RPC-MAG: daily extended temperature model and offset jumps.

Two fits that *make* the tables the pipeline applies (issue 13):

- `fit_extended_model`: the daily polynomial ``P_0 .. P_5`` of the extended temperature
  model 006 (seed 003, sec. 4.2.3.3) from a day of ground-calibrated LEVEL_A data: the
  field of calm phases "fitted against the temperature by the means of a 3rd order
  polynomial", so that the offset-free field averages to zero (the ambient field of calm
  phases has no long-term mean); `write_daily_model` writes it as the daily
  ``RPCMAG_<yymmdd>_006_CALIB_<IB|OB>.TXT`` file that ``rosetta calibrate --calib`` reads.
- `fit_offset_jumps`: the post-hibernation offsets of Appendix B (sec. 4.2.3.4): per
  interval, the constant offset in s/c coordinates that makes the long-term average of
  ``B_z`` in CSEQ zero and removes the correlation of the CSEQ field with the spacecraft
  rotation; `write_offset_jump_table` writes them in the columns of
  ``RPCMAG_OFFSET_JUMPS.csv``.

Both reduce the data to time blocks (count, mean) first: the ambient field is correlated
over minutes to hours, so the block means, not the samples, are the independent
measurements; parameter uncertainties come from the scatter of the block means about the
fit (docs/decisions/rosetta_fit.md).  Pure functions: arrays and Datasets in, estimates
with uncertainties out; no I/O except the two writers.

References
----------
.. [1] I. Richter, "Step by Step Calibration Procedure for RPC-MAG Data", RO-IGEP-TR0028
   issue 3 rev. 1 (2015) (seed 003), sec. 4.2.3.3, 4.2.3.4, Appendix B.
"""

from __future__ import annotations

import datetime as dt
import logging
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import xarray as xr
from numpy.polynomial import polynomial as npoly

from fluxcal.calibration.binned_stats import BinnedMoments
from fluxcal.errors import FluxcalError
from fluxcal.geometry.time import tt2000_to_utc, utc_to_tt2000
from fluxcal.missions.rosetta.calib import (
    DailyOffsetModel,
    GroundCalibration,
    check_sensor,
    write_daily_offset_model,
)
from fluxcal.products.atomic import atomic_write_bytes
from fluxcal.products.provenance import portable_text

log = logging.getLogger(__name__)

NS = 1_000_000_000
KELVIN = 273.15
#: Highest polynomial degree of the daily files (six parameters P_0 .. P_5, sec. 4.2.3.3).
MAX_DEGREE = 5
#: Default degree: "usually only polynomials up to 3rd order are used" (sec. 4.2.3.3).
DEFAULT_DEGREE = 3
#: Default block length (s) of the extended-model fit (decision 1 of rosetta_fit.md).
MODEL_BLOCK_S = 1800.0
#: Default block length (s) of the offset-jump fit.
JUMP_BLOCK_S = 1800.0
#: Largest standard error (nT) of a fitted jump accepted by default (decision 4).
JUMP_MAX_SIGMA = 1.0


# ----------------------------------------------------------------------------------------
# Block reduction and weighted least squares
# ----------------------------------------------------------------------------------------
def block_means(
    epoch: np.ndarray, values: np.ndarray, block_s: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per-block count, mean and standard error of the mean of ``values`` (columns).

    Blocks are ``[t0 + k block_s, t0 + (k + 1) block_s)`` with ``t0`` the first epoch;
    empty blocks are dropped.  The reduction is `fluxcal.calibration.binned_stats`'s
    (sufficient statistics, exact merges).

    Parameters
    ----------
    epoch : ndarray of int64, shape (n,)
        TT2000 ns.
    values : ndarray, shape (n, m)
    block_s : float
        Block length (s), > 0.

    Returns
    -------
    count : ndarray, shape (b,)
    mean : ndarray, shape (b, m)
    standard_error : ndarray, shape (b, m)
        ``sqrt(sample variance / count)``; NaN for a block of one sample.
    """
    if not block_s > 0:
        raise FluxcalError(f"block length must be positive, not {block_s} s")
    epoch = np.asarray(epoch, dtype=np.int64)
    values = np.asarray(values, dtype=float)
    if epoch.size == 0:
        empty = np.zeros((0, values.shape[1]))
        return np.zeros(0), empty, empty
    seconds = (epoch - epoch.min()) / NS
    edges = np.arange(int(seconds.max() // block_s) + 2) * float(block_s)
    moments = BinnedMoments.accumulate(seconds, values, edges, label="time", units="s")
    keep = moments.count > 0
    return (moments.count[keep].astype(float), moments.mean()[keep],
            moments.standard_error()[keep])


def weighted_lstsq(
    design: np.ndarray, target: np.ndarray, weight: np.ndarray, *, what: str
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Weighted least squares with the covariance from the residual scatter.

    Minimises ``sum w (target - design @ q)^2``.  The unit variance is estimated from the
    weighted residuals, ``s^2 = sum w r^2 / (N - p)``, and ``cov = s^2 (A^T W A)^-1``
    (the block means' scatter is the measured noise; Bevington & Robinson, "Data
    Reduction and Error Analysis", ch. 7, eq. 7.27 with the sample variance).

    Parameters
    ----------
    design : ndarray, shape (N, p)
    target : ndarray, shape (N,)
    weight : ndarray, shape (N,)
    what : str
        Names the fit in errors.

    Returns
    -------
    q : ndarray, shape (p,)
    cov : ndarray, shape (p, p)
    residual : ndarray, shape (N,)

    Raises
    ------
    FluxcalError
        Fewer equations than parameters + 1, or a rank-deficient design.
    """
    n, p = design.shape
    if n < p + 1:
        raise FluxcalError(
            f"{what}: {n} block(s) for {p} parameter(s); need at least {p + 1} "
            "(more data, shorter blocks or a lower degree)"
        )
    sw = np.sqrt(np.asarray(weight, dtype=float))
    a = design * sw[:, None]
    q, _, rank, sv = np.linalg.lstsq(a, target * sw, rcond=None)
    if rank < p:
        raise FluxcalError(
            f"{what}: the data do not determine all {p} parameters (rank {rank}); "
            "the temperature or attitude does not vary enough"
        )
    residual = target - design @ q
    s2 = float(np.sum(weight * residual**2) / (n - p))
    cov = s2 * np.linalg.inv(a.T @ a)
    return q, cov, residual


# ----------------------------------------------------------------------------------------
# Extended temperature model (sec. 4.2.3.3)
# ----------------------------------------------------------------------------------------
@dataclass(frozen=True)
class DailyModelFit:
    """Fitted daily extended-temperature polynomial of one sensor, with its statistics.

    The polynomial variable is the reduced temperature ``T~`` (deg C) of sec. 4.2.3.3.
    Internally the fit is made in ``x = (T~ - centre) / scale`` (well conditioned);
    ``coefficients`` are the power-basis ``P_k`` the daily file holds.

    Attributes
    ----------
    day : numpy.datetime64[D]
    sensor : str
    degree : int
    coefficients : ndarray, shape (6, 3)
        ``P_0 .. P_5`` (x, y, z; nT per deg C^k); zero above ``degree``.
    sigma : ndarray, shape (6, 3)
        Standard errors of ``coefficients`` (0 above ``degree``).
    centre, scale : float
        Of the fit variable ``x``.
    q : ndarray, shape (degree + 1, 3)
        Coefficients in ``x``.
    covariance_q : ndarray, shape (3, degree + 1, degree + 1)
        Covariance of ``q`` per axis.
    temperature_range : tuple of float
        Smallest and largest ``T~`` of the data (deg C): where the model is determined.
    n_samples, n_blocks : int
    block_s : float
    rms : ndarray, shape (3,)
        Weighted rms of the block-mean residuals (nT).
    chi2 : ndarray, shape (3,)
        Sum of squared block-mean residuals over their within-block standard errors
        (blocks with >= 2 samples); ``chi2 / dof`` >> 1 says the ambient field varies on
        scales longer than a block (expected), which the covariance accounts for.
    dof : int
        ``n_blocks - degree - 1``.
    noise : ndarray, shape (3,), optional
        Median within-block standard deviation of the field (nT): the fluctuation level
        block means of a calm, zero-mean field scatter well below (`fit_warnings`).
    estimator : str
        ``"zero-mean"`` (this module: the day's field averages to zero) or
        ``"variance"`` (`fluxcal.missions.rosetta.fit_variance`: ``|B|`` nearly constant
        within intervals); docs/decisions/rosetta_fit.md.
    """

    day: np.datetime64
    sensor: str
    degree: int
    coefficients: np.ndarray
    sigma: np.ndarray
    centre: float
    scale: float
    q: np.ndarray
    covariance_q: np.ndarray
    temperature_range: tuple[float, float]
    n_samples: int
    n_blocks: int
    block_s: float
    rms: np.ndarray
    chi2: np.ndarray
    dof: int
    notes: dict = field(default_factory=dict)
    noise: np.ndarray | None = None
    estimator: str = "zero-mean"

    def offset(self, temperature: np.ndarray) -> np.ndarray:
        """Return the fitted offset ``P(T~)`` (nT), shape (n, 3)."""
        x = (np.asarray(temperature, dtype=float) - self.centre) / self.scale
        return np.vander(x, self.degree + 1, increasing=True) @ self.q

    def offset_sigma(self, temperature: np.ndarray) -> np.ndarray:
        """Return the standard error of `offset` (nT), shape (n, 3), from the fit covariance."""
        x = (np.asarray(temperature, dtype=float) - self.centre) / self.scale
        g = np.vander(x, self.degree + 1, increasing=True)
        return np.sqrt(np.stack([np.einsum("ij,jk,ik->i", g, c, g)
                                 for c in self.covariance_q], axis=1))

    def to_model(self, source: str = "") -> DailyOffsetModel:
        """Return the `DailyOffsetModel` the pipeline applies, with its range and error.

        ``curve_sigma``: the largest stated error of the curve over the fitted range.
        """
        grid = np.linspace(*self.temperature_range, 101)
        return DailyOffsetModel(self.day, self.sensor, self.coefficients.copy(), source,
                                temperature_range=tuple(map(float, self.temperature_range)),
                                curve_sigma=self.offset_sigma(grid).max(axis=0))


def reduced_temperature(level_a: xr.Dataset, calibration: GroundCalibration) -> np.ndarray:
    """Reduced temperature ``T~`` (deg C) of each LEVEL_A vector, the polynomial's variable.

    LEVEL_A carries the calibrated sensor temperature ``T^c`` in K; ``T~`` follows the
    ground file's ``REDUCED_TEMPERATURE`` reading (docs/decisions/rosetta.md, decision 26).

    References
    ----------
    .. [1] RO-IGEP-TR0028 (seed 003), sec. 4.2.3.3 ("the reduced temperature
       ``T~ = T_s - T_s^O`` has to be used").
    """
    return calibration.extended_model_temperature(level_a["temperature"].values - KELVIN)


def _power_basis(centre: float, scale: float, degree: int) -> np.ndarray:
    """Matrix ``C`` with ``p = C q``: power coefficients in T of ``sum q_k ((T-c)/s)^k``."""
    c = np.zeros((degree + 1, degree + 1))
    for k in range(degree + 1):  # loop over polynomial orders, not samples
        col = npoly.polypow([-centre / scale, 1.0 / scale], k)
        c[: col.size, k] = col
    return c


def fit_extended_model(
    level_a: xr.Dataset,
    temperature: np.ndarray,
    *,
    degree: int = DEFAULT_DEGREE,
    block_s: float = MODEL_BLOCK_S,
    day: np.datetime64 | str | None = None,
) -> DailyModelFit:
    """Fit the daily extended-temperature polynomial ``P_0 .. P_5`` (sec. 4.2.3.3).

    The ground-calibrated field ``B^c = B_amb + P(T~)`` is fitted per axis by a polynomial
    of degree ``degree`` in ``T~``: the offset is the part of the field that follows the
    temperature, and the constant ``P_0`` is fixed by the criterion that the ambient field
    of calm phases has no long-term mean (the offset-free field averages to zero over the
    day).  The data are reduced to blocks of ``block_s``: the block mean of the field is
    fitted by the block means of ``T~^k`` (exact for a polynomial, however the temperature
    varies within the block), with count weights (``sqrt(N)`` weights on the means) and
    the covariance from the residual scatter of the block means (`weighted_lstsq`).

    Parameters
    ----------
    level_a : xarray.Dataset
        LEVEL_A of one sensor from the *ground calibration alone* (`level_a.level_a`
        without daily models): ``b`` (nT, URF), ``epoch``; attributes ``sensor``,
        ``level``.
    temperature : ndarray, shape (n,)
        Reduced temperature ``T~`` (deg C) of each vector (`reduced_temperature`).
    degree : int
        Polynomial degree, 0 .. 5 (default 3, as the seed usually uses).
    block_s : float
        Block length (s); choose it at least as long as the correlation time of the
        ambient field (default 1800 s).
    day : datetime64[D] or str, optional
        Day of the file; default the UTC day of the first vector.

    Returns
    -------
    DailyModelFit

    Raises
    ------
    FluxcalError
        Not LEVEL_A, a daily model already applied, degree out of range, too few blocks,
        temperature range too narrow for the degree (rank deficient), a field or
        temperature that is not finite.

    References
    ----------
    .. [1] RO-IGEP-TR0028 (seed 003), sec. 4.2.3.3 (daily polynomials ``p_{s,k,i}``, six
       parameters per component, "usually ... up to 3rd order"; calm phases).
    """
    source = level_a.attrs.get("source", "LEVEL_A dataset")
    if str(level_a.attrs.get("level", "A")) != "A":
        raise FluxcalError(
            f"{source}: the extended model is fitted on LEVEL_A (URF, where the daily "
            f"file applies), not LEVEL_{level_a.attrs.get('level')}"
        )
    applied = str(level_a.attrs.get("extended_temperature_model", "none"))
    if applied.startswith("model 006"):
        raise FluxcalError(
            f"{source}: LEVEL_A already has a daily model subtracted ({applied}); fit the "
            "ground-calibrated field (level_a without daily models)"
        )
    if not 0 <= int(degree) <= MAX_DEGREE:
        raise FluxcalError(f"degree {degree}: the daily files hold degrees 0 .. {MAX_DEGREE}")
    degree = int(degree)
    sensor = check_sensor(level_a.attrs.get("sensor", ""))
    b = np.asarray(level_a["b"].values, dtype=float)
    t = np.asarray(temperature, dtype=float)
    epoch = np.asarray(level_a["epoch"].values, dtype=np.int64)
    if t.shape != (b.shape[0],):
        raise FluxcalError(f"{source}: {t.size} temperatures for {b.shape[0]} vectors")
    bad = ~(np.isfinite(t) & np.isfinite(b).all(axis=1))
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise FluxcalError(f"{source}: vector {i} has a non-finite field or temperature")
    if day is None:
        day = str(tt2000_to_utc(epoch[:1], digits=0)[0])[:10]
    day = np.datetime64(day, "D")
    lo, hi = (float(t.min()), float(t.max())) if t.size else (0.0, 0.0)
    centre, scale = 0.5 * (lo + hi), max(0.5 * (hi - lo), 1.0)
    x = (t - centre) / scale
    powers = np.vander(x, degree + 1, increasing=True)
    count, mean, se = block_means(epoch, np.concatenate([b, powers], axis=1), block_s)
    design = mean[:, 3:]
    what = f"{source}: extended model {sensor} {day} (degree {degree}, {block_s:g}-s blocks)"
    q = np.zeros((degree + 1, 3))
    cov = np.zeros((3, degree + 1, degree + 1))
    rms, chi2 = np.zeros(3), np.zeros(3)
    multi = count >= 2
    for i in range(3):  # three axes
        q[:, i], cov[i], r = weighted_lstsq(design, mean[:, i], count, what=what)
        rms[i] = np.sqrt(np.sum(count * r**2) / np.sum(count))
        se2 = np.maximum(se[multi, i] ** 2, 1e-12)
        chi2[i] = float(np.sum(r[multi] ** 2 / se2))
    noise = (np.median(se[multi, :3] * np.sqrt(count[multi])[:, None], axis=0)
             if multi.any() else np.full(3, np.nan))
    c = _power_basis(centre, scale, degree)
    coefficients = np.zeros((MAX_DEGREE + 1, 3))
    sigma = np.zeros((MAX_DEGREE + 1, 3))
    coefficients[: degree + 1] = c @ q
    for i in range(3):
        sigma[: degree + 1, i] = np.sqrt(np.diag(c @ cov[i] @ c.T))
    return DailyModelFit(
        day=day, sensor=sensor, degree=degree, coefficients=coefficients, sigma=sigma,
        centre=centre, scale=scale, q=q, covariance_q=cov, temperature_range=(lo, hi),
        n_samples=int(b.shape[0]), n_blocks=int(count.size), block_s=float(block_s),
        rms=rms, chi2=chi2, dof=int(count.size - degree - 1),
        notes={"source": str(source)}, noise=noise,
    )


#: A fit whose block-mean residual rms exceeds this multiple of the within-block standard
#: deviation (`DailyModelFit.noise`) is reported (docs/decisions/rosetta_fit.md, issue 23).
RESIDUAL_NOISE_FACTOR = 1.75


def fit_warnings(fit: DailyModelFit, factor: float = RESIDUAL_NOISE_FACTOR) -> list[str]:
    """Say where the fit's residuals are far above the noise (the criterion does not hold).

    The daily model assumes the offset-free field averages to zero over the fit's blocks
    (a calm phase, sec. 4.2.3.3).  Block means of such a field scatter well below its
    within-block standard deviation; a block-mean residual rms above ``factor`` times
    that deviation says the ambient field (or an unmodelled offset) did not average out,
    and the fitted offsets hold it.  Returns one message per such axis (none: empty).

    References
    ----------
    .. [1] RO-IGEP-TR0028 (seed 003), sec. 4.2.3.3 (daily fit from calm phases).
    """
    if fit.noise is None:
        return []
    out = []
    for axis, (rms, noise) in enumerate(zip(fit.rms, fit.noise, strict=True)):
        if np.isfinite(noise) and rms > factor * noise:
            out.append(
                f"{fit.sensor} {fit.day} {'xyz'[axis]}: block-mean residual rms {rms:.3g} nT "
                f"is {rms / max(noise, 1e-12):.1f} x the within-block standard deviation "
                f"{noise:.3g} nT: the field did not average to zero over the "
                f"{fit.block_s:g}-s blocks (not a calm phase?); check the offsets before use"
            )
    return out


def write_daily_model(
    fit: DailyModelFit,
    out_dir: Path,
    day: np.datetime64 | str | None = None,
    sensor: str | None = None,
    *,
    provenance: dict | None = None,
) -> Path:
    """Write ``fit`` as ``RPCMAG_<yymmdd>_006_CALIB_<sensor>.TXT`` in ``out_dir``.

    The format `calib.read_daily_offset_model` reads (keys ``SENSOR``, ``P_0`` .. ``P_5``,
    ``T_RANGE`` (fitted reduced temperatures) and ``SIGMA_CURVE`` (the curve's largest
    1-sigma over them)) with ``#`` comment lines recording the fit: inputs, degree, blocks,
    temperature range, residual rms, chi2, the standard error of every coefficient and the
    estimator's notes (curve error, figure of merit, convergence).

    Raises
    ------
    FluxcalError
        ``day`` or ``sensor`` contradict the fit.
    """
    day = fit.day if day is None else np.datetime64(day, "D")
    sensor = fit.sensor if sensor is None else check_sensor(sensor)
    if day != fit.day or sensor != fit.sensor:
        raise FluxcalError(
            f"the fit is for {fit.sensor} {fit.day}, not {sensor} {day}: refusing to write it "
            "under another day or sensor"
        )
    vec = lambda v: " ".join(f"{float(x):.6g}" for x in v)  # noqa: E731
    warnings = fit_warnings(fit)
    for text in warnings:
        log.warning("%s", text)
    lines = [
        "fitted by fluxcal rosetta fit (issue 13; docs/decisions/rosetta_fit.md)",
        f"written {dt.datetime.now(dt.UTC).strftime('%Y-%m-%dT%H:%M:%SZ')}",
        (f"criterion: offset-free field averages to zero (calm phase), "
         f"degree {fit.degree}, {fit.block_s:g}-s blocks, count weights"
         if fit.estimator == "zero-mean" else
         f"criterion ({fit.estimator}): least within-interval variance of |B| (rotations "
         f"at nearly constant |B|), degree {fit.degree}, {fit.block_s:g}-s intervals"),
        f"samples {fit.n_samples}, blocks {fit.n_blocks}, dof {fit.dof}",
        f"reduced temperature range {fit.temperature_range[0]:.2f} .. "
        f"{fit.temperature_range[1]:.2f} degC (the model is determined only there)",
        f"block-mean residual rms x y z (nT): {vec(fit.rms)}",
        f"chi2 vs within-block errors x y z: {vec(fit.chi2)}",
        *([f"within-block standard deviation x y z (nT): {vec(fit.noise)}"]
          if fit.noise is not None else []),
        *(f"warning: {w}" for w in warnings),
        *(f"sigma P_{k} x y z: {vec(fit.sigma[k])}" for k in range(fit.degree + 1)),
        # file names only: no folder of the machine that made it (README, provenance)
        *(f"{k}: {portable_text(str(v))}"
          for k, v in {**fit.notes, **(provenance or {})}.items()),
    ]
    model = fit.to_model()
    return write_daily_offset_model(model, Path(out_dir), comments=lines)


# ----------------------------------------------------------------------------------------
# Offset jumps (sec. 4.2.3.4, Appendix B)
# ----------------------------------------------------------------------------------------
@dataclass(frozen=True)
class OffsetJumpFit:
    """Fitted post-hibernation offsets of one sensor, one row per interval.

    Attributes
    ----------
    sensor : str
    start_utc, end_utc : ndarray of str
        Intervals ``[start, end)`` (UTC, ISO).
    jumps : ndarray, shape (m, 3)
        Offset in s/c coordinates (nT) to subtract from LEVEL_B (Appendix B form).
    sigma : ndarray, shape (m, 3)
        Standard errors (nT).
    mean_field : ndarray, shape (m, 2)
        Fitted long-term mean of the CSEQ ``B_x``, ``B_y`` (nT; ``B_z`` is held at 0).
    rms : ndarray, shape (m,)
        Weighted rms of the block-mean residuals (nT).
    n_blocks, n_samples : ndarray of int, shape (m,)
    block_s : float
    estimator : str
        ``"zero-mean"`` (`fit_offset_jumps`) or ``"variance"``
        (`fluxcal.missions.rosetta.fit_variance.fit_offset_jumps_variance`).
    """

    sensor: str
    start_utc: np.ndarray
    end_utc: np.ndarray
    jumps: np.ndarray
    sigma: np.ndarray
    mean_field: np.ndarray
    rms: np.ndarray
    n_blocks: np.ndarray
    n_samples: np.ndarray
    block_s: float
    estimator: str = "zero-mean"


def fit_offset_jumps(
    epoch: np.ndarray,
    b_sc: np.ndarray,
    rotation: np.ndarray,
    start_utc: np.ndarray,
    end_utc: np.ndarray,
    *,
    sensor: str,
    block_s: float = JUMP_BLOCK_S,
    max_sigma: float | None = JUMP_MAX_SIGMA,
    lsk=None,
) -> OffsetJumpFit:
    """Fit the Appendix B offset of each interval (sec. 4.2.3.4).

    In an interval the LEVEL_B field (s/c coordinates, no jump subtracted) is
    ``B_sc = B_true,sc + J``, so in CSEQ ``B_cseq = M B_sc = B_true,cseq + M J`` with
    ``M`` the s/c -> CSEQ rotation.  Per interval the fit finds ``J`` (3) and the
    long-term mean CSEQ field ``m_x, m_y`` (2) from the block means::

        <B_cseq,x> = m_x + <M_x.> J,  <B_cseq,y> = m_y + <M_y.> J,  <B_cseq,z> = <M_z.> J

    i.e. the long-term average of ``B_z`` in CSEQ is driven to zero ("compatible with the
    usual long term solar wind properties") and, through the rotation-dependent terms
    ``<M> J``, whatever of the CSEQ field follows the spacecraft rotation is assigned to
    the s/c offset (the "decorrelation from spacecraft rotation").  The x/y parts of ``J``
    are determined only as far as the attitude varies (sec. 4.2.3.4: "does not adjust them
    perfectly"); the covariance says how well.  Count weights, covariance from the
    residual scatter (`weighted_lstsq`).

    Parameters
    ----------
    epoch : ndarray of int64, shape (n,)
        TT2000 ns of the LEVEL_B vectors.
    b_sc : ndarray, shape (n, 3)
        LEVEL_B field (nT, s/c coordinates) *without* offset jumps subtracted.
    rotation : ndarray, shape (n, 3, 3)
        s/c -> CSEQ rotation matrices (``B_cseq = rotation @ B_sc``).
    start_utc, end_utc : array of str
        Intervals (UTC, ISO), sorted and disjoint, ``[start, end)``.
    sensor : {"OB", "IB"}
    block_s : float
        Block length (s).
    max_sigma : float or None
        Refuse an interval whose jump has a larger standard error (nT) in any axis (the
        attitude did not vary enough in it); ``None``: accept any.

    Returns
    -------
    OffsetJumpFit
        Intervals without data are an error (no row is invented).

    Raises
    ------
    FluxcalError
        Shapes, unsorted/overlapping intervals, an interval with too few blocks or an
        attitude that does not vary enough to separate ``J`` from the mean field.

    References
    ----------
    .. [1] RO-IGEP-TR0028 (seed 003), sec. 4.2.3.4 and Appendix B (B.1, B.2).
    """
    sensor = check_sensor(sensor)
    start_utc, end_utc = np.asarray(start_utc, dtype=str), np.asarray(end_utc, dtype=str)
    blocks = reduce_offset_jumps(epoch, b_sc, rotation, start_utc, end_utc, block_s=block_s,
                                 lsk=lsk)
    return solve_offset_jumps([blocks], start_utc, end_utc, sensor=sensor,
                              max_sigma=max_sigma)


@dataclass(frozen=True)
class JumpBlocks:
    """Block reduction of LEVEL_B data for the offset-jump fit (mergeable by concatenation).

    Attributes
    ----------
    interval : ndarray of int, shape (b,)
        Index of the interval each block belongs to.
    count : ndarray, shape (b,)
    mean : ndarray, shape (b, 12)
        Block means of ``B_cseq`` (3) and of the s/c -> CSEQ matrix (9, row-major).
    block_s : float
    """

    interval: np.ndarray
    count: np.ndarray
    mean: np.ndarray
    block_s: float


def interval_bounds(start_utc: np.ndarray, end_utc: np.ndarray, lsk=None
                    ) -> tuple[np.ndarray, np.ndarray]:
    """TT2000 of the interval limits; `FluxcalError` unless sorted, disjoint, non-empty."""
    starts = utc_to_tt2000(np.asarray(start_utc, dtype=str), lsk)
    ends = utc_to_tt2000(np.asarray(end_utc, dtype=str), lsk)
    if (starts.size == 0 or np.any(ends <= starts) or np.any(np.diff(starts) <= 0)
            or np.any(ends[:-1] > starts[1:])):
        raise FluxcalError("offset jumps: intervals must be sorted, disjoint and non-empty")
    return starts, ends


def reduce_offset_jumps(
    epoch: np.ndarray,
    b_sc: np.ndarray,
    rotation: np.ndarray,
    start_utc: np.ndarray,
    end_utc: np.ndarray,
    *,
    block_s: float = JUMP_BLOCK_S,
    lsk=None,
) -> JumpBlocks:
    """Reduce one stretch of LEVEL_B data to the block means the jump fit needs.

    Parameters as `fit_offset_jumps`.  Vectors outside every interval are ignored;
    blocks start at each interval's first vector of this stretch, so reductions of
    different days (files) concatenate into one fit (`solve_offset_jumps`).
    """
    epoch = np.asarray(epoch, dtype=np.int64)
    b_sc = np.asarray(b_sc, dtype=float)
    rotation = np.asarray(rotation, dtype=float)
    n = epoch.size
    if b_sc.shape != (n, 3) or rotation.shape != (n, 3, 3):
        raise FluxcalError(
            f"offset jumps: shapes epoch {epoch.shape}, b_sc {b_sc.shape}, rotation "
            f"{rotation.shape}; expected (n,), (n, 3), (n, 3, 3)"
        )
    starts, ends = interval_bounds(start_utc, end_utc, lsk)
    b_cseq = np.einsum("nij,nj->ni", rotation, b_sc)
    k = np.searchsorted(starts, epoch, side="right") - 1
    inside = (k >= 0) & (epoch < ends[np.maximum(k, 0)])
    m = starts.size
    key = np.where(inside, k, m)
    order = np.argsort(key, kind="stable")
    bounds = np.searchsorted(key[order], np.arange(m + 1))
    parts = []
    for j in range(m):  # loop over intervals
        sel = order[bounds[j]: bounds[j + 1]]
        if sel.size == 0:
            continue
        values = np.concatenate([b_cseq[sel], rotation[sel].reshape(-1, 9)], axis=1)
        count, mean, _ = block_means(epoch[sel], values, block_s)
        parts.append((np.full(count.size, j), count, mean))
    if not parts:
        return JumpBlocks(np.zeros(0, dtype=int), np.zeros(0), np.zeros((0, 12)), float(block_s))
    return JumpBlocks(*(np.concatenate(c) for c in zip(*parts, strict=True)), float(block_s))


def solve_offset_jumps(
    blocks: list[JumpBlocks],
    start_utc: np.ndarray,
    end_utc: np.ndarray,
    *,
    sensor: str,
    max_sigma: float | None = JUMP_MAX_SIGMA,
) -> OffsetJumpFit:
    """Solve the jump model of `fit_offset_jumps` from block reductions (any number).

    Raises
    ------
    FluxcalError
        An interval without data, too few blocks, a rank-deficient design, a sigma above
        ``max_sigma``, reductions with different block lengths.
    """
    sensor = check_sensor(sensor)
    start_utc, end_utc = np.asarray(start_utc, dtype=str), np.asarray(end_utc, dtype=str)
    if len({b.block_s for b in blocks}) > 1:
        raise FluxcalError("offset jumps: reductions with different block lengths")
    interval = np.concatenate([b.interval for b in blocks]) if blocks else np.zeros(0, int)
    count_all = np.concatenate([b.count for b in blocks]) if blocks else np.zeros(0)
    mean_all = np.concatenate([b.mean for b in blocks]) if blocks else np.zeros((0, 12))
    block_s = blocks[0].block_s if blocks else JUMP_BLOCK_S
    m = start_utc.size
    jumps, sigma = np.full((m, 3), np.nan), np.full((m, 3), np.nan)
    mean_field, rms = np.full((m, 2), np.nan), np.full(m, np.nan)
    n_blocks, n_samples = np.zeros(m, dtype=int), np.zeros(m, dtype=int)
    for j in range(m):  # loop over intervals
        what = f"offset jump {sensor} {start_utc[j]} .. {end_utc[j]}"
        rows = interval == j
        if not rows.any():
            raise FluxcalError(f"{what}: no vectors in the interval (leave it out)")
        count, mean = count_all[rows], mean_all[rows]
        rot = mean[:, 3:].reshape(-1, 3, 3)
        nb = count.size
        # unknowns: J_x, J_y, J_z, m_x, m_y; three equations per block
        design = np.zeros((3 * nb, 5))
        design[:, :3] = rot.reshape(3 * nb, 3)
        design[0::3, 3] = 1.0
        design[1::3, 4] = 1.0
        target = mean[:, :3].reshape(-1)
        q, cov, r = weighted_lstsq(design, target, np.repeat(count, 3), what=what)
        jumps[j], sigma[j] = q[:3], np.sqrt(np.diag(cov)[:3])
        if max_sigma is not None and np.any(sigma[j] > max_sigma):
            raise FluxcalError(
                f"{what}: the jump is determined only to sigma "
                + " ".join(f"{v:.3g}" for v in sigma[j])
                + f" nT (limit {max_sigma:g} nT): the attitude does not vary enough in "
                f"{int(count.sum())} vectors; use a longer interval or raise the limit "
                "(--max-sigma)"
            )
        mean_field[j] = q[3:]
        rms[j] = np.sqrt(np.sum(np.repeat(count, 3) * r**2) / (3 * np.sum(count)))
        n_blocks[j], n_samples[j] = nb, int(count.sum())
    return OffsetJumpFit(sensor, start_utc, end_utc, jumps, sigma, mean_field, rms,
                         n_blocks, n_samples, float(block_s))


def write_offset_jump_table(
    fits: list[OffsetJumpFit], path: Path, *, provenance: dict | None = None
) -> Path:
    """Write fitted offsets as ``RPCMAG_OFFSET_JUMPS.csv`` (Appendix B, applied form).

    Columns ``start_utc,end_utc,ob_x,ob_y,ob_z,ib_x,ib_y,ib_z`` as the shipped table;
    the fits of both sensors must share their intervals.  A sensor not fitted is written
    ``nan`` (the pipeline then refuses that sensor's data in those intervals instead of
    applying a made-up value).  ``#`` comment lines hold the standard errors, the fitted
    CSEQ mean field and the provenance.

    Raises
    ------
    FluxcalError
        No fits, two fits of one sensor, or fits with different intervals.
    """
    if not fits:
        raise FluxcalError("no offset-jump fit to write")
    by_sensor = {}
    for f in fits:
        if f.sensor in by_sensor:
            raise FluxcalError(f"two offset-jump fits for sensor {f.sensor}")
        by_sensor[f.sensor] = f
    first = fits[0]
    for f in fits[1:]:
        if not (np.array_equal(f.start_utc, first.start_utc)
                and np.array_equal(f.end_utc, first.end_utc)):
            raise FluxcalError("the OB and IB offset-jump fits must have the same intervals")
    m = first.start_utc.size
    cols = {s: by_sensor[s].jumps if s in by_sensor else np.full((m, 3), np.nan)
            for s in ("OB", "IB")}
    lines = [
        "# RPC-MAG post-hibernation offsets (nT, s/c coordinates) fitted by fluxcal rosetta fit",
        "# (RO-IGEP-TR0028 sec. 4.2.3.4, Appendix B form): B_corrected = B - JUMP on "
        "[start_utc, end_utc).",
        ("# criterion: CSEQ B_z long-term mean 0, CSEQ field decorrelated from the s/c "
         "rotation; docs/decisions/rosetta_fit.md"
         if first.estimator == "zero-mean" else
         f"# criterion ({first.estimator}): least variance of |B - JUMP| within "
         f"{first.block_s:g}-s sub-intervals; docs/decisions/rosetta_fit.md"),
    ]
    for f in fits:
        for j in range(m):
            lines.append(
                f"# {f.sensor} {f.start_utc[j]}: sigma x y z "
                + " ".join(f"{v:.4f}" for v in f.sigma[j])
                + " nT; CSEQ mean Bx By " + " ".join(f"{v:.3f}" for v in f.mean_field[j])
                + f" nT; rms {f.rms[j]:.3f} nT; blocks {f.n_blocks[j]} of {f.block_s:g} s; "
                f"samples {f.n_samples[j]}"
            )
    lines += [f"# {k}: {v}" for k, v in (provenance or {}).items()]
    lines.append("start_utc,end_utc,ob_x,ob_y,ob_z,ib_x,ib_y,ib_z")
    for j in range(m):
        values = [*cols["OB"][j], *cols["IB"][j]]
        lines.append(f"{first.start_utc[j]},{first.end_utc[j]},"
                     + ",".join("nan" if np.isnan(v) else f"{v:.4f}" for v in values))
    path = Path(path)
    atomic_write_bytes(path, "\n".join(lines) + "\n", now=True)
    return path
