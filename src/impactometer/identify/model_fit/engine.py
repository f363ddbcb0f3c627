"""The fitting engine of every model fit of the project (the batch fit, the stream's first window and updates, the
calibration and the validation): a record as the fit reads it (:class:`Observed`), the weighted residual problem
of a layout on it (:class:`Residuals`), one Levenberg-Marquardt solver (:func:`solve`: one damping step,
:func:`_damped_step`, and one stopping rule, :func:`_stops`) and one answer (:class:`LawFit`).

::

    Layout (named unknowns)  ->  Residuals (data − offset − model)/σ, Jacobian  ->  solve  ->  Solution  ->  LawFit

The solver's loop is :func:`_advance`, which asks its caller for residuals and Jacobians one request at a time:
:func:`solve` answers it in Python for any :class:`Problem`, the stream's compiled fits (:mod:`.first_window`)
with compiled residuals.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field, replace
from typing import Any, Protocol

import numpy as np
from numba import njit

from ...errors import IdentificationError, shown
from ...recording import VALVE_OPENING, Recording
from ...rig import CONTACT_LAWS, contact_law_name
from ...signals.noise import quiet_noise_std, robust_noise_std
from .forward import CONTACT_EARLY, Grid, Layout, _contact_refusal, _make_grid, _predict
from .information import covariance

#: finite-difference step of the Jacobian in the fit variables (ln of a positive value, value/scale of a linear
#: one) and in sample periods for the contact instant. Smaller steps let the integrator's error (its step sequence
#: changes with the parameters, and the contact opens and closes between steps) into the differences: at 1e-6 the
#: Fisher information of M1 came out 8-25 times too large on two pad records (σ(M1) 0.18 % instead of 0.53 %);
#: from 1e-4 to 1e-3 it agrees within 4 %
STEP = 3e-4
CONTACT_TIME_STEP = 1e-2
#: most residual evaluations of one fit (a pad record converges in 11-18)
MAX_EVALUATIONS = 40
#: relative reduction of χ² (predicted by the linearised model, or achieved) at which a fit has converged
#: (MINPACK's ftol): 1e-6 of χ² is ~0.01 on a record of 7000 residuals, nothing beside its scatter of ±120
TOLERANCE = 1e-6
#: Marquardt damping of the first step (relative to the diagonal of JᵀJ), its floor, and the damping at which a fit
#: that finds no lower χ² stops (at the minimum to the precision of the model); :func:`_adapt` moves it in between
FIRST_DAMPING, LEAST_DAMPING, MOST_DAMPING = 1e-3, 1e-12, 1e8

#: fewest samples before first contact (the noise σ of each channel comes from them)
MIN_PRE_SAMPLES = 64
#: samples next to first contact left out of the noise estimate (the filter's foot of the first rise)
GUARD_SAMPLES = 16
#: shortest record after first contact the fit accepts [s] (the first pulses of a pad record last ~5 ms)
MIN_DURATION = 0.01
#: noise σ assumed for a channel without noise (a simulated record), as a fraction of its peak [-]
NOISE_FLOOR = 1e-6
CHANNELS = ("contact_force", "piston_acceleration")
#: samples before the fit's first contact kept in the predicted part of the record (the rest before it, where every
#: trial point's model is zero, enters through its sums only): a trial contact instant earlier than this is
#: refused, as a point outside the ranges is
LEAD_SAMPLES = 64


@njit(cache=True, error_model="numpy")
def normal_equations(jac, r):
    """The normal equations JᵀJ, Jᵀr of residuals ``r`` with Jacobian ``jac``: all the solver reads of a Jacobian
    (formed once per Jacobian; a rejected step only solves them again with another damping)."""
    return jac.T @ jac, jac.T @ r


@njit(cache=True, error_model="numpy")
def _damped_step(normal, gradient, damping):
    """The Levenberg-Marquardt step −(JᵀJ + λ·diag JᵀJ)⁻¹Jᵀr of the normal equations ``normal`` = JᵀJ and
    ``gradient`` = Jᵀr with damping λ, solved in column-scaled variables (a Cholesky factor; least squares where
    the damped matrix is not positive definite), and the reduction of χ² the linearised model predicts for it (the
    one damping step of every fit)."""
    scale = np.sqrt(np.diag(normal))
    for k in range(scale.size):
        if scale[k] == 0.0:
            scale[k] = 1.0
    scaled = normal / np.outer(scale, scale)
    g = gradient / scale
    lifted = scaled + damping * np.diag(np.diag(scaled))
    try:
        factor = np.linalg.cholesky(lifted)
        step = -np.linalg.solve(factor.T, np.linalg.solve(factor, g))
    except Exception:  # noqa: BLE001 - numba raises LinAlgError as Exception
        step = -np.linalg.lstsq(lifted, g)[0]
    return step / scale, -(2.0 * (step @ g) + step @ (scaled @ step))


@njit(cache=True, error_model="numpy")
def _adapt(damping, growth, gain):
    """The damping and its growth factor after a step of ``gain`` = achieved / predicted reduction of χ² (Nielsen's
    rule, H. B. Nielsen, IMM-REP-1999-05): a step that lowers χ² (gain > 0) lowers the damping by up to a factor 3
    as the linearised model predicted it well; one that does not raises it by ``growth``, which doubles with each
    failure in a row (a few failures reach any damping)."""
    if gain > 0.0:
        return max(damping * max(1.0 / 3.0, 1.0 - (2.0 * gain - 1.0) ** 3), LEAST_DAMPING), 2.0
    return damping * growth, 2.0 * growth


@njit(cache=True, error_model="numpy")
def _stops(chi2, lower, damping, tolerance):
    """The stopping rule of every fit: χ² falls (predicted by the linearised model or achieved: ``lower``) by no
    more than ``tolerance`` of it, or no damping up to :data:`MOST_DAMPING` finds a lower χ²."""
    return 0.0 <= chi2 - lower <= tolerance * chi2 or damping > MOST_DAMPING


#: what the solver asks of its caller next (:func:`_advance`): nothing (the fit is done), the χ² at the trial point,
#: to take the trial point and stop, to take it and make the Jacobian there
DONE, TRIAL, ACCEPT, ACCEPT_JACOBIAN = 0, 1, 2, 3
#: the solver's memory (:func:`begin`): χ², damping, its growth factor, χ² the last step predicted, residual
#: evaluations, Jacobians made, converged
_CHI2, _DAMPING, _GROWTH, _LOWER, _COUNT, _MADE, _CONVERGED = range(7)
#: the ``new`` of :func:`_advance` after a Jacobian (a χ² is never negative)
NO_TRIAL = -1.0


@njit(cache=True, error_model="numpy")
def _begin(chi2):
    """The solver's memory at the start point of χ² ``chi2`` (its residuals and Jacobian made)."""
    return np.array([chi2, FIRST_DAMPING, 2.0, chi2, 1.0, 1.0, 0.0])


