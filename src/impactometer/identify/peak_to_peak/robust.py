"""Robust peak-to-peak identification: every equation the record holds, one generalised least-squares estimate.

Axis down, t measured from first contact t00. The mass obeys M1·ü1 = M1·g − Fc, the piston's acceleration a2 is
measured, so the relative displacement (overlap) of mass and rod and its rates are

    δ(t) = V0·τ + (g + b)·τ²/2 − w·IF(t) − D2(t),    δ'(t) = V0 + (g + b)·τ − w·JF(t) − V2(t),
    δ''(t) = g + b − w·Fc(t) − a2(t),

τ = t − t00, w = 1/M1, JF/IF the single/double integrals of the force and V2/D2 those of the acceleration from t00
(the piston at rest before contact), b the offset left in the channels after the pre-trigger correction. The
equations, all linear in (V0, w, b):

- onset k (a pulse starts): δ(Tk) = 0 -- whatever the contact law, the force is positive only while the bodies
  overlap (a pulse starts from a fresh contact);
- force extremum k (a peak of a bounce, or a peak or trough of the force in sustained contact, stage B):
  δ'(Ek) + λe·δ''(Ek) = 0 -- the force turns where the overlap turns (exactly for an elastic or hysteretic law,
  with the lag λe = c/k for a viscous one). In stage B consecutive extrema are the exact integral of
  M1·(g − a2) = Fc over the samples between them: the mass and the rod share one acceleration on average over
  every half-cycle of the contact's own oscillation, whatever the law;
- separation k (a pulse ends): δ(Sk) + λs·δ'(Sk) − μ·δ(Pk) = 0 -- the contact lets go ahead of zero overlap by a
  lag (viscous contact, λs = c/k) or at a fraction μ of the pulse's largest overlap δ(Pk) (a set, as a hysteretic
  pad takes one); 0 for a force that vanishes with the overlap.

The nuisances b (with its pre-trigger prior), λe, λs and μ are estimated with (V0, w). The covariance of the
rows is that of the double-integrated white noise of both channels (the kernels of
:func:`.covariance.atom_kernel`), of the times of the onsets, extrema and separations (rate × time error; the
error of t00 acts on every displacement alike), and, for the rows that rest on a model of the contact (extrema,
separations), a model-error variance estimated from their own scatter. It depends on the estimate, so the solution
is iterated (Gauss-Newton).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import NamedTuple

import numpy as np

from .covariance import DIP_SIGMAS, atom_kernel, normal_inverse, slow_covariance, slow_errors

#: Gauss-Newton / reweighting iterations, at most: fewer once the solution changes by less than CONVERGED
#: (relative) from one to the next
ITERATIONS = 10
CONVERGED = 1e-6


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


class KinematicsAt(NamedTuple):
    """Force, piston acceleration and their integrals from first contact t00 at given instants (arrays)."""

    tau: np.ndarray  #: time since first contact t00 [s]
    force: np.ndarray  #: contact force Fc [N]
    force_impulse: np.ndarray  #: JF = ∫Fc dt from t00 [N·s]
    force_double: np.ndarray  #: IF = ∫∫Fc dt² from t00 [N·s²]
    acceleration: np.ndarray  #: piston acceleration a2 [m/s²]
    velocity_change: np.ndarray  #: V2 = ∫a2 dt from t00 [m/s]
    displacement: np.ndarray  #: D2 = ∫∫a2 dt² from t00 [m]


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

    def at(self, index) -> KinematicsAt:
        """τ, Fc, JF, IF, a2, V2, D2 at fractional sample indices ``index``, integrals from t00."""
        index = np.asarray(index, dtype=float)
        tau = (index - self.t00) * self.dt
        f, jf, i_f = integrals_at(self.force, self.cf[0], self.cf[1], self.dt, index)
        a, va, da = integrals_at(self.acceleration, self.ca[0], self.ca[1], self.dt, index)
        jf, i_f = jf - self._f0[1], i_f - self._f0[2] - self._f0[1] * tau
        va, da = va - self._a0[1], da - self._a0[2] - self._a0[1] * tau
        return KinematicsAt(tau, f, jf, i_f, a, va, da)


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
    nuisances: dict
    used: dict
    gain: np.ndarray
    tau: np.ndarray
    #: largest model-error variance of a group over its noise variance [-]
    scatter: float = 0.0
    #: where the gaps read as flights and as a contact that kept a set fit alike: (V0 [m/s], M1 [kg]) of each
    readings: dict | None = None


#: kinds of rows and atoms: onsets, extrema, separations, and the peak overlap of a separation
ONSET, EXTREMUM, SEPARATION, PEAK = 0, 1, 2, 3
#: largest set fraction μ of the separations [-]
SET_MAX = 0.95
#: fewest turning points and separations for their groups to be used: a group must outnumber its own nuisances
#: (the turning points bring the lag λe, the separations the lag λs and the set μ)
MIN_EXTREMA = 2
MIN_SEPARATIONS = 3


def solve_rows(kin: Kinematics, eqs: Equations, *, noise_force: float, noise_acceleration: float,
               pre_samples: int, lag_max: float) -> Solution:
    """Generalised least squares for (V0, w) from the rows of ``eqs`` (module notes and :func:`_solve_rows`).

    Every gap is first taken for a flight. Where stage B has an estimate of its own, the gaps are also judged by
    that estimate first (a pad with a set may never let the mass fly), and of the two answers the one whose
    turning points and separations scatter less beyond their noise is kept -- unless that one needs a contact
    model at the edge of its range (a set or a lag at its bound) and the other, inside its range, scatters less
    than ``BOUNDED_SCATTER`` times as much. Where the flights are kept with onsets the other reading drops, and
    that reading fits as well, the difference of the two readings is added to the covariance: whether those gaps
    were flights is not in the data.
    """
    options: dict = dict(noise_force=noise_force, noise_acceleration=noise_acceleration, pre_samples=pre_samples,
                         lag_max=lag_max)
    flights = _solve_rows(kin, eqs, judge_by_stage_b=False, **options)
    if int(np.count_nonzero(eqs.stage_b)) < STAGE_B_ROWS or not eqs.onsets.size:
        return flights
    judged = _solve_rows(kin, eqs, judge_by_stage_b=True, **options)

    def bounded(sol: Solution) -> bool:
        return any(value >= 0.99 * limit for name, limit in (("set", SET_MAX), ("lag_e", lag_max), ("lag_s", lag_max))
                   if isinstance(value := sol.nuisances.get(name), float))

    # the one that scatters less wins, unless it needs a model at the edge of its range and the other, without
    # one, scatters within its noise or less than BOUNDED_SCATTER times as much
    best, other = (judged, flights) if judged.scatter < flights.scatter else (flights, judged)
    near = other.scatter <= max(1.0, BOUNDED_SCATTER * best.scatter)
    chosen = other if bounded(best) and not bounded(other) and near else best
    if chosen is flights and flights.used["onsets"] > judged.used["onsets"] \
            and judged.scatter <= max(1.0, flights.scatter):
        # the flights keep onsets the judged reading doubts, and the data fit both readings as well: whether those
        # gaps were flights (a pad that kept no set) is not in the data, so their difference is in the answer's σ
        diff = flights.theta - judged.theta
        readings = {k: (float(v.theta[0]), 1.0 / float(v.theta[1])) for k, v in (("flights", flights), ("set", judged))}
        chosen = replace(flights, cov=flights.cov + np.outer(diff, diff), readings=readings)
    return chosen


def _solve_rows(kin: Kinematics, eqs: Equations, *, noise_force: float, noise_acceleration: float,
                pre_samples: int, lag_max: float, judge_by_stage_b: bool) -> Solution:
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
        Largest lag λe, λs [s].

    Notes
    -----
    Each row is a sum of atoms cd·δ(t) + cv·δ'(t) + ca·δ''(t); a separation has two (at Sk and at Pk). Extrema
    and separations rest on models of the contact (the lags, the set): a group is used only when it outnumbers
    its own nuisances, and where it scatters more than its noise explains, a white model-error variance is added
    to it until its chi-square matches its rows, so a poor model weighs less instead of pulling the estimate.
    """
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
    kind = np.r_[group, np.full(n_sep, PEAK)]
    tau, force, jf, i_f, acc, va, da = kin.at(atom_index)
    fit_b = pre_samples > 0
    nonlinear = ["lag_e"] * use_ext + ["lag_s", "set"] * use_sep
    n_lin = 2 + fit_b
    # δ, δ', δ'' of every atom as (design over (V0, w, b), constant)
    basis = {"d": (np.column_stack([tau, -i_f, tau ** 2 / 2.0]), g * tau ** 2 / 2.0 - da),
             "v": (np.column_stack([np.ones_like(tau), -jf, tau]), g * tau - va),
             "a": (np.column_stack([np.zeros_like(tau), -force, np.ones_like(tau)]), g - acc)}
    mixer = np.zeros((rows, atom_index.size))
    mixer[atom_row, np.arange(atom_index.size)] = 1.0
    bounds = {"lag_e": (0.0, lag_max), "lag_s": (0.0, lag_max), "set": (0.0, SET_MAX)}
    phi = {name: 0.0 for name in nonlinear}

    def coefficients():
        cd = np.select([kind == ONSET, kind == SEPARATION, kind == PEAK], [1.0, 1.0, -phi.get("set", 0.0)], 0.0)
        cv = np.select([kind == EXTREMUM, kind == SEPARATION], [1.0, phi.get("lag_s", 0.0)], 0.0)
        ca = np.where(kind == EXTREMUM, phi.get("lag_e", 0.0), 0.0)
        return cd, cv, ca

    def values(theta_lin):  # δ, δ', δ'' of every atom
        full = np.r_[theta_lin[:2], theta_lin[2] if fit_b else 0.0]
        return {key: m @ full + c for key, (m, c) in basis.items()}

    def derivatives(vals):  # d(row)/d(nonlinear parameter) at the current estimate
        cols = {"lag_e": np.where(kind == EXTREMUM, vals["a"], 0.0),
                "lag_s": np.where(kind == SEPARATION, vals["v"], 0.0),
                "set": np.where(kind == PEAK, -vals["d"], 0.0)}
        return np.column_stack([mixer @ cols[name] for name in nonlinear]) if nonlinear else np.zeros((rows, 0))

    # a gap in the force need not be a flight: a pad with a set unloads to zero force and may load again before
    # the bodies part; such an onset is not at zero overlap, and its row is dropped where the estimate shows
    # that the overlap stayed positive throughout the gap
    gap_index = [np.arange(lo, hi, max((hi - lo) // 64, 1), dtype=float) for lo, hi in eqs.gaps[:n_on]]
    gap_basis = [kin.at(i) for i in gap_index]
    # the onsets are first left out where the other rows determine the answer, so that a gap is judged by an
    # estimate its own (perhaps wrong) onset row has not pulled
    # (where stage B gives an estimate of its own: at least STAGE_B_ROWS turning points in sustained contact)
    strong = judge_by_stage_b and use_ext
    dips = np.full(n_on, strong and bool(gap_basis), dtype=bool)
    theta: np.ndarray = np.zeros(n_lin)
    aw: np.ndarray = np.zeros((0, n_lin + len(nonlinear)))
    model = np.zeros(3)  # model-error variance of each group [m², (m/s)² for extrema]
    previous = np.zeros(0)
    for it in range(ITERATIONS):
        cd, cv, ca = coefficients()
        design = mixer @ ((cd[:, None] * basis["d"][0] + cv[:, None] * basis["v"][0]
                           + ca[:, None] * basis["a"][0])[:, :n_lin])
        const = mixer @ (cd * basis["d"][1] + cv * basis["v"][1] + ca * basis["a"][1])
        if it == 0:
            theta = np.linalg.lstsq(design, -const, rcond=None)[0]
        vals = values(theta)
        if it in (2, 4) and gap_basis:
            # first judged by the estimate without the onsets: sure flights and sure dips; the unsure ones are
            # left out until the estimate from the other rows, sure flights included, settles them by sign
            least, spread = _least_overlap(gap_basis, theta, normal_inverse(aw)[:n_lin, :n_lin], g, fit_b)
            # without a stage-B estimate of its own the estimate leans on the onsets: only a sure dip loses its row
            threshold = (-DIP_SIGMAS * spread if it == 2 else 0.0) if strong else DIP_SIGMAS * spread
            dips = least > threshold
        v0, w = theta[0], max(theta[1], 0.0)
        white = noise_acceleration ** 2 + (w * noise_force) ** 2
        rate = cd * vals["v"] + cv * vals["a"]  # d(atom)/dt, the third derivative left out
        cov = white * (mixer @ atom_kernel(tau, cd, cv, dt) @ mixer.T)
        cov += np.diag(mixer @ ((rate * atom_std) ** 2 + ca ** 2 * white))
        shift = mixer @ (cd * v0 * kin.onset_std0 * dt)  # t00's error moves every overlap alike
        cov += np.outer(shift, shift)
        noise_diag = np.diag(cov).copy()  # each row's variance from the noise alone, before the model error
        cov += np.diag(model[group] + 1e-30 + 1e-18 * float(np.mean(np.diag(cov))))
        cov[np.flatnonzero(dips), np.flatnonzero(dips)] += 1e12 * float(np.max(np.diag(cov)))
        jac_nl = derivatives(vals)
        jac = np.column_stack([design, jac_nl])
        target = -const + jac_nl @ np.array([phi[name] for name in nonlinear])  # Gauss-Newton about φ
        chol = np.linalg.cholesky(cov)
        aw = np.linalg.solve(chol, jac)
        yw = np.linalg.solve(chol, target)
        if fit_b:  # the pre-trigger's residual offset: a prior row b = 0 ± its standard error
            prior = np.zeros(jac.shape[1])
            prior[2] = 1.0 / np.sqrt(white / pre_samples)
            aw = np.vstack([aw, prior])
            yw = np.append(yw, 0.0)
        sol = np.linalg.lstsq(aw, yw, rcond=None)[0]
        if it > 4 and np.allclose(sol, previous, rtol=CONVERGED, atol=0.0):
            break  # settled (the gaps were judged at iterations 2 and 4): another pass would repeat it
        previous = sol
        theta = sol[:n_lin]
        for k, name in enumerate(nonlinear):
            phi[name] = float(np.clip(sol[n_lin + k], *bounds[name]))
        # whitened residuals of a later group are its innovations given the earlier rows: its own chi-square
        resid = (yw - aw @ sol)[:rows]
        for k in (EXTREMUM, SEPARATION):
            inside = group == k
            if inside.any():
                excess = float(np.sum(resid[inside] ** 2)) / int(inside.sum())
                noise_part = float(np.mean(noise_diag[inside]))
                model[k] = max((model[k] + noise_part) * excess - noise_part, 0.0)
    resid = yw - aw @ sol
    chi2 = float(resid @ resid)
    dof = int(rows - np.count_nonzero(dips) - (aw.shape[1] - fit_b))
    bread = normal_inverse(aw)
    gain = (bread @ aw.T)[:2, :rows] @ np.linalg.inv(chol)
    nuisances: dict = dict(phi)
    if fit_b:
        nuisances["offset_m_s2"] = float(theta[2])
    # slow errors of the channels (a drift; an offset where no pre-trigger measures one) are no white noise: the
    # answer with them estimated differs from this one by what they may have done, and the difference joins the
    # covariance, as the readings of the gaps do in solve_rows
    room = rows - int(np.count_nonzero(dips)) - aw.shape[1] - 1
    slow = slow_errors(kin.t00, kin.dt, pre_samples, tau, (cd, cv, ca), mixer, chol, aw[:rows], yw[:rows], white,
                        room=room) if fit_b or room >= 1 else None
    cov_out = bread[:2, :2]
    if slow is not None:
        found, cov_slow = slow
        moved = sol[:2] - found[:2]
        cov_out = slow_covariance(cov_out, cov_slow, moved, bounded=pre_samples > 0)
        nuisances["slow_errors"] = {"offset_m_s2": float(found[2]), "drift_m_s3": float(found[3]),
                                    "shift_v0_m_s": float(moved[0]), "shift_w_1_kg": float(moved[1])}
    nuisances["model_error"] = {"extrema_m_s": float(np.sqrt(model[EXTREMUM])),
                                "separations_m": float(np.sqrt(model[SEPARATION]))}
    noise_var = np.array([float(np.mean(noise_diag[group == k])) if np.any(group == k) else 1.0 for k in range(3)])
    scatter = float(np.max(model / np.maximum(noise_var, 1e-300)))
    used = {"onsets": int(n_on - np.count_nonzero(dips)), "extrema": int(n_ext),
            "stage_b_extrema": int(np.count_nonzero(eqs.stage_b) * use_ext),
            "separations": int(n_sep), "stage_b_samples": int(eqs.stage_b_samples * use_ext)}
    return Solution(theta=theta[:2].copy(), cov=cov_out, chi2=chi2, dof=dof, nuisances=nuisances, used=used,
                    gain=gain, tau=tau[:rows], scatter=scatter)


#: a model at the edge of its range (a set or a lag at its bound) is taken only where the other reading of the gaps
#: scatters this many times more beyond its noise (model-error variance over noise variance) [-]
BOUNDED_SCATTER = 4.0
#: turning points in stage B from which its own estimate judges the gaps before the onsets are used [-]: two
#: consecutive ones bound one window of M1·∫(g − a2) dt = ∫Fc dt, the least that gives stage B a mass of its own
STAGE_B_ROWS = 2


def _least_overlap(gap_basis, theta, cov, g, fit_b) -> tuple[np.ndarray, np.ndarray]:
    """The least overlap in each gap [m] and its standard error from the estimate's covariance ``cov``."""
    full = np.r_[theta[:2], theta[2] if fit_b else 0.0]
    cov3 = np.zeros((3, 3))
    cov3[:cov.shape[0], :cov.shape[1]] = cov
    least, spread = [], []
    for tau, _, _, i_f, _, _, da in gap_basis:
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
