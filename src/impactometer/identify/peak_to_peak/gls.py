"""The generalised least squares of the robust peak-to-peak identification (:mod:`.robust`), in named steps.

One solve (:func:`solve`): the rows a record offers (:class:`Equations`) and their atoms (:func:`rows_of`); from
ordinary least squares, Gauss-Newton iterations (:func:`iterate`) that each linearise the rows about the estimate,
weigh them by their covariance there (:func:`noise_covariance`, :func:`with_model_error`), take one GLS step over
the rows kept (:func:`gls_step`), judge the gaps before the onsets at ``FIRST_JUDGEMENT`` and ``SECOND_JUDGEMENT``
(:func:`judge_gaps`: an onset after a gap that was no flight leaves the rows) and grow each contact-model group's
model-error variance (:func:`model_error`); then the answer with its covariance and the slow errors of the channels
(:func:`summary`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from ..details import GapReadings, ModelError, Nuisances, RowsUsed, SlowErrors
from .covariance import DIP_SIGMAS, atom_kernel, normal_inverse, slow_covariance, slow_errors
from .kinematics import Kinematics, KinematicsAt

#: Gauss-Newton / reweighting iterations, at most: fewer once the solution changes by less than CONVERGED
#: (relative) from one to the next
ITERATIONS = 10
CONVERGED = 1e-6


@dataclass(frozen=True)
class Equations:
    """The rows available in a record: fractional sample indices of the segment, standard errors in samples.

    ``onsets`` excludes t00; ``gaps`` holds the (first, last) samples of the force-free gap before each onset;
    ``peaks`` are the samples of the largest overlap of the separating pulses (force peaks); ``stage_b`` flags the
    extrema in sustained contact and ``stage_b_samples`` counts the samples between the first and last of them.
    """

    onsets: np.ndarray
    onset_std: np.ndarray
    extrema: np.ndarray = field(default_factory=lambda: np.zeros(0))
    extremum_std: np.ndarray = field(default_factory=lambda: np.zeros(0))
    stage_b: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))
    separations: np.ndarray = field(default_factory=lambda: np.zeros(0))
    separation_std: np.ndarray = field(default_factory=lambda: np.zeros(0))
    peaks: np.ndarray = field(default_factory=lambda: np.zeros(0))
    stage_b_samples: int = 0
    gaps: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), dtype=int))


@dataclass(frozen=True)
class Solution:
    """(V0 [m/s], w [1/kg]), their covariance, the fit's chi-square and degrees of freedom, the nuisances, the
    rows used, and d(V0, w)/d(error of a row) with the rows' times ``tau`` [s] for combining with another
    estimate."""

    theta: np.ndarray
    cov: np.ndarray
    chi2: float
    dof: int
    nuisances: Nuisances
    used: RowsUsed
    gain: np.ndarray
    tau: np.ndarray
    #: largest model-error variance of a group over its noise variance [-]
    scatter: float = 0.0
    #: where the gaps read as flights and as a contact that kept a set fit alike: (V0 [m/s], M1 [kg]) of each
    readings: GapReadings | None = None


#: kinds of rows and atoms: onsets, extrema, separations, and the peak overlap of a separation
ONSET, EXTREMUM, SEPARATION, PEAK = 0, 1, 2, 3
#: largest set fraction μ of the separations [-]
SET_MAX = 0.95
#: fewest turning points and separations for their groups to be used: a group must outnumber its own nuisances
#: (the turning points bring the lag λe, the separations the lag λs and the set μ)
MIN_EXTREMA = 2
MIN_SEPARATIONS = 3

#: the iterations at which the gaps are judged by the estimate so far: first by the estimate the onsets have not
#: pulled (where stage B gives one of its own), then by the estimate with the sure flights; the solution is taken as
#: settled only after the second
FIRST_JUDGEMENT, SECOND_JUDGEMENT = 2, 4


@dataclass(frozen=True)
class Rows:
    """The rows of one solve and their atoms (module notes): each row is a sum of atoms cd·δ(t) + cv·δ'(t) +
    ca·δ''(t), a separation two of them (at Sk and at Pk); the rows are the onsets, then the extrema, then the
    separations."""

    #: kind of each row (ONSET, EXTREMUM, SEPARATION)
    group: np.ndarray
    #: kind of each atom: the rows' own, then PEAK for the peak overlap of each separation
    kind: np.ndarray
    #: (rows, atoms): the atoms each row sums
    mixer: np.ndarray
    #: time of each atom from t00 [s] and its standard error [s]
    tau: np.ndarray
    atom_std: np.ndarray
    #: δ, δ', δ'' of every atom as (design over (V0, w, b), constant)
    basis: dict
    #: the contact-model nuisances fitted (λe with the extrema, λs and μ with the separations)
    nonlinear: list
    #: the offset b is fitted (a pre-trigger measured it)
    fit_b: bool
    onsets: int
    extrema: int
    separations: int

    @property
    def n_lin(self) -> int:
        """Linear parameters: V0, w and, where fitted, b."""
        return 2 + self.fit_b

    @property
    def rows(self) -> int:
        return self.onsets + self.extrema + self.separations


def rows_of(kin: Kinematics, eqs: Equations, *, pre_samples: int, lag_max: float) -> Rows:
    """The rows of ``eqs`` a solve uses: a group of rows that rests on a model of the contact only where it
    outnumbers its own nuisances."""
    dt, g = kin.dt, kin.gravity
    n_on = eqs.onsets.size
    use_ext = eqs.extrema.size >= MIN_EXTREMA and lag_max > 0
    use_sep = eqs.separations.size >= MIN_SEPARATIONS and lag_max > 0
    n_ext, n_sep = eqs.extrema.size * use_ext, eqs.separations.size * use_sep
    rows = n_on + n_ext + n_sep
    group = np.r_[np.full(n_on, ONSET), np.full(n_ext, EXTREMUM), np.full(n_sep, SEPARATION)]
    # atoms: the rows' own times, then the peak overlap of each separation
    atom_row = np.r_[np.arange(rows), n_on + n_ext + np.arange(n_sep)]
    atom_index = np.concatenate([eqs.onsets, eqs.extrema[:n_ext], eqs.separations[:n_sep], eqs.peaks[:n_sep]])
    atom_std = np.concatenate([eqs.onset_std, eqs.extremum_std[:n_ext], eqs.separation_std[:n_sep],
                               np.zeros(n_sep)]) * dt
    at = kin.at(atom_index)
    tau = at.tau
    basis = {"d": (np.column_stack([tau, -at.force_double, tau ** 2 / 2.0]), g * tau ** 2 / 2.0 - at.displacement),
             "v": (np.column_stack([np.ones_like(tau), -at.force_impulse, tau]), g * tau - at.velocity_change),
             "a": (np.column_stack([np.zeros_like(tau), -at.force, np.ones_like(tau)]), g - at.acceleration)}
    mixer = np.zeros((rows, atom_index.size))
    mixer[atom_row, np.arange(atom_index.size)] = 1.0
    return Rows(group=group, kind=np.r_[group, np.full(n_sep, PEAK)], mixer=mixer, tau=tau, atom_std=atom_std,
                 basis=basis, nonlinear=["lag_e"] * use_ext + ["lag_s", "set"] * use_sep, fit_b=pre_samples > 0,
                 onsets=n_on, extrema=n_ext, separations=n_sep)


def atom_coefficients(r: Rows, phi: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(cd, cv, ca) of every atom at the nuisances ``phi``."""
    kind = r.kind
    cd = np.select([kind == ONSET, kind == SEPARATION, kind == PEAK], [1.0, 1.0, -phi.get("set", 0.0)], 0.0)
    cv = np.select([kind == EXTREMUM, kind == SEPARATION], [1.0, phi.get("lag_s", 0.0)], 0.0)
    ca = np.where(kind == EXTREMUM, phi.get("lag_e", 0.0), 0.0)
    return cd, cv, ca


