"""Robust peak-to-peak identification: zero relative displacement at every contact onset.

Axis down, t measured from first contact t00. The mass obeys M1·ü1 = M1·g − Fc, the piston's acceleration a2 is
measured, so the relative displacement (compression) is

    δ(t) = V0·τ + g·τ²/2 − w·IF(t) − D2(t),   τ = t − t00,  w = 1/M1,

with IF = ∬Fc and D2 = ∬a2 from t00 (the piston at rest before contact). Whatever the contact law, the force is
positive only while δ > 0, so δ = 0 at every onset: one row V0·τk − w·IF(tk) = D2(tk) − g·τk²/2 per onset, linear
in (V0, w). The rows are solved by generalised least squares with the covariance propagated from the noise of
both channels (double-integrated), the residual offsets and the onset-time errors.
"""

from __future__ import annotations

import numpy as np

#: smallest number of onsets after t00 for the final answer (two unknowns)
MIN_ONSET_ROWS = 2


def cumulative_integrals(signal: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """First and second running integrals of a piecewise-linear ``signal`` from its first sample (exact)."""
    x = np.asarray(signal, dtype=float)
    first = np.zeros_like(x)
    second = np.zeros_like(x)
    first[1:] = np.cumsum(0.5 * dt * (x[1:] + x[:-1]))
    step2 = dt * first[:-1] + dt * dt * (x[:-1] / 3.0 + x[1:] / 6.0)
    second[1:] = np.cumsum(step2)
    return first, second


def integrals_at(signal, first, second, dt, index):
    """Value, first and second integrals at fractional sample ``index`` (piecewise-linear signal)."""
    index = np.asarray(index, dtype=float)
    i = np.clip(np.floor(index).astype(int), 0, signal.size - 2)
    s = (index - i) * dt
    x0 = signal[i]
    slope = (signal[i + 1] - x0) / dt
    value = x0 + slope * s
    v = first[i] + x0 * s + slope * s ** 2 / 2.0
    d = second[i] + first[i] * s + x0 * s ** 2 / 2.0 + slope * s ** 3 / 6.0
    return value, v, d


class Kinematics:
    """Double integrals of force and piston acceleration referred to the first contact t00."""

    def __init__(self, force, acceleration, dt, t00_index, gravity, *, onset_std0=0.0):
        self.force, self.acceleration, self.dt, self.gravity = force, acceleration, dt, gravity
        self.t00 = float(t00_index)
        self.onset_std0 = float(onset_std0)  # standard error of t00 [samples]
        self.cf = cumulative_integrals(force, dt)
        self.ca = cumulative_integrals(acceleration, dt)
        self._f0 = integrals_at(force, *self.cf, dt, self.t00)
        self._a0 = integrals_at(acceleration, *self.ca, dt, self.t00)

    def at(self, index):
        """(τ, Fc, JF, IF, a2, V2, D2) at fractional sample indices, integrals from t00."""
        index = np.asarray(index, dtype=float)
        tau = (index - self.t00) * self.dt
        f, jf, i_f = integrals_at(self.force, *self.cf, self.dt, index)
        a, va, da = integrals_at(self.acceleration, *self.ca, self.dt, index)
        jf, i_f = jf - self._f0[1], i_f - self._f0[2] - self._f0[1] * tau
        va, da = va - self._a0[1], da - self._a0[2] - self._a0[1] * tau
        return tau, f, jf, i_f, a, va, da


def white_kernel(tau: np.ndarray, dt: float) -> np.ndarray:
    """Covariance of the double integral (from τ = 0) of unit-variance white noise sampled at step ``dt``.

    K(s, t) = dt·∫₀^min(s,t) (s − u)(t − u) du [s⁵ → multiply by the noise variance [m²/s⁴] to get m²].
    """
    s, t = np.meshgrid(tau, tau, indexing="ij")
    m = np.minimum(s, t)
    return dt * (s * t * m - (s + t) * m ** 2 / 2.0 + m ** 3 / 3.0)


def kernel_form(weights: np.ndarray, tau: np.ndarray, dt: float) -> np.ndarray:
    """``weights @ white_kernel(tau, dt) @ weights.T`` in O(P·n) without forming the n×n kernel.

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


def solve_onsets(kin: Kinematics, onsets, onset_std, *, noise_force, noise_acceleration, pre_samples):
    """Generalised least squares for (V0, w) from the onsets after t00.

    Parameters
    ----------
    kin : Kinematics
    onsets, onset_std : array_like
        Fractional sample indices of the onsets after t00 and their standard errors [samples].
    noise_force, noise_acceleration : float
        Noise standard deviations [N], [m/s²].
    pre_samples : int
        Samples the offsets were estimated from (0: offsets not removed).

    Returns
    -------
    theta, cov, chi2, dof : the estimate (V0 [m/s], w [1/kg]), its covariance, chi-square and degrees of freedom.
    """
    onsets = np.asarray(onsets, dtype=float)
    tau, _, jf, i_f, _, va, da = kin.at(onsets)
    g = kin.gravity
    a = np.column_stack([tau, -i_f])
    b = da - g * tau ** 2 / 2.0
    kernel = white_kernel(tau, kin.dt)
    std_t0 = kin.onset_std0 * kin.dt
    theta = np.linalg.lstsq(a, b, rcond=None)[0]
    for _ in range(3):
        v0, w = theta
        w = max(w, 0.0)
        closing = np.maximum(v0 + g * tau - w * jf - va, 0.0)
        white = (noise_acceleration ** 2 + (w * noise_force) ** 2)
        cov = white * kernel + np.diag((closing * np.asarray(onset_std) * kin.dt) ** 2) + (v0 * std_t0) ** 2
        cov = cov + np.diag(np.full(tau.size, 1e-30 + 1e-12 * float(np.max(np.abs(b))) ** 2))
        chol = np.linalg.cholesky(cov)
        aw = np.linalg.solve(chol, a)
        bw = np.linalg.solve(chol, b)
        theta, *_ = np.linalg.lstsq(aw, bw, rcond=None)
    resid = bw - aw @ theta
    chi2 = float(resid @ resid)
    dof = tau.size - 2
    # the offsets left after the pre-trigger correction act on every row alike (∝ τ²): weighting by them would
    # trade the mass against an offset, so they enter the error only (sandwich covariance)
    bread = np.linalg.inv(aw.T @ aw)
    cov_theta = bread
    if dof > 0:
        cov_theta = cov_theta * max(1.0, chi2 / dof)
    gain = bread @ aw.T @ np.linalg.inv(chol)  # d theta / d b = d theta / d(error of D2 at each row)
    if pre_samples > 0:
        shape = tau ** 2 / 2.0
        spread = (noise_acceleration ** 2 + (w * noise_force) ** 2) / pre_samples
        cov_theta = cov_theta + spread * np.outer(gain @ shape, gain @ shape)
    return theta, cov_theta, chi2, dof, (gain, tau)


def combine(first, second, *, noise_acceleration, pre_samples, dt):
    """Best linear unbiased combination of two estimates of (V0, w) that share the acceleration noise.

    ``first`` and ``second`` are (theta, cov, (gain, tau)) with ``gain`` = d theta / d(error of D2 at the times
    ``tau``); their cross-covariance follows from the double-integrated acceleration noise and the residual
    offset. Returns (theta, cov).
    """
    (t1, c1, (g1, tau1)), (t2, c2, (g2, tau2)) = first, second
    weights = np.zeros((4, tau1.size + tau2.size))
    weights[:2, :tau1.size] = g1
    weights[2:, tau1.size:] = g2
    cross = noise_acceleration ** 2 * kernel_form(weights, np.concatenate([tau1, tau2]), dt)[:2, 2:]
    if pre_samples > 0:
        cross = cross + noise_acceleration ** 2 / pre_samples * np.outer(g1 @ (tau1 ** 2 / 2), g2 @ (tau2 ** 2 / 2))
    sigma = np.block([[c1, cross], [cross.T, c2]])
    h = np.vstack([np.eye(2), np.eye(2)])
    try:
        # the two must agree within their errors; where they do not, both are less certain than stated (Birge)
        diff = t1 - t2
        spread = np.linalg.solve(c1 + c2 - cross - cross.T, diff) @ diff / 2.0
        sigma = sigma * max(1.0, float(spread))
        info = h.T @ np.linalg.solve(sigma, h)
        cov = np.linalg.inv(info)
        theta = cov @ (h.T @ np.linalg.solve(sigma, np.concatenate([t1, t2])))
    except np.linalg.LinAlgError:
        return t1, c1
    return theta, cov
