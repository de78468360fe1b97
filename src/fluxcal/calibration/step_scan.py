"""Change-point score test of a constant offset step between intervals (variance fits).

A variance fit of offsets (``|B - O|`` least variable within intervals) ends with the
per-interval normal equations ``(N_k, r_k)`` of its linearised problem.  An offset that
jumps at some time and stays (a spacecraft field switched, an Appendix B jump) adds, from
the jump's interval on, the constant-offset columns: `scan_offset_step` tests that step
between every two intervals and keeps the largest ``chi2``.  Generic: arrays in, a
`JumpScan` out; no mission (docs/decisions/rosetta_fit.md entry 16 measures it).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["JumpScan", "scan_offset_step"]


@dataclass(frozen=True)
class JumpScan:
    """Change-point scan of the residual interval offsets of a variance fit.

    Attributes
    ----------
    statistic : float
        Largest ``chi2`` (3 dof) over the splits of the accepted intervals.
    split : int
        Index (into the intervals) of the first interval after the best split; -1: none.
    step : ndarray, shape (3,)
        The offset step (x y z, units of the field) at that split, the fit redone with it.
    sigma : ndarray, shape (3,)
        Its standard error.
    splits : int
        Splits scanned.
    """

    statistic: float
    split: int
    step: np.ndarray
    sigma: np.ndarray
    splits: int


def scan_offset_step(normal: np.ndarray, rhs: np.ndarray, use: np.ndarray,
                     const_columns: np.ndarray, min_side: int) -> JumpScan:
    """Score test of a constant offset step between consecutive intervals, every split.

    At the converged curve each accepted interval ``k`` has normal equations
    ``(N_k, r_k)`` of the linearised variance of ``|B'|`` (``r_k``: its residual
    scores).  A step ``D`` of the offset from interval ``j`` on adds the constant columns
    ``c`` (``u_i x^0``) of the intervals ``k >= j``.  Its estimate with the curve refitted
    is ``D_j = S_j^-1 (g_j - C_j^T N^-1 r)``, ``S_j = D_j - C_j^T N^-1 C_j``, with ``N, r``
    the sums over all intervals, ``C_j, D_j, g_j`` those over ``k >= j`` of ``N_k[:, c]``,
    ``N_k[c, c]``, ``r_k[c]``.  Its covariance is the sandwich over intervals (the scores'
    own scatter: the compressive noise is correlated within an interval, not between
    them) times ``n / (n - p - 3)``; ``chi2_j = D_j^T V_j^-1 D_j``.  Splits leave at
    least ``min_side`` accepted intervals on each side.

    Parameters
    ----------
    normal : ndarray, shape (k, p, p)
        Per-interval normal equations at the converged solution.
    rhs : ndarray, shape (k, p)
        Per-interval right-hand sides (residual scores).
    use : ndarray of bool, shape (k,)
        Intervals (in time order) that enter the scan.
    const_columns : array of int, shape (3,)
        Columns of the constant offset per axis (``u_i``).
    min_side : int

    Returns
    -------
    JumpScan
        ``split`` indexes ``normal``'s intervals.
    """
    idx = np.flatnonzero(use)
    n = idx.size
    p = normal.shape[1]
    cc = np.asarray(const_columns, dtype=int)
    none = JumpScan(0.0, -1, np.zeros(3), np.full(3, np.nan), 0)
    if n < 2 * min_side:
        return none
    nk, rk = normal[idx], rhs[idx]
    n_all, r_all = nk.sum(axis=0), rk.sum(axis=0)
    inv = np.linalg.pinv(n_all)
    # suffix sums over intervals k >= j
    c_suf = np.cumsum(nk[::-1][:, :, cc], axis=0)[::-1]           # (n, p, 3)
    d_suf = np.cumsum(nk[::-1][:, cc][:, :, cc], axis=0)[::-1]    # (n, 3, 3)
    g_suf = np.cumsum(rk[::-1][:, cc], axis=0)[::-1]              # (n, 3)
    js = np.arange(min_side, n - min_side + 1)
    own = np.linalg.pinv(nk[:, cc][:, :, cc])                      # (n, 3, 3)
    # splits in chunks: the per-split, per-interval arrays stay near 2e6 numbers (an
    # Appendix B interval of months has thousands of sub-intervals)
    per = max(1, int(2_000_000 // max(n * p, 1)))
    parts = [_scan_splits(js[c:c + per], nk, rk, c_suf, d_suf, g_suf, inv, r_all, own, cc, p)
             for c in range(0, js.size, per)]
    chi2, step, cov = (np.concatenate(x) for x in zip(*parts, strict=True))
    best = int(np.argmax(chi2))
    return JumpScan(float(chi2[best]), int(idx[js[best]]), step[best],
                    np.sqrt(np.diag(cov[best])), int(js.size))



def _scan_splits(js, nk, rk, c_suf, d_suf, g_suf, inv, r_all, own, cc, p):
    """``(chi2, step, cov)`` of the splits ``js`` (`scan_offset_step`)."""
    n = nk.shape[0]
    c_j, d_j, g_j = c_suf[js], d_suf[js], g_suf[js]
    proj = np.einsum("jpc,pq->jcq", c_j, inv)                      # C_j^T N^-1, (J, 3, p)
    s_j = d_j - np.einsum("jcq,jqd->jcd", proj, c_j)
    after = np.arange(n)[None, :] >= js[:, None]                   # (J, n)
    s_inv = np.linalg.pinv(s_j)
    step = np.einsum("jcd,jd->jc", s_inv, g_j - np.einsum("jcq,q->jc", proj, r_all))
    # the curve's change with the step, and each interval's scores after both (the
    # alternative's residuals: a real step must not inflate its own error)
    moved = np.einsum("pq,jq->jp", inv, r_all[None] - np.einsum("jpc,jc->jp", c_j, step))
    r_alt = (rk[None] - np.einsum("kpq,jq->jkp", nk, moved)
             - after[:, :, None] * np.einsum("kpc,jc->jkp", nk[:, :, cc], step))
    # the scores of an interval scatter as phi N_k (phi > 1: the compressive noise is
    # correlated within a segment); phi pooled over all intervals, so that a split near
    # the day's edge is not judged by the scatter of three intervals
    phi = (np.einsum("jkc,kcd,jkd->j", r_alt[:, :, cc], own, r_alt[:, :, cc])
           / max(3 * n - p - 3, 1))
    pooled = phi[:, None, None] * s_inv
    # and the sandwich over intervals (robust where some intervals are much noisier than
    # the rest, as near wave packets); the smaller chi2 of the two is the statistic
    z = after[:, :, None] * r_alt[:, :, cc] - np.einsum("jcq,jkq->jkc", proj, r_alt)
    meat = np.einsum("jkc,jkd->jcd", z, z) * n / max(n - p - 3, 1)
    sandwich = np.einsum("jab,jbc,jdc->jad", s_inv, meat, s_inv)
    chi2_pooled = np.einsum("ja,jab,jb->j", step, np.linalg.pinv(pooled), step)
    chi2_sandwich = np.einsum("ja,jab,jb->j", step, np.linalg.pinv(sandwich), step)
    chi2 = np.minimum(chi2_pooled, chi2_sandwich)
    cov = np.where((chi2_pooled <= chi2_sandwich)[:, None, None], pooled, sandwich)
    return chi2, step, cov
