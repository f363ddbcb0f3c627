"""Early answer of the robust variant: the first two pulses only.

Two onsets give one onset row for two unknowns, so the contact phase is used as well: while the bodies touch,
the measured force must follow one contact law of the compression δ and its rate δ' (both linear in (V0, w), see
:mod:`robust`), the same law in both pulses. The law is modelled as Fc = k·δ^n + c·δ^m·δ' with (k, c, n, m) nuisance
unknowns -- Kelvin-Voigt is n = 1, m = 0 and Hunt-Crossley n = m = 3/2 -- and fitted to the force samples of both
pulses together with the onset row of the second pulse (δ = 0 there), by nonlinear least squares in units of the
force noise. The covariance adds the propagated double-integrated acceleration noise and residual offsets to the
force-noise part (sandwich form), inflated by the reduced chi-square when it exceeds 1.

:func:`combine` joins this fit with the agnostic answer (the ``contact_phase`` option), with the acceleration
noise the two share.
"""

from __future__ import annotations

import contextlib
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from scipy.optimize import least_squares

from . import contact_law
from .covariance import DIP_SIGMAS, kernel_form, normal_inverse

#: starting (n, m) exponents of the law: Kelvin-Voigt and Hunt-Crossley
LAW_STARTS = ((1.0, 0.0), (1.5, 1.5))
#: starting 1/M1 [1/kg] (the fit is started from each, with each law, and the best kept)
START_INVERSE_MASSES = (1.0 / 20.0,)
#: bounds of the exponents n and m
N_BOUNDS, M_BOUNDS = (0.8, 2.5), (-0.5, 2.5)


#: the law fits the whole pulses when their chi-square exceeds its degrees of freedom ν by at most this many
#: standard deviations √(2ν) of it [-]
FIT_SIGMAS = 4.0
#: a fit that fails the chi-square test is refused when its force residual beyond the noise is also this fraction
#: of the force (RMS over the fitted samples) or more: the law family does not describe the contact; below it the
#: model error is too small to matter, as in noise-free records, whose chi-square fails on any model error [-]
MISFIT_LIMIT = 0.01


@dataclass(frozen=True)
class ContactFit:
    """The contact-phase fit: ``theta`` = (V0 [m/s], w = 1/M1 [1/kg]) and its covariance ``cov``, the fit's
    chi-square and degrees of freedom, d theta / d(error of δ) ``weights`` (2, n) at the times ``taus`` (n,) [s],
    what was used ``info`` (``samples``, ``onset_row``, ``branches``; ``branches`` is ``none`` where there is no
    answer, and ``refusal`` then says why; ``misfit`` of a fit) and the fit's parameters ``start`` (the seven
    unknowns and the overlap scale) from which another fit may start."""

    theta: np.ndarray
    cov: np.ndarray
    chi2: float = np.inf
    dof: int = 0
    weights: np.ndarray = field(default_factory=lambda: np.zeros((2, 0)))
    taus: np.ndarray = field(default_factory=lambda: np.zeros(0))
    info: dict[str, Any] = field(default_factory=dict)
    start: tuple[np.ndarray, float] | None = None

    @property
    def passes(self) -> bool:
        """The chi-square test: at most ``FIT_SIGMAS`` standard deviations √(2ν) above ν = ``dof``."""
        return bool(self.chi2 <= self.dof + FIT_SIGMAS * np.sqrt(2.0 * max(self.dof, 1)))


def _failed(theta=None) -> ContactFit:
    """A fit without an answer (``theta`` NaN unless given; an infinite covariance)."""
    return ContactFit(theta=np.full(2, np.nan) if theta is None else theta, cov=np.full((2, 2), np.inf))