@njit(cache=True, error_model="numpy")
def _advance(memo, x, trial, normal, gradient, new, evaluations, jacobians, information, tolerance):
    """The Levenberg-Marquardt loop of every fit, one request at a time (reverse communication): after the
    Jacobian at ``x`` (its normal equations ``normal``, ``gradient``; ``new`` :data:`NO_TRIAL`) or the χ² ``new``
    of the last trial point (inf or NaN where the model cannot be evaluated there), returns what the caller does
    next (:data:`TRIAL`: evaluate at ``trial``; :data:`ACCEPT`, :data:`ACCEPT_JACOBIAN`: ``x`` moved to the trial
    point, keep its residuals, and make the Jacobian there; :data:`DONE`). ``memo`` (:func:`begin`) holds the rest.

    Damped steps (:func:`_damped_step`), the damping lowered after a step that lowers χ² and raised after one that
    does not (:func:`_adapt`), until :func:`_stops` (converged), ``evaluations`` residual evaluations are spent, or
    ``jacobians`` Jacobians are made (> 0; an update of a fit whose window grew a little: one Jacobian and one or
    a few residual evaluations). With ``information`` the Jacobian of a converged answer is made at it.
    """
    if new != NO_TRIAL:
        if not new < np.inf:  # NaN: not evaluated
            new = np.inf
        chi2 = memo[_CHI2]
        memo[_COUNT] += 1.0
        memo[_DAMPING], memo[_GROWTH] = _adapt(memo[_DAMPING], memo[_GROWTH], (chi2 - new) / max(chi2 - memo[_LOWER],
                                                                                              1e-300))
        converged = _stops(chi2, new, memo[_DAMPING], tolerance)
        if new < chi2:
            x[:] = trial
            memo[_CHI2], memo[_CONVERGED] = new, converged
            if (jacobians > 0 and memo[_MADE] >= jacobians) or (converged and not information):
                return ACCEPT
            memo[_MADE] += 1.0
            return ACCEPT_JACOBIAN
        if converged:  # no damping lowers χ²: at the minimum to the model precision
            memo[_CONVERGED] = 1.0
            return DONE
    elif memo[_CONVERGED]:  # the Jacobian of the answer made
        return DONE
    if memo[_COUNT] >= evaluations:
        return DONE
    step, reduction = _damped_step(normal, gradient, memo[_DAMPING])
    memo[_LOWER] = memo[_CHI2] - reduction
    if _stops(memo[_CHI2], memo[_LOWER], memo[_DAMPING], tolerance):
        memo[_CONVERGED] = 1.0
        return DONE
    trial[:] = x + step
    return TRIAL