def linearised(r: Rows, coefficients) -> tuple[np.ndarray, np.ndarray]:
    """Design over the linear parameters and constant of every row: row = design·θ + const."""
    cd, cv, ca = coefficients
    basis = r.basis
    design = r.mixer @ ((cd[:, None] * basis["d"][0] + cv[:, None] * basis["v"][0]
                         + ca[:, None] * basis["a"][0])[:, :r.n_lin])
    const = r.mixer @ (cd * basis["d"][1] + cv * basis["v"][1] + ca * basis["a"][1])
    return design, const


def atom_values(r: Rows, theta_lin: np.ndarray) -> dict:
    """δ, δ', δ'' of every atom at the linear parameters ``theta_lin``."""
    full = np.r_[theta_lin[:2], theta_lin[2] if r.fit_b else 0.0]
    return {key: m @ full + c for key, (m, c) in r.basis.items()}


def nuisance_derivatives(r: Rows, vals: dict) -> np.ndarray:
    """d(row)/d(nonlinear parameter) at the atoms' values ``vals``."""
    if not r.nonlinear:
        return np.zeros((r.rows, 0))
    cols = {"lag_e": np.where(r.kind == EXTREMUM, vals["a"], 0.0),
            "lag_s": np.where(r.kind == SEPARATION, vals["v"], 0.0),
            "set": np.where(r.kind == PEAK, -vals["d"], 0.0)}
    return np.column_stack([r.mixer @ cols[name] for name in r.nonlinear])


