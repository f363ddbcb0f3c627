"""Robust peak-to-peak identification: every equation the record holds, one generalised least-squares estimate.

Axis down, t measured from first contact t00. The mass obeys M1·ü1 = M1·g − Fc, the piston's acceleration a2 is
measured, so the relative displacement (compression) and its rate are

    δ(t) = V0·τ + (g + b)·τ²/2 − w·IF(t) − D2(t),    δ'(t) = V0 + (g + b)·τ − w·JF(t) − V2(t),

τ = t − t00, w = 1/M1, JF/IF the single/double integrals of the force and V2/D2 those of the acceleration from t00
(the piston at rest before contact), b the offset left in the channels after the pre-trigger correction. The
equations, all linear in (V0, w) and whatever the contact law:

- onset k (a pulse starts): δ(Tk) = 0 -- the force is positive only while the bodies overlap;
- separation k (a pulse ends): δ(Sk) + λ·δ'(Sk) = 0, with one lag λ >= 0 shared by all pulses (a viscous contact
  lets go before the overlap is gone: λ = c/k for Kelvin-Voigt, 0 for a force that vanishes with the overlap);
- stage B (sustained contact): the bodies move together and the overlap follows the force,
  δ(t) + λ·δ'(t) = β0 + β1·F(t), in cells of a few samples (F averaged over the cell), β0 and β1 unknown.

The nuisances (b with its pre-trigger prior, λ, β0, β1) are estimated with (V0, w). The covariance of the rows
is that of the double-integrated white noise of both channels (kernels below), of the onset and separation times
(rate × time error; the t00 error acts on every row alike) and of the cell-averaged force; it depends on the
estimate, so the solution is iterated (Gauss-Newton in λ).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

#: Gauss-Newton / reweighting iterations
ITERATIONS = 8


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
    return lagged_kernel(tau, np.zeros_like(np.asarray(tau, dtype=float)), dt)


def lagged_kernel(tau: np.ndarray, lag: np.ndarray, dt: float) -> np.ndarray:
    """Covariance of e(τi) + lag_i·e'(τi), e the double integral from 0 of unit white noise at step ``dt``.

    With m = min(s, t): cov(e(s), e(t)) = dt·(s·t·m − (s+t)·m²/2 + m³/3), cov(e(s), e'(t)) = dt·(s·m − m²/2),
    cov(e'(s), e'(t)) = dt·m.
    """
    tau = np.asarray(tau, dtype=float)
    lag = np.asarray(lag, dtype=float)
    s, t = tau[:, None], tau[None, :]
    m = np.minimum(s, t)
    k_dd = s * t * m - (s + t) * m ** 2 / 2.0 + m ** 3 / 3.0
    k_dv = s * m - m ** 2 / 2.0  # cov(e(s), e'(t))
    return dt * (k_dd + lag[None, :] * k_dv + lag[:, None] * k_dv.T + lag[:, None] * lag[None, :] * m)


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


@dataclass(frozen=True)
class Equations:
    """The rows available in a record (fractional sample indices of the segment, standard errors in samples).

    ``onsets`` excludes t00; ``cells``/``cell_force`` are the centres and mean forces [N] of the stage-B cells of
    ``cell_size`` samples.
    """

    onsets: np.ndarray
    onset_std: np.ndarray
    separations: np.ndarray = field(default_factory=lambda: np.zeros(0))
    separation_std: np.ndarray = field(default_factory=lambda: np.zeros(0))
    cells: np.ndarray = field(default_factory=lambda: np.zeros(0))
    cell_force: np.ndarray = field(default_factory=lambda: np.zeros(0))
    cell_size: int = 1

    def counts(self) -> dict[str, int]:
        """Equations used: onsets after t00, separations, stage-B rows and the samples they average."""
        return {"onsets": int(self.onsets.size), "separations": int(self.separations.size),
                "stage_b_rows": int(self.cells.size), "stage_b_samples": int(self.cells.size * self.cell_size)}


@dataclass(frozen=True)
class Solution:
    """(V0 [m/s], w [1/kg]), their covariance, the fit's chi-square and degrees of freedom, the nuisances and
    d(V0, w)/d(error of δ at the times ``tau``) for combining with another estimate."""

    theta: np.ndarray
    cov: np.ndarray
    chi2: float
    dof: int
    nuisances: dict
    gain: np.ndarray
    tau: np.ndarray


def solve_rows(kin: Kinematics, eqs: Equations, *, noise_force: float, noise_acceleration: float,
               pre_samples: int, lag_max: float) -> Solution:
    """Generalised least squares for (V0, w) from the rows of ``eqs`` (module notes).

    Parameters
    ----------
    kin : Kinematics
    eqs : Equations
    noise_force, noise_acceleration : float
        White-noise standard deviations [N], [m/s²].
    pre_samples : int
        Samples the offsets were removed with (0: no offset correction, b is taken as zero).
    lag_max : float
        Largest separation lag λ [s].

    Notes
    -----
    The stage-B overlap is h(F) = β0 + Σ βj·(F/Fs)^(j/3), j = 1..3 (Fs the largest cell force): a smooth function
    of the force that holds linear springs (j = 3), Hertzian contact (j = 2) and a permanent set (β0). Separations
    and stage-B cells rest on models of the contact (the lag, h): where their rows scatter more than their noise
    explains, a white model-error variance is added to that group until its chi-square matches its rows, so a
    poor model weighs less instead of pulling the estimate.
    """
    dt, g = kin.dt, kin.gravity
    n_on, n_sep, n_cell = eqs.onsets.size, eqs.separations.size, eqs.cells.size
    index = np.concatenate([eqs.onsets, eqs.separations, eqs.cells])
    group = np.r_[np.zeros(n_on, int), np.ones(n_sep, int), np.full(n_cell, 2)]
    lagged = (group > 0).astype(float)
    timing = np.r_[eqs.onset_std, eqs.separation_std, np.zeros(n_cell)] * dt
    tau, force, jf, i_f, acc, va, da = kin.at(index)
    fit_lag, fit_b, fit_h = bool(n_sep + n_cell) and lag_max > 0, pre_samples > 0, n_cell > 0
    names = ["V0", "w"] + ["b"] * fit_b + ["h0", "h1", "h2", "h3"] * fit_h
    cols = {name: i for i, name in enumerate(names)}
    cell = (group == 2).astype(float)
    scale = float(np.max(eqs.cell_force)) if n_cell else 1.0
    x = np.r_[np.zeros(n_on + n_sep), np.maximum(eqs.cell_force, 0.0) / scale]
    powers = [x ** (j / 3.0) for j in range(4)]

    def design(lag):
        lam = lagged * lag
        a = np.zeros((index.size, len(names)))
        a[:, 0] = tau + lam
        a[:, 1] = -(i_f + lam * jf)
        if fit_b:
            a[:, cols["b"]] = tau ** 2 / 2.0 + lam * tau
        if fit_h:
            for j in range(4):
                a[:, cols[f"h{j}"]] = -cell * powers[j]
        y = da + lam * va - g * (tau ** 2 / 2.0 + lam * tau)
        return a, y

    def rates(theta):
        b = theta[cols["b"]] if fit_b else 0.0
        d1 = theta[0] + (g + b) * tau - theta[1] * jf - va  # δ'
        d2 = g + b - theta[1] * force - acc  # δ''
        return d1, d2

    def slope(theta):  # dh/dF at the cell forces [m/N]
        if not fit_h:
            return np.zeros(index.size)
        xs = np.maximum(x, 1e-3)
        return cell * sum(theta[cols[f"h{j}"]] * j / 3.0 * xs ** (j / 3.0 - 1.0) for j in (1, 2, 3)) / scale

    lag = 0.0
    a, y = design(lag)
    theta = np.linalg.lstsq(a, y, rcond=None)[0]
    tiny = (1e-9 * (np.sqrt(np.mean(np.square(y))) + 1e-30)) ** 2
    model = np.zeros(3)  # model-error variance of each group [m²]
    for _ in range(ITERATIONS):
        v0, w = theta[0], max(theta[1], 0.0)
        white = noise_acceleration ** 2 + (w * noise_force) ** 2
        d1, d2 = rates(theta)
        speed = np.abs(d1 + lagged * lag * d2)
        cov = white * lagged_kernel(tau, lagged * lag, dt) + (v0 * kin.onset_std0 * dt) ** 2
        cov += np.diag((speed * timing) ** 2 + (slope(theta) * noise_force) ** 2 / eqs.cell_size
                       + model[group] + tiny)
        a, y = design(lag)
        jac = a
        if fit_lag:
            jac = np.column_stack([a, lagged * d1])
            y = y + lagged * d1 * lag  # Gauss-Newton about the current lag
        chol = np.linalg.cholesky(cov)
        aw = np.linalg.solve(chol, jac)
        yw = np.linalg.solve(chol, y)
        if fit_b:  # the pre-trigger's residual offset: a prior row b = 0 ± its standard error
            prior = np.zeros(jac.shape[1])
            prior[cols["b"]] = 1.0 / np.sqrt(white / pre_samples)
            aw = np.vstack([aw, prior])
            yw = np.append(yw, 0.0)
        sol = np.linalg.lstsq(aw, yw, rcond=None)[0]
        theta = sol[:len(names)]
        if fit_lag:
            lag = float(np.clip(sol[-1], 0.0, lag_max))
        # whitened residuals of a later group are its innovations given the earlier rows: its own chi-square
        resid = (yw - aw @ sol)[:index.size]
        for k in (1, 2):
            inside = group == k
            excess = float(np.sum(resid[inside] ** 2)) / max(int(inside.sum()), 1)
            if inside.any():
                noise_part = float(np.mean(np.diag(cov)[inside])) - model[k]
                model[k] = max((model[k] + noise_part) * excess - noise_part, 0.0)
    resid = yw - aw @ sol
    chi2 = float(resid @ resid)
    n_param = aw.shape[1]
    dof = int(index.size - (n_param - fit_b))
    bread = np.linalg.pinv(aw.T @ aw)
    cov_theta = bread[:2, :2]
    gain = (bread @ aw.T)[:2, :index.size] @ np.linalg.inv(chol)
    nuisances = {"lag_s": lag} if fit_lag else {}
    if fit_b:
        nuisances["offset_m_s2"] = float(theta[cols["b"]])
    nuisances["model_error_m"] = {"separations": float(np.sqrt(model[1])), "stage_b": float(np.sqrt(model[2]))}
    return Solution(theta=theta[:2].copy(), cov=cov_theta, chi2=chi2, dof=dof, nuisances=nuisances, gain=gain,
                    tau=tau)


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
