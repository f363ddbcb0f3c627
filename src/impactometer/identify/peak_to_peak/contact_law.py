"""The contact-law family of the early answer and its least-squares residuals and Jacobian (compiled).

Fc = k·x^n + c·x^m·δ' with x = δ/δ_s (δ_s a scale of the compression, so that k and c are forces), zero where
the bodies do not overlap (δ <= 0); δ and δ' are linear in (V0, w) and the shift d0 of the compression
(:mod:`.robust`): δ = V0·τ + g·τ²/2 − w·IF − D2 + d0, δ' = V0 + g·τ − w·JF − V2. The unknowns are
x = (V0, w, d0, k, c, n, m). Residuals, in units of the force noise: the force samples, then the second onset's row
(δ = 0 there, over its standard error) and the prior of d0 (0 over its standard error). Compiled, because the
fit of :func:`~impactometer.identify.peak_to_peak.early.solve_early` evaluates them some hundred times per answer.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

#: smallest x = δ/δ_s the powers are taken of (x^m with m < 0 stays finite at the edge of contact)
X_FLOOR = 1e-12


@njit(cache=True, inline="always", error_model="numpy")
def _force(delta, rate, k, c, n, m, dscale):
    """Contact force [N] of the family at one compression ``delta`` [m] and rate ``rate`` [m/s]."""
    if delta <= 0.0:
        return 0.0
    x = max(delta / dscale, X_FLOOR)
    return k * x ** n + c * x ** m * rate


@njit(cache=True, error_model="numpy")
def law(delta, rate, k, c, n, m, dscale):
    """Contact force [N] of the family at compressions ``delta`` [m] and rates ``rate`` [m/s] (arrays)."""
    out = np.zeros(delta.size)
    for i in range(delta.size):
        out[i] = _force(delta[i], rate[i], k, c, n, m, dscale)
    return out


@njit(cache=True, inline="always", error_model="numpy")
def _overlap(x, t, i_f, jf, da, va, gravity):
    """δ [m] and δ' [m/s] at time ``t`` since first contact, for the unknowns ``x`` and the integrals there."""
    v0, w, d0 = x[0], x[1], x[2]
    return v0 * t + gravity * t * t / 2.0 - w * i_f - da + d0, v0 + gravity * t - w * jf - va


@njit(cache=True, error_model="numpy")
def overlaps(x, tau, i_f, jf, da, va, gravity):
    """δ [m] and δ' [m/s] at every sample (arrays of the times since first contact and the integrals there)."""
    delta, rate = np.empty(tau.size), np.empty(tau.size)
    for i in range(tau.size):
        delta[i], rate[i] = _overlap(x, tau[i], i_f[i], jf[i], da[i], va[i], gravity)
    return delta, rate


@njit(cache=True, error_model="numpy")
def residuals(x, tau, i_f, jf, da, va, f, gravity, dscale, sigma_f, onset, s1, shift_time):
    """Residual vector of the fit (module notes). ``onset`` = (τ, IF, D2) at the second onset; ``s1`` its row's
    standard error [m]; ``shift_time`` the standard error of t00 [s] (d0's is |V0| times it)."""
    k, c, n, m = x[3], x[4], x[5], x[6]
    out = np.empty(f.size + 2)
    for i in range(f.size):
        delta, rate = _overlap(x, tau[i], i_f[i], jf[i], da[i], va[i], gravity)
        out[i] = (f[i] - _force(delta, rate, k, c, n, m, dscale)) / sigma_f
    out[f.size] = _overlap(x, onset[0], onset[1], 0.0, onset[2], 0.0, gravity)[0] / s1
    out[f.size + 1] = x[2] / max(abs(x[0]) * shift_time, 1e-15)
    return out


@njit(cache=True, error_model="numpy")
def jacobian(x, tau, i_f, jf, da, va, f, gravity, dscale, sigma_f, onset, s1, shift_time):
    """Jacobian of :func:`residuals` with respect to x (same arguments)."""
    k, c, n, m = x[3], x[4], x[5], x[6]
    jac = np.zeros((f.size + 2, 7))
    for i in range(f.size):
        t = tau[i]
        delta, rate = _overlap(x, t, i_f[i], jf[i], da[i], va[i], gravity)
        if delta <= 0.0:
            continue
        xs = max(delta / dscale, X_FLOOR)
        xn, xm = xs ** n, xs ** m
        log_x = math.log(xs)
        d_delta = (k * n * xn + c * m * xm * rate) / xs / dscale
        d_rate = c * xm
        jac[i, 0] = -(d_delta * t + d_rate) / sigma_f
        jac[i, 1] = -(-d_delta * i_f[i] - d_rate * jf[i]) / sigma_f
        jac[i, 2] = -d_delta / sigma_f
        jac[i, 3] = -xn / sigma_f
        jac[i, 4] = -xm * rate / sigma_f
        jac[i, 5] = -k * xn * log_x / sigma_f
        jac[i, 6] = -c * xm * rate * log_x / sigma_f
    jac[f.size, 0] = onset[0] / s1
    jac[f.size, 1] = -onset[1] / s1
    jac[f.size, 2] = 1.0 / s1
    jac[f.size + 1, 2] = 1.0 / max(abs(x[0]) * shift_time, 1e-15)
    return jac