def noise_covariance(r: Rows, kin: Kinematics, coefficients, vals: dict, v0: float, white: float) -> np.ndarray:
    """Covariance of the rows from the double-integrated white noise (variance ``white`` [(m/s²)²]), the errors
    of the atoms' times and the error of t00, which moves every overlap alike."""
    cd, cv, ca = coefficients
    rate = cd * vals["v"] + cv * vals["a"]  # d(atom)/dt, the third derivative left out
    cov = white * (r.mixer @ atom_kernel(r.tau, cd, cv, kin.dt) @ r.mixer.T)
    cov += np.diag(r.mixer @ ((rate * r.atom_std) ** 2 + ca ** 2 * white))
    shift = r.mixer @ (cd * v0 * kin.onset_std0 * kin.dt)
    cov += np.outer(shift, shift)
    return cov


def with_model_error(cov: np.ndarray, model: np.ndarray, group: np.ndarray) -> np.ndarray:
    """The rows' covariance with each group's model-error variance (and a jitter that keeps it positive)."""
    return cov + np.diag(model[group] + 1e-30 + 1e-18 * float(np.mean(np.diag(cov))))


class Step(NamedTuple):
    """One generalised least-squares step over the rows kept."""

    #: (V0, w, [b,] nuisances)
    solution: np.ndarray
    #: whitened design and target of the rows kept, then the prior row of b where b is fitted
    aw: np.ndarray
    yw: np.ndarray
    #: Cholesky factor of the kept rows' covariance
    chol: np.ndarray


def gls_step(jac: np.ndarray, target: np.ndarray, cov: np.ndarray, keep: np.ndarray, *, fit_b: bool,
              white: float, pre_samples: int) -> Step:
    """Generalised least squares of ``jac``·x = ``target`` over the rows ``keep`` with their covariance ``cov``;
    where b is fitted, with the pre-trigger's prior row b = 0 ± its standard error (the residual offset)."""
    chol = np.linalg.cholesky(cov[np.ix_(keep, keep)])
    aw = np.linalg.solve(chol, jac[keep])
    yw = np.linalg.solve(chol, target[keep])
    if fit_b:
        prior = np.zeros(jac.shape[1])
        prior[2] = 1.0 / np.sqrt(white / pre_samples)
        aw = np.vstack([aw, prior])
        yw = np.append(yw, 0.0)
    return Step(np.linalg.lstsq(aw, yw, rcond=None)[0], aw, yw, chol)