@njit(cache=True, error_model="numpy")
def _outcome(memo):
    """χ², residual evaluations and whether it converged, of the solver's memory ``memo``."""
    return memo[_CHI2], int(memo[_COUNT]), memo[_CONVERGED] > 0.0


class Problem(Protocol):
    """A weighted least-squares problem: ``residuals(x)`` (None where the model cannot be evaluated at ``x``),
    ``jacobian(x)`` and the normal equations ``normal(jacobian, r)`` (JᵀJ, Jᵀr) the solver reads of it."""

    def residuals(self, x: np.ndarray) -> np.ndarray | None: ...

    def jacobian(self, x: np.ndarray): ...

    def normal(self, jacobian, r: np.ndarray) -> tuple[np.ndarray, np.ndarray]: ...


@dataclass(frozen=True)
class Solution:
    """What :func:`solve` found: the variables ``x``, the residuals there and their sum of squares ``chi2``, the
    last Jacobian made (at ``x`` unless the Jacobians ran out; in the problem's form: an array, or the
    calibration's blocks), the residual evaluations and whether the stopping rule ended the fit."""

    x: np.ndarray
    residuals: np.ndarray
    chi2: float
    jacobian: Any
    evaluations: int
    converged: bool


def solve(problem: Problem, x: np.ndarray, *, evaluations: int = MAX_EVALUATIONS, tolerance: float = TOLERANCE,
          jacobians: int | None = None, information: bool = True, known: tuple[np.ndarray | None, Any] | None = None
          ) -> Solution:
    """Levenberg-Marquardt on ``problem`` from ``x`` (:func:`_advance`, which see for ``evaluations``,
    ``jacobians`` and ``information``; without ``information`` the Jacobian is the last one made, where the fit
    stops). ``known``: the residuals and the Jacobian at ``x`` where the caller has them (:func:`_restricted`).

    Raises
    ------
    IdentificationError
        When the problem cannot be evaluated at ``x``.
    """
    x = np.array(x, dtype=float)
    r, jac = (problem.residuals(x), None) if known is None else known
    if r is None:
        raise IdentificationError("the model cannot be integrated at the fit's start")
    r_trial: np.ndarray | None = r
    memo, trial, new = _begin(float(r @ r)), np.empty_like(x), NO_TRIAL
    jac = problem.jacobian(x) if jac is None else jac
    normal, gradient = problem.normal(jac, r)
    while (request := _advance(memo, x, trial, normal, gradient, new, evaluations, jacobians or 0, information,
                              tolerance)) != DONE:
        if request == TRIAL:
            r_trial = problem.residuals(trial)
            new = np.inf if r_trial is None else float(r_trial @ r_trial)
            continue
        assert r_trial is not None  # the trial point taken lowered χ²
        r, new = r_trial, NO_TRIAL
        if request == ACCEPT:
            break
        jac = problem.jacobian(x)
        normal, gradient = problem.normal(jac, r)
    chi2, count, converged = _outcome(memo)
    return Solution(x=x, residuals=r, chi2=float(chi2), jacobian=jac, evaluations=count, converged=bool(converged))


