"""Early answer of the robust variant: the first two pulses only.

Two onsets give one onset row for two unknowns, so the contact phase is used as well: while the bodies touch,
the measured force must follow one contact law of the compression δ and its rate δ' (both linear in (V0, w), see
:mod:`robust`), the same law in both pulses. The law is modelled as Fc = k·δ^n + c·δ^m·δ' with (k, c, n, m) nuisance
unknowns -- Kelvin-Voigt is n = 1, m = 0 and Hunt-Crossley n = m = 3/2 -- and fitted to the force samples of both
pulses together with the onset row of the second pulse (δ = 0 there), by nonlinear least squares in units of the
force noise. The covariance adds the propagated double-integrated acceleration noise and residual offsets to the
force-noise part (sandwich form), inflated by the reduced chi-square when it exceeds 1.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import least_squares

from .robust import kernel_form

#: starting (n, m) exponents of the law: Kelvin-Voigt and Hunt-Crossley
LAW_STARTS = ((1.0, 0.0), (1.5, 1.5))
#: starting 1/M1 [1/kg] (the fit is started from each, with each law, and the best kept)
START_INVERSE_MASSES = (1.0 / 20.0,)
#: bounds of the exponents n and m
N_BOUNDS, M_BOUNDS = (0.8, 2.5), (-0.5, 2.5)


def _law(delta, rate, k, c, n, m, dscale):
    x = np.maximum(delta / dscale, 1e-12)
    return np.where(delta > 0, k * x ** n + c * x ** m * rate, 0.0)


def solve_early(kin, pulses, onset1, onset1_std, *, noise_force, noise_acceleration, pre_samples):
    """(V0, w) from the force samples of the first two pulses and the onset of the second.

    Returns theta, cov, chi2, dof like :func:`robust.solve_onsets`.
    """
    idx = np.concatenate([np.arange(p.first, p.end, dtype=float) for p in pulses])
    tau, f, jf, i_f, _, va, da = kin.at(idx)
    g = kin.gravity
    t1, _, _, if1, _, _, da1 = kin.at(np.array([onset1]))
    sigma_f = max(noise_force, 1e-9 * float(np.max(f)))
    fpeak = float(np.max(f))

    def kinematics(v0, w):
        delta = v0 * tau + g * tau ** 2 / 2 - w * i_f - da
        rate = v0 + g * tau - w * jf - va
        return delta, rate

    # scale of the compression from a rough first guess: V0 from the onset row with a mass of M2-scale
    sigma_onset = float(np.sqrt(noise_acceleration ** 2 * kin.dt * t1[0] ** 3 / 3.0 + (onset1_std * kin.dt) ** 2))

    def residuals(x, dscale):
        v0, w, k, c, n, m = x
        delta, rate = kinematics(v0, w)
        model = _law(delta, rate, k, c, n, m, dscale)
        onset = (v0 * t1[0] + g * t1[0] ** 2 / 2 - w * if1[0] - da1[0]) / max(sigma_onset, 1e-12)
        return np.append((f - model) / sigma_f, onset)

    def jacobian(x, dscale):
        v0, w, k, c, n, m = x
        delta, rate = kinematics(v0, w)
        touch = delta > 0
        xs = np.maximum(delta / dscale, 1e-12)
        xn, xm = xs ** n, xs ** m
        log_x = np.log(xs)
        d_delta = np.where(touch, (k * n * xn + c * m * xm * rate) / xs / dscale, 0.0)
        d_rate = np.where(touch, c * xm, 0.0)
        jac = np.empty((f.size + 1, 6))
        jac[:-1, 0] = d_delta * tau + d_rate
        jac[:-1, 1] = -d_delta * i_f - d_rate * jf
        jac[:-1, 2] = np.where(touch, xn, 0.0)
        jac[:-1, 3] = np.where(touch, xm * rate, 0.0)
        jac[:-1, 4] = np.where(touch, k * xn * log_x, 0.0)
        jac[:-1, 5] = np.where(touch, c * xm * rate * log_x, 0.0)
        jac[:-1] /= -sigma_f
        jac[-1] = [t1[0] / max(sigma_onset, 1e-12), -if1[0] / max(sigma_onset, 1e-12), 0.0, 0.0, 0.0, 0.0]
        return jac

    best = None
    for w0 in START_INVERSE_MASSES:
        v0 = max(float(da1[0] - g * t1[0] ** 2 / 2 + w0 * if1[0]) / max(t1[0], kin.dt), 0.05)
        delta0, _ = kinematics(v0, w0)
        dscale = max(float(np.max(delta0)), 1e-6)
        for n0, m0 in LAW_STARTS:
            x0 = np.array([v0, w0, fpeak, 0.0 if m0 == 0 else 0.3 * fpeak, n0, m0])
            lower = [0.0, 0.0, 0.0, -np.inf, N_BOUNDS[0], M_BOUNDS[0]]
            upper = [np.inf, np.inf, np.inf, np.inf, N_BOUNDS[1], M_BOUNDS[1]]
            try:
                fit = least_squares(residuals, x0, jac=jacobian, args=(dscale,), bounds=(lower, upper),
                                    x_scale="jac", max_nfev=300)
            except (ValueError, np.linalg.LinAlgError):
                continue
            if best is None or fit.cost < best[0].cost:
                best = (fit, dscale)
    fit, dscale = best
    jac = fit.jac
    chi2 = float(fit.fun @ fit.fun)
    dof = fit.fun.size - 6
    try:
        bread = np.linalg.pinv(jac.T @ jac)
    except np.linalg.LinAlgError:
        return fit.x[:2], np.full((2, 2), np.inf), chi2, dof, (np.zeros((2, 0)), np.zeros(0))
    cov = bread * max(1.0, chi2 / max(dof, 1))
    # correlated part: the double-integrated acceleration noise and residual offset shift δ at every sample
    v0, w, k, c, n, m = fit.x
    delta, rate = kinematics(v0, w)
    eps = 1e-6 * dscale
    slope = (_law(delta + eps, rate, k, c, n, m, dscale) - _law(delta - eps, rate, k, c, n, m, dscale)) / (2 * eps)
    dr = np.append(-slope / sigma_f, 1.0 / max(sigma_onset, 1e-12))
    taus = np.append(tau, t1[0])
    weights = (bread @ jac.T) * dr[None, :]  # d theta / d(error of δ at each row)
    cov = cov + noise_acceleration ** 2 * kernel_form(weights, taus, kin.dt)
    if pre_samples > 0:
        shift = weights @ (taus ** 2 / 2.0)
        cov = cov + noise_acceleration ** 2 / pre_samples * np.outer(shift, shift)
    return fit.x[:2], cov[:2, :2], chi2, dof, (weights[:2], taus)
