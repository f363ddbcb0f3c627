"""Early answer of the robust variant: the first two pulses only.

Two onsets give one onset row for two unknowns, so rows from the contact phase are added: while the bodies
touch, the compression δ(t) (linear in (V0, w), see :mod:`robust`) is a function of the force plus damping,
modelled as δ = c1·Fc^(2/3) + c2·Fc + (d1 + d2·Fc^(2/3))·δ' with (c1, c2, d1, d2) nuisance unknowns; it covers
Kelvin-Voigt (δ = Fc/k − (c/k)·δ') and Hunt-Crossley (δ ≈ (Fc/k)^(2/3)·(1 − α·δ')).
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import least_squares


def solve_early(kin, pulses, onset1, onset1_std, *, noise_force, noise_acceleration, pre_samples):
    """(V0, w) from the onset row of the second pulse and the contact rows of the first two pulses.

    Returns theta, cov, chi2, dof like :func:`robust.solve_onsets`; the covariance is the Gauss-Newton one scaled
    by the residual variance (rows weighted by the propagated noise of δ).
    """
    idx = np.concatenate([np.arange(p.first, p.end, dtype=float) for p in pulses])
    tau, f, jf, i_f, _, va, da = kin.at(idx)
    g = kin.gravity
    f23 = np.cbrt(np.maximum(f, 0.0)) ** 2
    t1, _, jf1, if1, _, va1, da1 = kin.at(np.array([onset1]))
    scale_t = max(float(tau.max()), kin.dt)
    sigma_row = np.sqrt((noise_acceleration ** 2 + 1e-30) * kin.dt * np.maximum(tau, kin.dt) ** 3 / 3.0)
    floor = 1e-6 * max(float(np.max(np.abs(da - g * tau ** 2 / 2))), 1e-9)
    sigma_row = np.maximum(sigma_row, floor)
    sigma_onset = max(float(np.sqrt(noise_acceleration ** 2 * kin.dt * t1[0] ** 3 / 3.0
                                    + (onset1_std * kin.dt) ** 2)), floor)

    def residuals(x):
        v0, w, c1, c2, d1, d2 = x
        delta = v0 * tau + g * tau ** 2 / 2 - w * i_f - da
        rate = v0 + g * tau - w * jf - va
        model = c1 * f23 + c2 * f + (d1 * 1e-4 + d2 * f23) * rate
        onset = v0 * t1 + g * t1 ** 2 / 2 - w * if1 - da1
        return np.concatenate([(delta - model) / sigma_row, onset / sigma_onset])

    # start: the paper-like guess V0 from the first peak, mass from the impulse balance
    v_guess = max(float(va[np.argmax(f[: np.searchsorted(idx, pulses[0].end) ])]), 0.1)
    x0 = np.array([2.0 * v_guess, 1.0 / 20.0, 0.0, 1e-7, 0.0, 0.0])
    x0[0] = max(float(da1[0] - g * t1[0] ** 2 / 2 + x0[1] * if1[0]) / max(t1[0], kin.dt), 0.1)
    fit = least_squares(residuals, x0, method="lm", x_scale="jac", max_nfev=400)
    jac = fit.jac
    chi2 = float(fit.fun @ fit.fun)
    dof = fit.fun.size - 6
    try:
        cov = np.linalg.inv(jac.T @ jac)
    except np.linalg.LinAlgError:
        cov = np.full((6, 6), np.inf)
    cov = cov * max(1.0, chi2 / max(dof, 1))
    del scale_t
    return fit.x[:2], cov[:2, :2], chi2, dof