@dataclass(frozen=True)
class Observed:
    """What the fit reads of a recording: both channels (2, n) [N], [m/s²], their noise σ (2,) from the
    pre-trigger, the grid and sensor model of the samples, and the start values of the offsets (2,)."""

    channels: np.ndarray
    noise: np.ndarray
    grid: Grid
    offsets: np.ndarray

    @property
    def size(self) -> int:
        """Number of residuals (both channels)."""
        return int(self.channels.size)


def window(data: Observed, end: float) -> Observed:
    """``data`` up to the instant ``end`` [s] on the recording's clock (all of it when ``end`` is past its end;
    ``data`` itself at +inf: :attr:`LawFit.end` of a fit of the whole record)."""
    if end == math.inf:
        return data
    n = min(data.channels.shape[1], int(math.floor((end - data.grid.start_time) * data.grid.sample_rate)) + 1)
    return replace(data, channels=data.channels[:, :n], grid=replace(data.grid, size=n))


@njit(cache=True, error_model="numpy")
def _weighted(tail, model, x, q, root, mean, prior_index, prior_mean, prior_sigma, r):
    """``r`` := the rows of :class:`Residuals` at ``x`` of the model over σ ``model`` (2, n): ``tail`` − offset −
    model, the head's two rows ``root``·(``mean`` − offset), one row per prior; returns ``r``."""
    n = tail.shape[1]
    for c in range(2):
        r[c * n:(c + 1) * n] = tail[c] - x[q + c] - model[c]
        r[2 * n + c] = root * (mean[c] - x[q + c])
    for k in range(prior_index.size):
        r[2 * n + 2 + k] = (x[prior_index[k]] - prior_mean[k]) / prior_sigma[k]
    return r


@njit(cache=True, error_model="numpy")
def _differenced(model, moved, steps, root, prior_index, prior_sigma, jac):
    """``jac`` := the Jacobian of :func:`_weighted`'s rows from the model over σ ``model`` (2, n) and ``moved`` (q,
    2, n), the model with each variable j moved by ``steps[j]`` (finite differences; exact for the offsets)."""
    q, n = steps.size, model.shape[1]
    jac[:] = 0.0
    for j in range(q):
        for c in range(2):
            jac[c * n:(c + 1) * n, j] = (model[c] - moved[j, c]) / steps[j]
    jac[:n, q] = jac[n:2 * n, q + 1] = -1.0
    jac[2 * n, q] = jac[2 * n + 1, q + 1] = -root
    for k in range(prior_index.size):
        jac[2 * n + 2 + k, prior_index[k]] = 1.0 / prior_sigma[k]
    return jac


