"""Covariances of the robust answer: the kernels of the double-integrated white noise that correlate its rows, the
inverse of the normal equations computed stably, and what the slow errors of the acceleration channel (an offset,
a drift) may do to an answer that leaves them out."""

from __future__ import annotations

import numpy as np

#: the least overlap of the bodies over a gap between two pulses is taken as surely negative (a flight) or surely
#: positive (the pad stayed loaded) when it lies this many of its standard errors from zero [-] (the early answer's
#: test of a dip and the robust fit's test of a flight)
DIP_SIGMAS = 2.0

def atom_kernel(tau: np.ndarray, cd: np.ndarray, cv: np.ndarray, dt: float) -> np.ndarray:
    """Covariance of cd_i·e(τi) + cv_i·e'(τi), e the double integral from 0 of unit white noise at step ``dt``.

    With m = min(s, t): cov(e(s), e(t)) = dt·(s·t·m − (s+t)·m²/2 + m³/3), cov(e(s), e'(t)) = dt·(s·m − m²/2),
    cov(e'(s), e'(t)) = dt·m [multiply by the noise variance [m²/s⁴]].
    """
    tau = np.asarray(tau, dtype=float)
    s, t = tau[:, None], tau[None, :]
    m = np.minimum(s, t)
    k_dd = s * t * m - (s + t) * m ** 2 / 2.0 + m ** 3 / 3.0
    k_dv = s * m - m ** 2 / 2.0  # cov(e(s), e'(t))
    cd, cv = np.asarray(cd, dtype=float), np.asarray(cv, dtype=float)
    return dt * (cd[:, None] * cd[None, :] * k_dd + cd[:, None] * cv[None, :] * k_dv
                 + cv[:, None] * cd[None, :] * k_dv.T + cv[:, None] * cv[None, :] * m)


def kernel_form(weights: np.ndarray, tau: np.ndarray, dt: float) -> np.ndarray:
    """``weights @ K @ weights.T`` in O(P·n) without forming the n×n kernel K of the double-integrated white
    noise (:func:`atom_kernel` with cd = 1, cv = 0).

    The kernel factors as B·Bᵀ with B[j, u] = √(dt·h)·(τj − u)₊ over nodes u spaced h = dt (midpoint rule), so
    weights·B follows from suffix sums of the weights sorted by τ.
    """
    weights = np.atleast_2d(weights)
    order = np.argsort(tau)
    t = np.asarray(tau, dtype=float)[order]
    w = weights[:, order]
    if t.size == 0 or t[-1] <= 0:
        return np.zeros((weights.shape[0], weights.shape[0]))
    nodes = (np.arange(int(np.ceil(t[-1] / dt))) + 0.5) * dt
    a0 = np.concatenate([np.cumsum(w[:, ::-1], axis=1)[:, ::-1], np.zeros((w.shape[0], 1))], axis=1)
    a1 = np.concatenate([np.cumsum((w * t)[:, ::-1], axis=1)[:, ::-1], np.zeros((w.shape[0], 1))], axis=1)
    first = np.searchsorted(t, nodes, side="right")  # first j with τj > u
    wb = np.sqrt(dt * dt) * (a1[:, first] - nodes * a0[:, first])
    return wb @ wb.T


def normal_inverse(jac: np.ndarray) -> np.ndarray:
    """(JᵀJ)⁺, the covariance of a least-squares fit with whitened Jacobian ``jac``, from the singular values of J
    with its columns scaled to unit norm: the condition number of J, not its square, and no parameter lost to the
    cut-off of small singular values because another parameter's column is large (a tight prior row)."""
    scale = np.linalg.norm(jac, axis=0)
    scale[~(scale > 0.0)] = 1.0
    half = np.linalg.pinv(jac / scale)
    return (half @ half.T) / np.outer(scale, scale)


def slow_covariance(cov: np.ndarray, cov_slow: np.ndarray, moved: np.ndarray, *, bounded: bool) -> np.ndarray:
    """The covariance of an answer (``cov``, of V0 and w) that leaves the slow errors out, carrying what they may do,
    from the answer that estimates them (its covariance ``cov_slow``, ``moved`` from it to this answer).

    Where the two lie further apart than the estimate's extra spread explains (q = movedᵀ·(cov_slow − cov)⁺·moved
    > 1), the part of the shift beyond it, (1 − 1/q)·moved·movedᵀ, joins the covariance: a drift shows so. Where
    the slow errors are not ``bounded`` (no pre-trigger measures the offset), the spread they may cause joins it
    too (``cov_slow`` instead of ``cov``): an offset need not move the estimate that estimates it far enough to
    be seen. A pre-trigger bounds them, and the answer keeps its own covariance where nothing is seen.
    """
    q = float(moved @ np.linalg.pinv(cov_slow - cov) @ moved)
    base = cov if bounded else cov_slow
    return base + max(1.0 - 1.0 / q, 0.0) * np.outer(moved, moved) if q > 0 else base


def slow_errors(t00: float, dt: float, pre_samples: int, tau: np.ndarray, coefficients, mixer: np.ndarray,
                 chol: np.ndarray, aw: np.ndarray, yw: np.ndarray, white: float, *,
                 room: int) -> tuple[np.ndarray, np.ndarray] | None:
    """(V0, w, b, b') and the covariance of (V0, w) from the whitened rows ``aw``, ``yw`` of a solution (its
    parameters V0, w, [b,] nuisances) with the channels' slow errors estimated too: an offset b and a drift b'
    [m/s³] in δ'' = g + b + b'·τ − w·Fc − a2.

    With a pre-trigger, its mean (which the correction removed) says b + b'·τ̄ = 0 (τ̄ its centre from t00) within
    √(white/n), and its length bounds the drift: b' = 0 within √(white/Σ(τ − τ̄)²), the error of a slope fitted to
    it -- zero-centred, since a slope read from a short window follows hum and slow noise. Without one, b is
    free and b' taken as zero. None where the rows leave no room for them (``room``: degrees of freedom left).
    """
    cd, cv, ca = coefficients
    if pre_samples > 0:
        pre = (np.arange(pre_samples) - t00) * dt
        centre = float(np.mean(pre))
        column = mixer @ (cd * tau ** 3 / 6.0 + cv * tau ** 2 / 2.0 + ca * tau)  # b' in every row
        a = np.column_stack([aw, np.linalg.solve(chol, column)])
        prior = np.zeros((2, a.shape[1]))
        prior[0, 2], prior[0, -1] = 1.0, centre
        prior[0] /= np.sqrt(white / pre_samples)
        prior[1, -1] = 1.0 / np.sqrt(white / float(np.sum((pre - centre) ** 2)))
        a = np.vstack([a, prior])
        found = np.linalg.lstsq(a, np.r_[yw, 0.0, 0.0], rcond=None)[0]
        return np.r_[found[:3], found[-1]], normal_inverse(a)[:2, :2]
    if room < 1:
        return None
    column = mixer @ (cd * tau ** 2 / 2.0 + cv * tau + ca)  # b in every row
    a = np.column_stack([aw, np.linalg.solve(chol, column)])
    found = np.linalg.lstsq(a, yw, rcond=None)[0]
    return np.r_[found[:2], found[-1], 0.0], normal_inverse(a)[:2, :2]
