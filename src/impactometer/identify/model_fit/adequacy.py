"""Model adequacy of a whole-record fit: does the stand model explain the record down to its noise, judged by what
this record's noise allows; and the standard errors of the answer where it does not.

The test reads the weighted residuals r = (data − offset − model)/σ of each channel after first contact (n samples),
σ measured on the pre-trigger (n0 samples, :func:`.engine.observe`):

- **misfit**: v = mean(r²). Under a right model v is the ratio of two sample variances of the same noise (after
  contact and before it), so v − 1 has the σ sqrt(2/n + 2/n0): z_χ = (v − 1)/sqrt(2/n + 2/n0). A longer record
  judges finer, and the error of σ measured on a short pre-trigger is counted (a fixed χ²/dof limit does neither).
- **correlation**: the lag-1 autocorrelation ρ of r after contact against that of the pre-trigger ρ0 (the noise's
  own colour, zero for white noise): z_ρ = (ρ − ρ0)/sqrt(1/n + 1/n0). A model error is smooth over many samples,
  so it correlates the residuals well before it raises χ² visibly. The statistic measures a smooth error against
  the noise: a smooth error e of power P under white noise σ gives ρ ≈ P/(P + σ²), so a record whose residuals carry
  their noise flags an error of power P ≳ Z·σ²/sqrt(n). Where a channel's residuals after contact are significantly
  smaller than its noise σ (misfit z below −:data:`Z_ADEQUATE`: a noise-free simulated record, whose σ is the floor
  :data:`.engine.NOISE_FLOOR`, or a pre-trigger noisier than the record after it), the residuals' own variance no
  longer holds the noise: ρ of any smooth remnant, however small against σ, tends to 1 (integration-level
  differences gave z 11-75 at misfits 0.004-0.16 on noise-free records), and the test would judge the record finer
  than its noise allows. There each lag-1 autocovariance (after and before contact) is taken over the noise's
  variance (over the residuals' own where that is larger: :func:`_lag1`), ρ ≈ P/σ², the same error power relative
  to the noise that a noisy record's test reads, with the same null distribution (the variance of a lag-1
  autocovariance of white noise over σ² is 1/n as that of ρ). A channel whose misfit is not below −Z_ADEQUATE, every
  record that carries its noise, keeps the residuals' own variance (the two agree there to sqrt(2/n)), so its test
  is unchanged.

A record whose four z (two channels) are all within :data:`Z_ADEQUATE` is ``adequate``: the answer's σ is the
Fisher information's. Otherwise the residuals are not the noise, and the σ is the sandwich (heteroskedasticity and
autocorrelation consistent, Newey-West) covariance H⁻¹·S·H⁻¹ of the fit, H the Fisher information and S the
long-run covariance of the scores J_i·r_i with the Bartlett kernel, its bandwidth the lag at which the residuals'
autocorrelation has fallen to noise (:func:`bandwidth`): it counts the model error as the correlated error it is.
A record explained down to its noise can still be of another stand or at another pressure than the one stated, the
fit soaking the difference up into the pressure and the contact: then the fit of its first span (:data:`NESTED_SPAN`)
and the whole fit disagree beyond the σ of their difference (:func:`_nested`, a Hausman specification test); such an
answer is ``widened`` by that difference and its warning names ``--rig`` and ``--pressure``.
Either answer is then checked against the robust answer of the same record within their joint σ (:data:`Z_JOINT`;
:data:`Z_JOINT_ADEQUATE` for an adequate fit, and for a shortened one, whose residuals pass the test above, where it
is the more precise): where they
disagree (another stand, a misread pressure, a pad the model does not hold), the answer is the robust one with a σ
that spans both (``fell back``); an adequate whole-record fit keeps its answer with a σ widened to reach the robust
one.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ...errors import IdentificationError
from ..details import Adequacy
from ..result import Identification
from .engine import GUARD_SAMPLES, LawFit, Observed, Residuals, _restricted, fit_law, solve, window
from .information import covariance

#: the paths an answer takes: the model's fit with its Fisher σ; the fit of the first span the model explains; the
#: whole fit with the sandwich σ; the robust answer
VERDICTS = ("adequate", "shortened", "widened", "fell back")
#: the largest z of the misfit and correlation statistics of an adequate model [-]: four statistics, each a standard
#: normal under a right model, exceed 4 together in 1 record of 4000
Z_ADEQUATE = 4.0
#: the model and the robust answer disagree beyond this many of their joint σ, in M1 or V0 [-] (two nearly
#: independent answers of a right model: 1 record in 200 on either)
Z_JOINT = 3.0
#: ... and for a fit the adequacy test found adequate, over the whole record or over the span a shortened answer is
#: the fit of (a far finer test than the comparison): the robust answer's own σ is short at times on records of the
#: model's own stand (3.6-4.4 joint σ in 3 of 33 records tried; on noise-free records its errors are 2-3 of its own
#: σ, its rows' method bias beyond their noise, while the model's σ is a thousandth of it, so that the joint σ is
#: the robust σ alone and the comparison tests the robust answer), so a disagreement counts from 5. A shortened
#: answer (its fit explains a span, not the whole record) is kept within it only where its σ is below the robust
#: answer's in M1 and V0, as any answer within Z_JOINT is; where it is the less precise or disagrees beyond 5, the
#: robust answer is given (a span of a pad outside the laws, its σ hundreds of times the robust one, gave answers
#: 2-6 times off when kept)
Z_JOINT_ADEQUATE = 5.0
#: the spans after first contact [s] the chosen law is refitted on, longest first, when it does not explain the
#: whole record: the first impact and its rebound (the pad's loading and unloading) come before the minor loops
#: of sustained contact, where pads differ most in how they reload
SPANS = (0.03, 0.015, 0.008)
#: the span after first contact [s] whose fit the whole record's fit is checked against (:func:`_nested`): the
#: first impact and its rebound, every unknown free (the last stage of the continuation, :data:`.select.STAGES`)
NESTED_SPAN = 0.03
#: the nested fits disagree beyond this many σ of their difference, in ln M1 or ln V0 [-]: each of the two is a
#: standard normal under a right model and beyond 4 in 1 record of 16000 (6.3e-5); either is, at most, in 1 record
#: of 8000 (the two are correlated, so fewer)
Z_NESTED = 4.0
#: the most lags the sandwich's bandwidth reaches, as a fraction of the samples after contact [-]
MAX_BANDWIDTH_FRACTION = 0.25


@dataclass(frozen=True)
class _Residual:
    """Each channel's weighted residuals after first contact (2, n), those of the pre-trigger (2, n0), the fit's
    residual vector and the problem it belongs to, and its Jacobian there where the fit kept it."""

    after: np.ndarray
    before: np.ndarray
    problem: Residuals
    vector: np.ndarray
    onset: int
    jacobian: np.ndarray | None = None


def _residuals_of(data: Observed, best: LawFit, quiet: float) -> _Residual | None:
    """The weighted residuals of ``best`` on the part of ``data`` it was fitted to, the pre-trigger's up to
    ``GUARD_SAMPLES`` before ``quiet`` (the instant [s] the noise σ was measured up to, :func:`.engine.observe`);
    None where the model cannot be integrated at its answer."""
    part = window(data, best.end)
    problem = Residuals(part, best.layout)
    known = _restricted(best, problem)
    vector = problem.residuals(best.x) if known is None else known[0]
    if vector is None:
        return None
    tail = vector[:2 * problem.tail.shape[1]].reshape(2, -1)
    grid, fs = problem.grid, problem.grid.sample_rate
    onset = max(int(math.ceil((best.values["contact_time"] - grid.start_time) * fs)), 0)
    # the pre-trigger the noise σ was measured on (the samples up to GUARD_SAMPLES before first contact)
    pre = int(math.floor((quiet - part.grid.start_time) * fs)) - GUARD_SAMPLES
    before = part.channels[:, :max(pre, 2)] / part.noise[:, None] - best.x[problem.q:, None]
    return _Residual(after=tail[:, onset:], before=before, problem=problem, vector=vector, onset=onset,
                     jacobian=None if known is None else known[1])


def _lag1(r: np.ndarray, noise: bool = False) -> float:
    """The lag-1 autocorrelation of ``r`` (weighted residuals, the noise's σ 1) about its mean; with ``noise`` its
    lag-1 autocovariance over the larger of its own variance and the noise's (1)."""
    r = r - r.mean()
    denominator = max(float(r @ r), float(r.size) if noise else 0.0)
    return float(r[1:] @ r[:-1]) / denominator if denominator > 0.0 else 0.0


def _statistics(res: _Residual) -> dict:
    """Per channel: the misfit v and its z, the lag-1 autocorrelation after and before contact and its z (over the
    noise's variance where the misfit is significantly below 1: see the module's docstring)."""
    out: dict = {"misfit": [], "misfit_z": [], "autocorrelation": [], "autocorrelation_before": [],
                 "autocorrelation_z": []}
    for c in range(2):
        after, before = res.after[c], res.before[c]
        n, n0 = max(after.size, 2), max(before.size, 2)
        v = float(np.mean(after ** 2)) if after.size else 1.0
        z_v = (v - 1.0) / math.sqrt(2.0 / n + 2.0 / n0)
        quiet = z_v < -Z_ADEQUATE  # residuals significantly below the noise: correlation against the noise's variance
        rho, rho0 = _lag1(after, quiet), _lag1(before, quiet)
        out["misfit"].append(v)
        out["misfit_z"].append(z_v)
        out["autocorrelation"].append(rho)
        out["autocorrelation_before"].append(rho0)
        out["autocorrelation_z"].append((rho - rho0) / math.sqrt(1.0 / n + 1.0 / n0))
    return out


def _bandwidth(after: np.ndarray) -> int:
    """The sandwich's bandwidth [samples]: the first lag at which the autocorrelation of the residuals after contact
    (both channels pooled) falls below its noise level 2/sqrt(n), at least 1 and at most
    :data:`MAX_BANDWIDTH_FRACTION` of n."""
    n = after.shape[1]
    limit = max(int(MAX_BANDWIDTH_FRACTION * n), 1)
    centred = after - after.mean(axis=1, keepdims=True)
    size = 1 << int(math.ceil(math.log2(2 * n)))
    spectrum = np.fft.rfft(centred, size, axis=1)
    acov = np.fft.irfft(np.abs(spectrum) ** 2, size, axis=1)[:, :limit + 1].sum(axis=0)
    rho = acov / acov[0] if acov[0] > 0.0 else np.zeros_like(acov)
    below = np.flatnonzero(rho[1:] < 2.0 / math.sqrt(n))
    return int(below[0] + 1) if below.size else limit


def _sandwich(res: _Residual, best: LawFit, lags: int) -> np.ndarray:
    """Newey-West covariance of the fit's variables: H⁻¹·S·H⁻¹ with H⁻¹ the fit's inverse Fisher information and S
    the Bartlett-weighted long-run covariance (``lags``) of the scores of each channel's residuals after contact;
    the rows before contact, of the pre-trigger's means and of the priors enter S with their Fisher information."""
    problem = res.problem
    jac = problem.jacobian(best.x) if res.jacobian is None else res.jacobian
    after = [c * problem.tail.shape[1] + res.onset + np.arange(res.after.shape[1]) for c in range(2)]
    rest = np.setdiff1d(np.arange(jac.shape[0]), np.concatenate(after))
    meat = jac[rest].T @ jac[rest]
    for index in after:
        scores = jac[index] * res.vector[index, None]
        meat += scores.T @ scores
        for lag in range(1, lags + 1):
            gamma = scores[lag:].T @ scores[:-lag]
            meat += (1.0 - lag / (lags + 1.0)) * (gamma + gamma.T)
    # the variables the record determines (those it does not have an infinite variance and no share in M1, V0)
    kept = np.isfinite(np.diag(best.cov))
    bread = best.cov[np.ix_(kept, kept)]
    return bread @ meat[np.ix_(kept, kept)] @ bread


def _assess(data: Observed, best: LawFit, quiet: float) -> tuple[Adequacy, float, float]:
    """The adequacy of ``best`` and the σ of ln M1 and ln V0 its answer carries: the Fisher σ inflated by
    sqrt(χ²/dof) where that exceeds 1 when adequate, the sandwich σ (never below that) otherwise. ``quiet``: the
    instant [s] the noise σ was measured up to."""
    inflation = math.sqrt(max(1.0, best.reduced_chi2))
    plain = (math.sqrt(best.cov[0, 0]) * inflation, math.sqrt(best.cov[1, 1]) * inflation)
    res = _residuals_of(data, best, quiet)
    if res is None or res.after.shape[1] < 4:
        return (Adequacy(verdict="adequate", reason="the residuals could not be recomputed; the Fisher σ is given",
                         reduced_chi2=best.reduced_chi2, chi2_z=None, autocorrelation=None, autocorrelation_z=None),
                *plain)
    stats = _statistics(res)
    z_misfit = max(stats["misfit_z"])
    z_rho = max(stats["autocorrelation_z"])
    common = dict(reduced_chi2=best.reduced_chi2, chi2_z=z_misfit, misfit=tuple(stats["misfit"]),
                  autocorrelation=max(stats["autocorrelation"]), autocorrelation_z=z_rho, samples=res.after.shape[1],
                  pre_trigger_samples=res.before.shape[1])
    if max(z_misfit, z_rho) <= Z_ADEQUATE or not np.all(np.isfinite(best.cov[:2, :2])):
        return (Adequacy(verdict="adequate", reason=f"the residuals after contact are the noise of the pre-trigger: "
                         f"misfit z {z_misfit:.2g}, lag-1 autocorrelation z {z_rho:.2g} (each within "
                         f"{Z_ADEQUATE:g})", **common), *plain)
    lags = _bandwidth(res.after)
    cov = _sandwich(res, best, lags)
    wide = (max(math.sqrt(max(cov[0, 0], 0.0)), plain[0]), max(math.sqrt(max(cov[1, 1], 0.0)), plain[1]))
    which = "misfit" if z_misfit > Z_ADEQUATE else "autocorrelation"
    reason = (f"the residuals after contact are not the noise of the pre-trigger (misfit z {z_misfit:.3g}, lag-1 "
              f"autocorrelation z {z_rho:.3g}; {which} beyond {Z_ADEQUATE:g}): the {best.law} model does not "
              f"describe this record down to its noise, so σ is the sandwich (Newey-West) covariance over {lags} lags, "
              f"{wide[0] / plain[0]:.3g} and {wide[1] / plain[1]:.3g} times the Fisher σ of M1 and V0")
    return (Adequacy(verdict="widened", reason=reason, bandwidth=lags,
                     widening=(wide[0] / plain[0], wide[1] / plain[1]), **common), *wide)


def _robust_inflation(robust) -> float:
    """The factor sqrt(max(1, χ²/dof)) [-] by which the σ of the robust answer ``robust`` (an
    :class:`~impactometer.identify.result.Identification` of the peak-to-peak method) is widened where its rows
    scatter beyond their noise (1 where its details state no χ² or no degree of freedom).

    The robust answer is the least-squares solution of rows (onsets, turning points, separations) whose σ counts the
    noise and the scatter the method models; where the record's pad breaks the rows' assumptions (a reload the
    method reads as a flight, a set it does not hold) they disagree with each other beyond that σ, and χ²/dof
    estimates by how much their variance is understated (the Birge ratio, the same rule that inflates the model's
    Fisher σ by sqrt(χ²/dof)). A right record's χ²/dof is near 1, so the σ is then nearly unchanged.
    """
    details = getattr(robust, "details", None)
    chi2, dof = getattr(details, "chi2", None), getattr(details, "dof", None)
    if chi2 is None or dof is None or dof < 1 or not math.isfinite(chi2):
        return 1.0
    return math.sqrt(max(1.0, chi2 / dof))


def _disagreement(model: Identification, robust: Identification) -> float:
    """The larger of |M1 − M1_robust| and |V0 − V0_robust| over their joint σ [-]."""
    return max(abs(model.mass - robust.mass) / math.hypot(model.mass_std, robust.mass_std),
               abs(model.velocity - robust.velocity) / math.hypot(model.velocity_std, robust.velocity_std))


def _shortened(data: Observed, best: LawFit, quiet: float) -> tuple[LawFit, Adequacy, float, float] | None:
    """The fit of ``best``'s law and unknowns on the longest of :data:`SPANS` (shorter than the span it read) that
    the model explains down to the noise, from ``best``'s answer, with its adequacy and σ of ln M1 and ln V0; None
    where no span is explained."""
    read = best.span[0] if best.span is not None else math.inf
    for end in SPANS:
        if end >= read:
            continue
        part = window(data, best.values["contact_time"] + end)
        try:
            fit = fit_law(part, best.layout, best.values, offsets=best.offsets)
        except IdentificationError:
            continue
        fit = replace(fit, span=(end, f"the first {end * 1e3:g} ms after contact: the model explains them down to "
                                      "the noise, not the whole record"))
        adequacy, mass_std, velocity_std = _assess(part, fit, quiet)
        if adequacy.verdict == "adequate" and math.isfinite(mass_std) and math.isfinite(velocity_std):
            return fit, adequacy, mass_std, velocity_std
    return None


def _nested(data: Observed, best: LawFit) -> tuple[float, float, float, float] | None:
    """The specification (Hausman) test of ``best``: the same law and unknowns refitted on the first
    :data:`NESTED_SPAN` after contact, from ``best``'s answer. Under a right model the whole fit is the efficient
    one, so the difference of the two answers has the variance of the short fit less that of the whole (their
    covariance is the whole fit's); a stand or a pressure that the fit soaks up into other parameters explains each
    span to its noise with another parameter set, and the two disagree beyond that σ. Both variances are taken at
    ``best``'s answer (the span's information there, one Jacobian), as the test's null has them: at the short
    fit's own optimum, where the span determines M1 or V0 weakly (a soft pad whose span ends mid-contact), the
    curvature is another, and on in-family Kelvin-Voigt records the variance of the difference shrank to a few %
    of the whole fit's and a right model failed the test (|z| beyond 3 in 6 of 124 records, up to 3.9; taken at
    ``best``'s answer: 1). Returns the z of ln M1 and ln V0 and the differences of ln M1 and ln V0 (short −
    whole); None where ``best`` read no more than 1.5 spans, the short fit fails or a variance is not positive."""
    end = data.grid.start_time + (data.grid.size - 1) / data.grid.sample_rate - best.values["contact_time"]
    if (end if best.span is None else min(best.span[0], end)) <= 1.5 * NESTED_SPAN:
        return None
    part = window(data, best.values["contact_time"] + NESTED_SPAN)
    problem = Residuals(part, best.layout)
    try:
        known = _restricted(best, problem) or (problem.residuals(best.x), problem.jacobian(best.x))
        short = best.layout.values(solve(problem, best.x, information=False, known=known).x[:problem.q])
        at_whole = covariance(known[1])[0]
    except IdentificationError:
        return None
    delta = (math.log(short["mass"] / best.values["mass"]), math.log(short["velocity"] / best.values["velocity"]))
    spread = (at_whole[0, 0] - best.cov[0, 0], at_whole[1, 1] - best.cov[1, 1])
    if not all(math.isfinite(v) and v > 0.0 for v in spread):
        return None
    return delta[0] / math.sqrt(spread[0]), delta[1] / math.sqrt(spread[1]), delta[0], delta[1]