def solve_early(kin, pulses, onset1, onset1_std, *, noise_force, noise_acceleration, pre_samples, peaks, gap):
    """(V0, w) from the contact phase of the first two pulses and the onset of the second.

    ``pulses`` are the first two pulses (the second may be running), ``peaks`` the samples of their force peaks
    and ``gap`` the (first, last) samples between them. A law of the family loads and unloads along one curve;
    a hysteretic contact does not, but it still loads along one. So the law is fitted to the whole pulses, and
    where it does not fit them (a chi-square more than ``FIT_SIGMAS`` standard deviations above its degrees of
    freedom) to their loading parts alone (each onset to its peak); where these do not fit either, and miss by
    ``MISFIT_LIMIT`` of the force or more beyond the noise, there is no answer (the contact is not one of the
    family, or the pulses found are not whole contacts). Where the overlap stayed positive throughout the gap (by
    ``DIP_SIGMAS`` standard errors: a pad that unloaded to zero force and loaded again, so the second pulse is not
    a fresh contact) there is no answer either: the first pulse alone determines V0 but hardly the mass (theta is
    NaN).

    Returns the :class:`ContactFit`.
    """
    common = dict(noise_force=noise_force, noise_acceleration=noise_acceleration, pre_samples=pre_samples)
    whole = _fit(kin, pulses, [p.end for p in pulses], onset1, onset1_std, **common)
    fits = bool(np.all(np.isfinite(whole.theta))) and whole.passes
    chosen = whole if fits else _fit(kin, pulses, [pk + 1 for pk in peaks], onset1, onset1_std, start=whole.start,
                                     **common)
    if not fits and not chosen.passes and chosen.info.get("misfit", 0.0) > MISFIT_LIMIT:
        # not even the loading parts follow one law of the family, beyond the noise and by a visible part of the
        # force: the contact phase says nothing reliable
        return _no_answer(f"the first two pulses follow no law Fc = k·δ^n + c·δ^m·δ' of the early fit's family "
                          f"(even their loading parts miss it by {chosen.info['misfit']:.1%} of the force beyond the "
                          "noise): a hysteretic contact such as a pad, or pulses that are not whole contacts")
    gap_index = np.arange(gap[0], gap[1], dtype=float)
    if gap_index.size and np.all(np.isfinite(chosen.theta)):
        at = kin.at(gap_index)
        tau, i_f, da = at.tau, at.force_double, at.displacement
        v0, w = chosen.theta
        delta = v0 * tau + kin.gravity * tau ** 2 / 2 - w * i_f - da
        k = int(np.argmin(delta))
        grad = np.array([tau[k], -i_f[k]])
        if delta[k] > DIP_SIGMAS * np.sqrt(max(float(grad @ chosen.cov @ grad), 0.0)):
            # the first pulse alone determines V0 but hardly the mass: no answer
            return _no_answer("the second pulse is not a fresh contact (the overlap stayed positive through the gap "
                              "before it), and the first pulse alone fixes the velocity but hardly the mass")
    return replace(chosen, info={"samples": int(chosen.taus.size - 1), "onset_row": True,
                                 "branches": "whole" if fits else "loading"})


def _no_answer(reason: str) -> ContactFit:
    """What :func:`solve_early` returns where the contact phase gives no answer, and why (``info["refusal"]``)."""
    return replace(_failed(), info={"samples": 0, "onset_row": False, "branches": "none", "refusal": reason})