def judge_gaps(gap_basis: list[KinematicsAt], theta: np.ndarray, aw: np.ndarray, r: Rows, g: float, *, strong: bool,
          first: bool) -> np.ndarray:
    """The onsets whose gap was no flight (the overlap stayed positive throughout it), judged by the estimate
    ``theta`` with the covariance of the whitened design ``aw``.

    First judged by the estimate without the onsets: sure flights and sure dips; the unsure ones are left out until
    the estimate from the other rows, sure flights included, settles them by sign. Without a stage-B estimate of
    its own (``strong`` false) the estimate leans on the onsets: only a sure dip loses its row."""
    least, spread = _least_overlap(gap_basis, theta, normal_inverse(aw)[:r.n_lin, :r.n_lin], g, r.fit_b)
    threshold = (-DIP_SIGMAS * spread if first else 0.0) if strong else DIP_SIGMAS * spread
    return least > threshold


def model_error(model: np.ndarray, resid: np.ndarray, group: np.ndarray, noise_diag: np.ndarray) -> np.ndarray:
    """Each contact-model group's model-error variance, grown until its chi-square matches its rows.

    ``resid`` are the whitened residuals of the rows (of the groups ``group``, with the noise variances
    ``noise_diag``): those of a later group are its innovations given the earlier rows, so its own chi-square."""
    model = model.copy()
    for k in (EXTREMUM, SEPARATION):
        inside = group == k
        if inside.any():
            excess = float(np.sum(resid[inside] ** 2)) / int(inside.sum())
            noise_part = float(np.mean(noise_diag[inside]))
            model[k] = max((model[k] + noise_part) * excess - noise_part, 0.0)
    return model


class Fit(NamedTuple):
    """Where the iterations of :func:`solve` ended."""

    step: Step
    theta: np.ndarray
    phi: dict
    model: np.ndarray
    coefficients: tuple
    dips: np.ndarray
    keep: np.ndarray
    noise_diag: np.ndarray
    white: float


def solve(kin: Kinematics, eqs: Equations, *, noise_force: float, noise_acceleration: float,
          pre_samples: int, lag_max: float, judge_by_stage_b: bool) -> Solution:
    """Generalised least squares for (V0, w) from the rows of ``eqs`` (the equations: :mod:`.robust`).

    Parameters
    ----------
    kin : Kinematics
    eqs : Equations
    noise_force, noise_acceleration : float
        White-noise standard deviations [N], [m/s²].
    pre_samples : int
        Samples the offsets were removed with (0: no offset correction, b is taken as zero).
    lag_max : float
        Largest lag λe, λs [s].

    Notes
    -----
    Each row is a sum of atoms cd·δ(t) + cv·δ'(t) + ca·δ''(t); a separation has two (at Sk and at Pk). Extrema
    and separations rest on models of the contact (the lags, the set): a group is used only when it outnumbers
    its own nuisances, and where it scatters more than its noise explains, a white model-error variance is added
    to it until its chi-square matches its rows, so a poor model weighs less instead of pulling the estimate.
    Starting from ordinary least squares, each iteration linearises the rows about the estimate (Gauss-Newton in
    the nuisances), weighs them by their covariance at it, judges the gaps at FIRST_JUDGEMENT and
    SECOND_JUDGEMENT (:func:`judge_gaps`: an onset after a gap that was no flight is left out) and updates the model
    error (:func:`model_error`).
    """
    r = rows_of(kin, eqs, pre_samples=pre_samples, lag_max=lag_max)
    fit = iterate(r, kin, eqs, noise_force=noise_force, noise_acceleration=noise_acceleration,
                  pre_samples=pre_samples, lag_max=lag_max, strong=judge_by_stage_b and r.extrema > 0)
    return summary(r, kin, eqs, fit, pre_samples=pre_samples)