class Residuals:
    """The weighted residuals (data − offset − model)/σ of ``layout`` on ``data`` as functions of the variables
    ``x`` (the layout's, then the two offsets in units of each channel's σ), and their Jacobian (forward
    differences of the layout's variables, :data:`STEP`, backward ones where a forward step leaves the range the
    model is integrated in; exact for the offsets). The prediction at the last point is kept. ``in_turn``
    predicts on the calling thread (:func:`.forward.predict`).

    The samples more than :data:`LEAD_SAMPLES` before the layout's first contact (``head``) hold offset and noise
    only under a causal sensor model: their residuals about each channel's mean m over them give χ² a constant,
    and the two rows sqrt(head)·(m − offset) stand for the rest. So χ² = |r|² + ``constant`` and JᵀJ are those of
    every sample, while the model is predicted on the samples after the head only (a first window holds ~1000
    pre-trigger samples for ~200 after contact). Each prior of the layout adds one row last.
    """

    def __init__(self, data: Observed, layout: Layout, *, in_turn: bool = False):
        self.data, self.layout, self.q, self.noise, self.in_turn = data, layout, len(layout.names), data.noise, in_turn
        grid, scaled = data.grid, data.channels / data.noise[:, None]
        onset = int(np.floor((layout.origin - grid.start_time) * grid.sample_rate))
        head = max(onset - LEAD_SAMPLES, 0) if grid.design in ("causal", "none") else 0
        self.head = head
        self.earliest = grid.start_time + (head + 1) / grid.sample_rate  # a contact before it reaches the head
        self.grid = replace(grid, start_time=grid.start_time + head / grid.sample_rate, size=grid.size - head)
        self.tail = scaled[:, head:]
        self.mean = scaled[:, :head].mean(axis=1) if head else np.zeros(2)
        self.constant = float(np.sum(np.square(scaled[:, :head] - self.mean[:, None])))
        self.root = np.sqrt(head)
        self.steps = np.array([CONTACT_TIME_STEP if name == "contact_time" else STEP for name in layout.names])
        self.prior_index = np.array([j for j, _, _ in layout.priors], dtype=np.int64)
        self.prior_mean = np.array([mean for _, mean, _ in layout.priors])
        self.prior_sigma = np.array([sigma for _, _, sigma in layout.priors])
        self._last: tuple[bytes, np.ndarray] | None = None

    @property
    def size(self) -> int:
        """Number of residuals χ² holds: every sample of both channels and one per prior."""
        return self.data.size + self.prior_index.size

    def sample_chi2(self, r: np.ndarray) -> float:
        """The samples' share of χ² of residuals ``r`` (the priors' rows left out)."""
        samples = r[:r.size - self.prior_index.size]
        return float(samples @ samples) + self.constant

    def _predicted(self, rows: np.ndarray) -> np.ndarray:
        params, times = self.layout.packed(rows)
        if any(_contact_refusal(time, self.earliest) == CONTACT_EARLY for time in times):  # the not finite: _predict
            raise IdentificationError("the model is not predicted at a contact instant before the part of the "
                                      "record it is predicted on")
        return _predict(self.grid, params, times, in_turn=self.in_turn) / self.noise[None, :, None]

    def model(self, x: np.ndarray) -> np.ndarray:
        """Predicted channels over σ (2, n) at ``x`` (offsets excluded), on the samples after the head."""
        key = x[:self.q].tobytes()
        if self._last is None or self._last[0] != key:
            self._last = (key, self._predicted(x[None, :self.q])[0])
        return self._last[1]

    def predicted(self, x: np.ndarray) -> np.ndarray:
        """The recorded channels (2, every sample) [N], [m/s²] the model predicts at ``x``, offsets included."""
        out = np.zeros(self.data.channels.shape)
        out[:, self.head:] = self.model(x) * self.noise[:, None]
        return out + (x[self.q:] * self.noise)[:, None]

    def residuals(self, x: np.ndarray) -> np.ndarray | None:
        """The residuals at ``x`` (those after the head, then the head's two rows); None where the model cannot be
        integrated there."""
        try:
            model = self.model(x)
        except IdentificationError:
            return None
        return _weighted(self.tail, model, x, self.q, self.root, self.mean, self.prior_index, self.prior_mean,
                         self.prior_sigma, np.empty(self.tail.size + 2 + self.prior_index.size))

    def normal(self, jac: np.ndarray, r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The normal equations of Jacobian ``jac`` and residuals ``r`` (:func:`normal_equations`)."""
        return normal_equations(jac, r)

    def jacobian(self, x: np.ndarray) -> np.ndarray:
        """∂residuals/∂x (rows of :meth:`residuals`, q + 2)."""
        base = self.model(x)
        try:
            steps = self.steps
            moved = self._predicted(x[None, :self.q] + np.diag(steps))
        except IdentificationError:
            steps = -self.steps
            moved = self._predicted(x[None, :self.q] + np.diag(steps))
        return _differenced(base, moved, steps, self.root, self.prior_index, self.prior_sigma,
                            np.empty((self.tail.size + 2 + self.prior_index.size, self.q + 2)))


class Quality:
    """The χ² figures of a weighted least-squares fit with ``chi2``, ``residuals`` (their number) and
    ``unknowns``."""

    chi2: float
    residuals: int

    @property
    def unknowns(self) -> int:  # pragma: no cover - every fit defines it
        raise NotImplementedError

    @property
    def dof(self) -> int:
        """Degrees of freedom of χ²."""
        return self.residuals - self.unknowns

    @property
    def reduced_chi2(self) -> float:
        """χ² per degree of freedom [-] (1 when the model explains the data down to their noise)."""
        return self.chi2 / max(self.dof, 1)

    @property
    def bic(self) -> float:
        """Bayesian information criterion χ² + k·ln(N) (−2·log-likelihood up to a constant shared by every law)."""
        return self.chi2 + self.unknowns * math.log(self.residuals)


@dataclass(frozen=True)
class LawFit(Quality):
    """The fit of one contact law.

    ``x`` holds the layout's variables then the offsets in units of each channel's σ; ``cov`` is the inverse
    Fisher information of all of them (unscaled by χ²); ``values`` the physical values [SI] of the layout's
    unknowns and ``offsets`` the sensor offsets [N], [m/s²].
    """

    layout: Layout
    x: np.ndarray
    values: dict
    offsets: np.ndarray
    cov: np.ndarray
    rank: int
    chi2: float
    residuals: int
    evaluations: int
    converged: bool
    #: the span of the record after first contact the fit read [s] and why it ends there (the whole window
    #: given, or the :func:`~.forward.horizon` of the whole record)
    span: tuple[float, str] | None = None
    #: the weighted residuals and their Jacobian at ``x`` (rows of :class:`Residuals`) where the fit made them
    #: there (:func:`fit_law` with ``information``), for the tests of the answer (:func:`_restricted`)
    residual: np.ndarray | None = field(default=None, repr=False)
    jacobian: np.ndarray | None = field(default=None, repr=False)

    @property
    def law(self) -> str:
        """The contact law."""
        return self.layout.law

    @property
    def end(self) -> float:
        """The instant [s] up to which the fit read its record (its span's end), +inf for the whole record."""
        return math.inf if self.span is None else self.values["contact_time"] + self.span[0]

    @property
    def unknowns(self) -> int:
        """Number of fitted unknowns (the layout's and the two offsets)."""
        return self.x.size

    def std(self, name: str) -> float:
        """Standard error [SI] of a fitted unknown from the Fisher information (not scaled by χ²)."""
        j = self.layout.names.index(name)
        return abs(self.layout.derivative(name, float(self.x[j]))) * math.sqrt(self.cov[j, j])

    def summary(self) -> dict:
        """JSON-ready figures of the fit: χ², degrees of freedom, BIC and each unknown with its standard error."""
        return {"chi2": self.chi2, "dof": self.dof, "reduced_chi2": self.reduced_chi2, "bic": self.bic,
                "evaluations": self.evaluations, "converged": self.converged, "rank": self.rank,
                "unknowns": self.unknowns,
                **({} if self.span is None else {"fit_span_s": self.span[0], "fit_span": self.span[1]}),
                "values": {name: self.values[name] for name in self.layout.names},
                "std": {name: self.std(name) for name in self.layout.names},
                "offsets": {"contact_force_N": float(self.offsets[0]),
                            "piston_acceleration_m_s2": float(self.offsets[1])}}


def _least_bic(fits: Iterable[LawFit]) -> LawFit | None:
    """The fit of smallest BIC of ``fits`` (the first of equals; None where there is none)."""
    return min(fits, key=lambda fit: fit.bic, default=None)


def _law_fit(problem: Residuals, solution: Solution, *, information: bool = True,
            converged: bool | None = None, kept: bool = False) -> LawFit:
    """The :class:`LawFit` of ``solution`` on ``problem`` (its covariance from the solution's Jacobian with
    ``information``, else NaN; ``converged`` overrides the solution's; ``kept``: the solution's residuals and
    Jacobian, made at its answer, kept in it)."""
    x, layout = solution.x, problem.layout
    cov, rank = covariance(solution.jacobian) if information else (np.full((x.size, x.size), np.nan), 0)
    return LawFit(layout=layout, x=x, values=layout.values(x[:problem.q]), offsets=x[problem.q:] * problem.noise,
                  cov=cov, rank=rank, chi2=solution.chi2 + problem.constant, residuals=problem.size,
                  evaluations=solution.evaluations,
                  converged=solution.converged if converged is None else converged,
                  residual=solution.residuals if kept else None, jacobian=solution.jacobian if kept else None)


def _variables(layout: Layout, values: dict[str, float], offsets: np.ndarray, noise: np.ndarray) -> np.ndarray:
    """The fit vector of physical ``values`` (name -> value [SI]) and ``offsets`` [N], [m/s²]."""
    return np.concatenate((layout.variables(values), offsets / noise))


def fit_law(data: Observed, layout: Layout, start: dict[str, float], *, offsets: np.ndarray | None = None,
            evaluations: int = MAX_EVALUATIONS, information: bool = True, jacobians: int | None = None,
            in_turn: bool = False) -> LawFit:
    """Weighted least-squares fit of ``layout`` to ``data`` from ``start`` (physical values of its unknowns) and
    ``offsets`` [N], [m/s²] (default ``data.offsets``) by :func:`solve`; with ``information`` the covariance from
    the Jacobian at the optimum (else NaN: a window whose answer only starts the next). ``jacobians``: an update
    (see :func:`solve`; it claims convergence, with the covariance from the Jacobian its last step started from).

    Raises
    ------
    IdentificationError
        When the model cannot be integrated at the start.
    """
    problem = Residuals(data, layout, in_turn=in_turn)
    x0 = _variables(layout, start, data.offsets if offsets is None else offsets, data.noise)
    try:
        solution = solve(problem, x0, evaluations=evaluations, jacobians=jacobians,
                         information=information and jacobians is None)
    except IdentificationError as exc:
        raise IdentificationError(f"the {layout.law} fit failed: {exc}") from None
    if jacobians is not None:
        return _law_fit(problem, solution, converged=True)
    return _law_fit(problem, solution, information=information, kept=information)


def _restricted(fit: LawFit, problem: Residuals) -> tuple[np.ndarray, np.ndarray] | None:
    """The residuals and the Jacobian of ``problem`` at ``fit``'s answer, read off those ``fit`` kept: ``problem``
    is ``fit``'s layout on the record it was fitted to, up to an instant no later than the fit's (its rows are the
    fit's rows of the samples up to there: under a causal anti-alias filter, or none, the model of a sample does not
    depend on later ones). None where the fit kept none or the filter is zero-phase (then they are computed)."""
    if fit.residual is None or fit.jacobian is None or problem.layout is not fit.layout or (
            problem.grid.design not in ("causal", "none")):
        return None
    whole = (fit.residual.size - 2 - problem.prior_index.size) // 2
    n = problem.tail.shape[1]
    if n > whole:
        return None
    rows = np.r_[np.arange(n), whole + np.arange(n), 2 * whole + np.arange(fit.residual.size - 2 * whole)]
    return fit.residual[rows], fit.jacobian[rows]


def weighted_jacobian(data: Observed, layout: Layout, values: dict[str, float]) -> np.ndarray:
    """The weighted Jacobian of ``layout`` on ``data`` at physical ``values`` (offsets zero: they enter linearly,
    so the Jacobian does not depend on them); its JᵀJ is the Fisher information of every sample."""
    return Residuals(data, layout).jacobian(_variables(layout, values, np.zeros(2), np.ones(2)))


def contact_laws(contact: str | None) -> tuple[str, ...]:
    """The contact laws fitted: every law the project has for ``"auto"``/None, else the one named."""
    if contact is None or contact == "auto":
        return tuple(CONTACT_LAWS)
    return (contact_law_name(contact),)


def anti_alias_design(recording: Recording) -> str:
    """The anti-alias design the recording's channels went through (metadata ``anti_alias``; none stated: plain
    sampling)."""
    design = recording.metadata.get("anti_alias", "none")
    if design not in ("causal", "zero-phase", "none"):
        raise IdentificationError(f"{recording.source}: metadata anti_alias = {shown(design)} names a filter the "
                                  "model cannot reproduce; expected 'causal', 'zero-phase' or 'none'")
    if isinstance(recording.metadata.get("cfc"), dict):
        raise IdentificationError(f"{recording.source}: CFC-filtered channels; the model fit predicts the channels "
                                  "through the recording's anti-alias filter only -- identify the unfiltered record")
    return design


def observe(recording: Recording, design: str, contact_time: float, min_duration: float = MIN_DURATION,
            quiet: dict | None = None) -> Observed:
    """The record as the fit reads it, with each channel's noise σ from the samples before ``contact_time``, and
    at least ``min_duration`` [s] after it. A record with a :data:`VALVE_OPENING` channel (valve Z's opening [-]
    at each sample, as the valve's command and drive give it) is predicted with that opening (the fit knows the
    valve); without it, or with it zero throughout, with the valve closed. ``quiet``: where given, the
    :func:`_pre_trigger` figures are read from it, or kept in it when it is empty (a stream's updates of one impact
    read the same pre-trigger)."""
    data = np.vstack([np.asarray(recording.channel(name), dtype=float) for name in CHANNELS])
    fs = recording.sample_rate
    onset = int(math.floor((contact_time - recording.start_time) * fs))
    _check_after(recording, (data.shape[1] - 1 - onset) / fs, min_duration)
    pre = onset - GUARD_SAMPLES
    if pre < MIN_PRE_SAMPLES:
        raise IdentificationError(f"{recording.source}: {max(pre, 0)} samples before first contact; the model fit "
                                  f"needs at least {MIN_PRE_SAMPLES + GUARD_SAMPLES} (the noise of each channel is "
                                  "measured there) -- record with a pre-trigger")
    figures = None if quiet is None else quiet.get("pre_trigger")
    if figures is None:
        figures = _pre_trigger(data[:, :pre])
        if quiet is not None:
            quiet["pre_trigger"] = figures
    noise, level = figures
    floor = NOISE_FLOOR * np.max(np.abs(data - level[:, None]), axis=1)
    noise = np.maximum(noise, np.maximum(floor, 1e-300))
    opening = recording.channels.get(VALVE_OPENING)  # the valve command's opening, where the record holds it
    grid = _make_grid(recording.start_time, fs, data.shape[1], design, opening=opening)
    return Observed(channels=data, noise=noise, grid=grid, offsets=level)


def _pre_trigger(samples: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each channel's noise σ and median of the pre-trigger ``samples`` (2, n) [N], [m/s²]."""
    # the model of the pre-trigger is an offset plus white noise: the sample standard deviation is its most
    # efficient σ (the median second difference of robust_noise_std scatters 2-3 times more: 10 % off on a record
    # of 1000 pre-trigger samples)
    return quiet_noise_std(samples, axis=1, ddof=1), np.median(samples, axis=1)


def check_length(recording: Recording, min_duration: float = MIN_DURATION) -> float:
    """IdentificationError for a record without the pre-trigger or the length after first contact the fit needs;
    else the crude instant of first contact [s].

    The first ``MIN_PRE_SAMPLES`` + ``GUARD_SAMPLES`` samples of the force must be quiet (within 8 σ of their
    median, σ by :func:`~impactometer.signals.noise.robust_noise_std`), and first contact, the first sample 10 σ
    off, must leave ``min_duration`` [s] of record.
    """
    force = np.asarray(recording.channel("contact_force"), dtype=float)
    need = MIN_PRE_SAMPLES + GUARD_SAMPLES
    head = force[:need]
    level = float(np.median(head))
    sd = max(robust_noise_std(head), 1e-12 * float(np.max(np.abs(force))), 1e-300)
    if force.size <= need or np.max(np.abs(head - level)) > 8.0 * sd:
        raise IdentificationError(f"{recording.source}: the force is not quiet over the first {need} samples; the "
                                  f"model fit needs at least {need} samples before first contact (the noise of "
                                  "each channel is measured there) -- record with a pre-trigger")
    above = np.flatnonzero(np.abs(force - level) > 10.0 * sd)
    if not above.size:
        raise IdentificationError(f"{recording.source}: no impact: the force never leaves its noise ({sd:.3g} N)")
    _check_after(recording, (force.size - 1 - above[0]) / recording.sample_rate, min_duration)
    return recording.start_time + above[0] / recording.sample_rate


def _check_after(recording: Recording, after: float, min_duration: float) -> None:
    """IdentificationError where ``recording`` holds less than ``min_duration`` [s] (``after`` [s]) after contact."""
    if after < min_duration:
        raise IdentificationError(f"{recording.source}: the record holds {after * 1e3:.3g} ms after first contact; "
                                  f"the model fit needs at least {min_duration * 1e3:g} ms")


def check_channels(recording: Recording) -> None:
    """IdentificationError unless ``recording`` is a Recording with both channels the fit reads."""
    if not isinstance(recording, Recording):
        raise IdentificationError(f"recording must be a Recording, got {type(recording).__name__}")
    missing = [name for name in CHANNELS if name not in recording.channels]
    if missing:
        raise IdentificationError(f"{recording.source}: channel(s) {missing} missing; the model fit needs "
                                  f"{list(CHANNELS)}, found {sorted(recording.channels)}")


def staged(stages: Sequence, fit_one, state):
    """The staged-window fit of every caller (identification, stream, calibration, validation): ``fit_one(stage,
    state)`` of each stage in turn, each from the state the last one left; returns the last state."""
    for stage in stages:
        state = fit_one(stage, state)
    return state