def _fit(kin, pulses, stops, onset1, onset1_std, *, noise_force, noise_acceleration, pre_samples, start=None):
    """The law fit to the samples of ``pulses`` up to ``stops`` and, unless ``onset1`` is None, the second
    onset's row (see :func:`solve_early`), started from each law of ``LAW_STARTS`` or from ``start`` (the
    parameters of another fit). Returns the :class:`ContactFit`.

    The first contact t00 is refined by the fit: a shift d0 of the compression (an error ε of t00 shifts δ by
    −V0·ε at every sample) is a seventh unknown, with the foot fit's standard error of t00 as its prior.
    """
    idx = np.concatenate([np.arange(max(p.zero, 0), stop, dtype=float) for p, stop in zip(pulses, stops,
                                                                                           strict=True)])
    use_onset = onset1 is not None
    onset1 = float(idx[-1]) if onset1 is None else onset1
    at = kin.at(idx)
    tau, f, jf, i_f, va, da = at.tau, at.force, at.force_impulse, at.force_double, at.velocity_change, at.displacement
    g = kin.gravity
    at1 = kin.at(np.array([onset1]))
    t1, jf1, if1, va1, da1 = at1.tau, at1.force_impulse, at1.force_double, at1.velocity_change, at1.displacement
    sigma_f = max(noise_force, 1e-9 * float(np.max(f)))
    fpeak = float(np.max(f))

    def kinematics(v0, w, d0):  # δ, δ' at the samples
        return contact_law.overlaps(np.array([v0, w, d0]), tau, i_f, jf, da, va, float(g))

    def onset_sigma(v0, w):  # the second onset row: double-integrated noise and its time error
        if not use_onset:
            return 1e30
        closing = max(v0 + g * t1[0] - w * jf1[0] - va1[0], 0.0)
        white = noise_acceleration ** 2 + (w * noise_force) ** 2
        return max(float(np.sqrt(white * kin.dt * t1[0] ** 3 / 3.0 + (closing * onset1_std * kin.dt) ** 2)), 1e-15)

    data = (tau, i_f, jf, da, va, f, float(g))
    onset = np.array([t1[0], if1[0], da1[0]])
    shift_time = kin.onset_std0 * kin.dt  # the standard error of t00 [s]: d0's is |V0| times it

    def residuals(x, dscale, s1):
        return contact_law.residuals(np.asarray(x, dtype=float), *data, dscale, sigma_f, onset, s1, shift_time)

    def jacobian(x, dscale, s1):
        return contact_law.jacobian(np.asarray(x, dtype=float), *data, dscale, sigma_f, onset, s1, shift_time)

    lower = [0.0, 0.0, -np.inf, 0.0, -np.inf, N_BOUNDS[0], M_BOUNDS[0]]
    upper = [np.inf, np.inf, np.inf, np.inf, np.inf, N_BOUNDS[1], M_BOUNDS[1]]
    if start is None:
        starts = []
        for w0 in START_INVERSE_MASSES:
            v0 = max(float(da1[0] - g * t1[0] ** 2 / 2 + w0 * if1[0]) / max(t1[0], kin.dt), 0.05)
            delta0, _ = kinematics(v0, w0, 0.0)
            dscale = max(float(np.max(delta0)), 1e-6)
            starts += [(np.array([v0, w0, 0.0, fpeak, 0.0 if m0 == 0 else 0.3 * fpeak, n0, m0]), dscale)
                       for n0, m0 in LAW_STARTS]
    else:
        starts = [start]
    best = None
    for x, dscale in starts:
        try:
            s1 = onset_sigma(x[0], x[1])
            fit = least_squares(residuals, np.clip(x, lower, upper), jac=jacobian, args=(dscale, s1),
                                bounds=(lower, upper), x_scale="jac", max_nfev=50)
        except (ValueError, np.linalg.LinAlgError):
            continue
        if best is None or fit.cost < best[0].cost:
            best = (fit, dscale, s1)
    if best is not None and abs(onset_sigma(*best[0].x[:2]) / best[2] - 1.0) > 0.1:
        fit, dscale, _ = best  # the onset row's weight depends on the estimate: once more with the new one
        s1 = onset_sigma(*fit.x[:2])
        with contextlib.suppress(ValueError, np.linalg.LinAlgError):
            best = (least_squares(residuals, fit.x, jac=jacobian, args=(dscale, s1), bounds=(lower, upper),
                                  x_scale="jac", max_nfev=50), dscale, s1)
    if best is None:
        return _failed()
    fit, dscale, s1 = best
    jac = fit.jac
    chi2 = float(fit.fun @ fit.fun)
    dof = fit.fun.size - 7
    try:
        bread = normal_inverse(jac)
    except np.linalg.LinAlgError:
        return replace(_failed(fit.x[:2]), chi2=chi2, dof=dof)
    cov = bread * max(1.0, chi2 / max(dof, 1))
    # the residual beyond the noise, as a fraction of the force (RMS over the fitted samples)
    excess = max(float(np.mean((fit.fun[:-2] * sigma_f) ** 2)) - noise_force ** 2, 0.0)
    info = {"misfit": float(np.sqrt(excess / max(float(np.mean(f ** 2)), 1e-300)))}
    # correlated part: the double-integrated acceleration noise and residual offset shift δ at every sample
    v0, w, d0, k, c, n, m = fit.x
    delta, rate = kinematics(v0, w, d0)
    eps = 1e-6 * dscale
    slope = (contact_law.law(delta + eps, rate, k, c, n, m, dscale)
             - contact_law.law(delta - eps, rate, k, c, n, m, dscale)) / (2 * eps)
    dr = np.append(-slope / sigma_f, 1.0 / s1)
    taus = np.append(tau, t1[0])
    weights = (bread @ jac[:-1].T) * dr[None, :]  # d theta / d(error of δ at each row)
    cov = cov + noise_acceleration ** 2 * kernel_form(weights, taus, kin.dt)
    if pre_samples > 0:
        shift = weights @ (taus ** 2 / 2.0)
        cov = cov + noise_acceleration ** 2 / pre_samples * np.outer(shift, shift)
    return ContactFit(theta=fit.x[:2], cov=cov[:2, :2], chi2=chi2, dof=dof, weights=weights[:2], taus=taus, info=info,
                      start=(fit.x, dscale))