def iterate(r: Rows, kin: Kinematics, eqs: Equations, *, noise_force: float, noise_acceleration: float,
            pre_samples: int, lag_max: float, strong: bool) -> Fit:
    """The iterations of :func:`solve` (``strong``: stage B has an estimate of its own that judges the gaps
    before the onsets are used)."""
    g = kin.gravity
    bounds = {"lag_e": (0.0, lag_max), "lag_s": (0.0, lag_max), "set": (0.0, SET_MAX)}
    phi = {name: 0.0 for name in r.nonlinear}
    # a gap in the force need not be a flight: a pad with a set unloads to zero force and may load again before
    # the bodies part; such an onset is not at zero overlap, and its row is dropped where the estimate shows
    # that the overlap stayed positive throughout the gap
    gap_index = [np.arange(lo, hi, max((hi - lo) // 64, 1), dtype=float) for lo, hi in eqs.gaps[:r.onsets]]
    gap_basis = [kin.at(i) for i in gap_index]
    # the onsets are first left out where the other rows determine the answer, so that a gap is judged by an
    # estimate its own (perhaps wrong) onset row has not pulled
    dips = np.full(r.onsets, strong and bool(gap_basis), dtype=bool)
    design, const = linearised(r, atom_coefficients(r, phi))
    theta: np.ndarray = np.linalg.lstsq(design, -const, rcond=None)[0]  # the start: ordinary least squares
    model = np.zeros(3)  # model-error variance of each group [m², (m/s)² for extrema]
    previous = np.zeros(0)
    step: Step | None = None
    for it in range(ITERATIONS):
        coefficients = atom_coefficients(r, phi)
        design, const = linearised(r, coefficients)
        vals = atom_values(r, theta)
        if it in (FIRST_JUDGEMENT, SECOND_JUDGEMENT) and gap_basis and step is not None:
            dips = judge_gaps(gap_basis, theta, step.aw, r, g, strong=strong, first=it == FIRST_JUDGEMENT)
        keep = np.r_[~dips, np.ones(r.rows - r.onsets, dtype=bool)]
        white = noise_acceleration ** 2 + (max(theta[1], 0.0) * noise_force) ** 2
        noise_cov = noise_covariance(r, kin, coefficients, vals, theta[0], white)
        noise_diag = np.diag(noise_cov).copy()  # each row's variance from the noise alone, before the model error
        jac_nl = nuisance_derivatives(r, vals)
        target = -const + jac_nl @ np.array([phi[name] for name in r.nonlinear])  # Gauss-Newton about φ
        step = gls_step(np.column_stack([design, jac_nl]), target, with_model_error(noise_cov, model, r.group),
                         keep, fit_b=r.fit_b, white=white, pre_samples=pre_samples)
        if it > SECOND_JUDGEMENT and np.allclose(step.solution, previous, rtol=CONVERGED, atol=0.0):
            break  # settled (the gaps were judged): another pass would repeat it
        previous = step.solution
        theta = step.solution[:r.n_lin]
        for k, name in enumerate(r.nonlinear):
            phi[name] = float(np.clip(step.solution[r.n_lin + k], *bounds[name]))
        kept = int(np.count_nonzero(keep))
        resid = (step.yw - step.aw @ step.solution)[:kept]
        model = model_error(model, resid, r.group[keep], noise_diag[keep])
    if step is None:
        raise ValueError(f"ITERATIONS must be >= 1, got {ITERATIONS}")
    return Fit(step=step, theta=theta, phi=phi, model=model, coefficients=coefficients, dips=dips, keep=keep,
                noise_diag=noise_diag, white=white)


def summary(r: Rows, kin: Kinematics, eqs: Equations, fit: Fit, *, pre_samples: int) -> Solution:
    """The Solution where the iterations ended: covariance with the slow errors, chi-square, nuisances, rows
    used, and the gain of (V0, w) on each row (zero on the rows left out)."""
    sol, aw, yw, chol = fit.step
    rows, kept, dropped = r.rows, int(np.count_nonzero(fit.keep)), int(np.count_nonzero(fit.dips))
    resid = yw - aw @ sol
    chi2 = float(resid @ resid)
    dof = int(rows - dropped - (aw.shape[1] - r.fit_b))
    bread = normal_inverse(aw)
    gain = np.zeros((2, rows))
    gain[:, fit.keep] = (bread @ aw.T)[:2, :kept] @ np.linalg.inv(chol)
    # slow errors of the channels (a drift; an offset where no pre-trigger measures one) are no white noise: the
    # answer with them estimated differs from this one by what they may have done, and the difference joins the
    # covariance, as the readings of the gaps do in :func:`.robust.solve_rows`
    room = rows - dropped - aw.shape[1] - 1
    slow = slow_errors(kin.t00, kin.dt, pre_samples, r.tau, fit.coefficients, r.mixer[fit.keep], chol, aw[:kept],
                       yw[:kept], fit.white, room=room) if r.fit_b or room >= 1 else None
    cov_out = bread[:2, :2]
    slow_found: SlowErrors | None = None
    if slow is not None:
        found, cov_slow = slow
        moved = sol[:2] - found[:2]
        cov_out = slow_covariance(cov_out, cov_slow, moved, bounded=pre_samples > 0)
        slow_found = SlowErrors(offset=float(found[2]), drift=float(found[3]), shift_velocity=float(moved[0]),
                                shift_inverse_mass=float(moved[1]))
    model = fit.model
    nuisances = Nuisances(lag_e=fit.phi.get("lag_e"), lag_s=fit.phi.get("lag_s"), set_fraction=fit.phi.get("set"),
                          offset=float(fit.theta[2]) if r.fit_b else None,
                          slow_errors=slow_found,
                          model_error=ModelError(extrema=float(np.sqrt(model[EXTREMUM])),
                                                 separations=float(np.sqrt(model[SEPARATION]))))
    noise_var = np.array([float(np.mean(fit.noise_diag[r.group == k])) if np.any(r.group == k) else 1.0
                          for k in range(3)])
    scatter = float(np.max(model / np.maximum(noise_var, 1e-300)))
    used = RowsUsed(onsets=int(r.onsets - dropped), extrema=int(r.extrema),
                    stage_b_extrema=int(np.count_nonzero(eqs.stage_b) * (r.extrema > 0)),
                    separations=int(r.separations), stage_b_samples=int(eqs.stage_b_samples * (r.extrema > 0)))
    return Solution(theta=fit.theta[:2].copy(), cov=cov_out, chi2=chi2, dof=dof, nuisances=nuisances, used=used,
                    gain=gain, tau=r.tau[:rows], scatter=scatter)


def _least_overlap(gap_basis: list[KinematicsAt], theta, cov, g, fit_b) -> tuple[np.ndarray, np.ndarray]:
    """The least overlap in each gap [m] and its standard error from the estimate's covariance ``cov``."""
    full = np.r_[theta[:2], theta[2] if fit_b else 0.0]
    cov3 = np.zeros((3, 3))
    cov3[:cov.shape[0], :cov.shape[1]] = cov
    least, spread = [], []
    for at in gap_basis:
        tau, i_f, da = at.tau, at.force_double, at.displacement
        if tau.size == 0:
            least.append(-np.inf)
            spread.append(0.0)
            continue
        delta = full[0] * tau + (g + full[2]) * tau ** 2 / 2 - full[1] * i_f - da
        k = int(np.argmin(delta))
        grad = np.array([tau[k], -i_f[k], tau[k] ** 2 / 2])
        least.append(float(delta[k]))
        spread.append(float(np.sqrt(max(float(grad @ cov3 @ grad), 0.0))))
    return np.array(least), np.array(spread)