def combine(first, second, *, noise_acceleration, pre_samples, dt):
    """Best linear unbiased combination of two estimates of (V0, w) that share the acceleration noise.

    ``first`` and ``second`` are (theta, cov, (gain, tau)) with ``gain`` = d theta / d(error of D2 at the times
    ``tau``); their cross-covariance follows from the double-integrated acceleration noise and the residual
    offset. Returns (theta, cov), or None where the two cannot be combined: an estimate that is not finite, or a
    cross-covariance the two covariances cannot hold (a joint covariance that is not positive definite, where the
    weights of the combination would extrapolate far beyond both estimates).
    """
    (t1, c1, (g1, tau1)), (t2, c2, (g2, tau2)) = first, second
    if not all(np.all(np.isfinite(x)) for x in (t1, c1, t2, c2)):
        return None
    weights = np.zeros((4, tau1.size + tau2.size))
    weights[:2, :tau1.size] = g1
    weights[2:, tau1.size:] = g2
    cross = noise_acceleration ** 2 * kernel_form(weights, np.concatenate([tau1, tau2]), dt)[:2, 2:]
    if pre_samples > 0:
        cross = cross + noise_acceleration ** 2 / pre_samples * np.outer(g1 @ (tau1 ** 2 / 2), g2 @ (tau2 ** 2 / 2))
    sigma = np.block([[c1, cross], [cross.T, c2]])
    h = np.vstack([np.eye(2), np.eye(2)])
    try:
        np.linalg.cholesky(sigma)
        # the two must agree within their errors; where they do not, both are less certain than stated (Birge)
        diff = t1 - t2
        spread = np.linalg.solve(c1 + c2 - cross - cross.T, diff) @ diff / 2.0
        sigma = sigma * max(1.0, float(spread))
        info = h.T @ np.linalg.solve(sigma, h)
        cov = np.linalg.inv(info)
        theta = cov @ (h.T @ np.linalg.solve(sigma, np.concatenate([t1, t2])))
    except np.linalg.LinAlgError:
        return None
    return theta, cov
