"""The fits of a stream's growing record on the calling thread: the same model, weighting and Levenberg-Marquardt
steps as :mod:`.fit`, at the cost a real-time system pays for one answer.

A first answer reads a few hundred samples after contact: one prediction is ~0.05 ms of integration, and the
batch fit's machinery around it (a parallel launch of the integrator for every Jacobian, scipy's least-squares
setup) cost 10-20 times that. Here the rows of a prediction are integrated one after the other on the calling thread
(the integrator, tolerance and sensor model of :func:`.forward.predict`, so the predictions agree bit for bit),
and the Levenberg-Marquardt loop is a few lines of numpy on five unknowns (M1, V0, the contact instant and the two
offsets). The batch fit (:func:`~impactometer.identify.model_fit.identify`) does not use this module.

The integration tolerance stays :data:`.forward.FIT_RTOL`: a looser one saves little on a 4 ms window (54 steps at
1e-9, 25 at 1e-7; the output instants of the anti-alias filter cost as much) and its error, though far below the
noise (1e-7: 2e-5 of each channel's peak, against a noise of 2-5 % of its RMS), enters the finite-difference
Jacobian (:data:`.fit.STEP` moves a prediction by ~3e-4 of it): on the 27 first windows of the 3-grid it moved
σ(M1) by up to 8 % at 1e-8 and 37 % at 1e-7 (and the answers by up to 0.5 σ) and took more evaluations.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from numba import njit

from ...errors import IdentificationError
from ...model import dynamics as d
from ...model import fast
from ...model.setup import contact_state
from ...model.simulate import MAX_STEP, absolute_tolerance
from .fit import CONTACT_TIME_STEP, DAMPING, MAX_EVALUATIONS, STEP, TOLERANCE, LawFit, Observed
from .forward import CHANNEL_INDEX, FIT_RTOL, MAX_FIT_STEPS, TRIAL_RANGES, Grid, Layout, integrate_row, sensed
from .information import covariance

#: the packed parameters a trial point is checked on, and their ranges (:data:`.forward.TRIAL_RANGES`)
_CHECKED = np.array(list(TRIAL_RANGES), dtype=np.int64)
_LOW, _HIGH = (np.array([bounds[k] for bounds in TRIAL_RANGES.values()]) for k in (0, 1))
#: Marquardt damping of the first step of a fit to convergence, its factor after a step that fails and after one
#: that lowers χ², and the damping at which a fit that finds no lower χ² stops (relative to the diagonal of JᵀJ)
FIRST_DAMPING, RAISE, LOWER, MOST_DAMPING = 1e-3, 10.0, 0.1, 1e8


#: status of a row whose charge cannot carry the piston (it would rest on the bottom stop)
NO_START = -100


@njit(cache=True, error_model="numpy")
def _integrate_in_turn(params, offsets, shifts, rtol, atol, max_step, max_steps, out, status):
    """Row s integrated from its contact instant at ``offsets - shifts[s]``; zero before the last instant before
    contact (which holds the state at contact, as :func:`.forward.predict` integrates it)."""
    y0 = np.empty(d.N_STATE)
    for s in range(params.shape[0]):
        if not contact_state(params[s], y0):
            status[s] = NO_START
            continue
        status[s] = integrate_row(params[s], y0, offsets, shifts[s], CHANNEL_INDEX, rtol, atol, max_step,
                                  max_steps, out[s])


def predict_in_turn(grid: Grid, params: np.ndarray, contact_times: np.ndarray) -> np.ndarray:
    """:func:`.forward.predict` on the calling thread, one row after the other: the same channels (m, 2, size),
    the same refusals (a trial point outside :data:`.forward.TRIAL_RANGES`, a stand that cannot start, a failed
    integration) as :class:`IdentificationError`. Nothing of it runs on the thread pool: a launch there cost
    1-10 ms on a loaded machine, twenty integrations of a first window."""
    params = np.ascontiguousarray(params, dtype=float)
    checked = params[:, _CHECKED]
    outside = ~((checked >= _LOW) & (checked <= _HIGH))
    if outside.any() or not np.all(np.isfinite(contact_times)):
        raise IdentificationError("the model is not integrated at a trial point outside the ranges it is "
                                  "integrated in (packed parameters "
                                  f"{sorted(set(_CHECKED[np.nonzero(outside)[1]].tolist()))}) or at a contact "
                                  "instant that is not finite")
    offsets = grid.offsets
    out = np.empty((params.shape[0], 2, offsets.size))
    status = np.zeros(params.shape[0], dtype=np.int64)
    _integrate_in_turn(params, offsets, np.asarray(contact_times, dtype=float) - grid.start_time, FIT_RTOL,
                       absolute_tolerance(FIT_RTOL), MAX_STEP, MAX_FIT_STEPS, out, status)
    if np.any(status == NO_START):
        raise IdentificationError("the model cannot start: the charge is too low to carry the piston")
    if np.any(status != fast.OK):
        raise IdentificationError(f"the model's integration failed ({fast.STATUS_TEXT[int(status[status != 0][0])]})")
    return sensed(grid, out)


#: samples before the fit's first contact kept in the predicted part of the record (the rest before it, where every
#: trial point's model is zero, enters through its sums only): a trial contact instant earlier than this is
#: refused, as a point outside the ranges is
LEAD_SAMPLES = 64


class Residuals:
    """Weighted residuals (data − offset − model)/σ of ``layout`` on ``data`` and their Jacobian (forward
    differences of the layout's variables, :data:`.fit.STEP`, exact for the offsets), the prediction at the last
    point kept.

    The samples more than :data:`LEAD_SAMPLES` before the layout's first contact (``head``) hold offset and noise
    only under a causal sensor model: their residuals about each channel's mean m over them give χ² a constant,
    and the two rows sqrt(head)·(m − offset) stand for the rest. So χ² = |r|² + ``constant`` and JᵀJ are those of
    every sample, while the model is predicted on the samples after the head only (a first window holds ~1000
    pre-trigger samples for ~200 after contact).
    """

    def __init__(self, data: Observed, layout: Layout):
        self.layout, self.q, self.noise = layout, len(layout.names), data.noise
        grid, scaled = data.grid, data.channels / data.noise[:, None]
        onset = int(np.floor((layout.origin - grid.start_time) * grid.sample_rate))
        head = max(onset - LEAD_SAMPLES, 0) if grid.design in ("causal", "none") else 0
        self.earliest = grid.start_time + (head + 1) / grid.sample_rate  # a contact before it reaches the head
        self.grid = replace(grid, start_time=grid.start_time + head / grid.sample_rate, size=grid.size - head)
        self.tail = scaled[:, head:]
        self.mean = scaled[:, :head].mean(axis=1) if head else np.zeros(2)
        self.constant = float(np.sum(np.square(scaled[:, :head] - self.mean[:, None])))
        self.root = np.sqrt(head)
        self.steps = np.where(np.array(layout.names) == "contact_time", CONTACT_TIME_STEP, STEP)
        self._last: tuple[bytes, np.ndarray] | None = None

    def _predicted(self, rows: np.ndarray) -> np.ndarray:
        params, times = self.layout.packed(rows)
        if np.any(times < self.earliest):
            raise IdentificationError("the model is not predicted at a contact instant before the part of the "
                                      "record it is predicted on")
        return predict_in_turn(self.grid, params, times) / self.noise[None, :, None]

    def model(self, x: np.ndarray) -> np.ndarray:
        """Predicted channels over σ (2, n) at ``x`` (offsets excluded), on the samples after the head."""
        key = x[:self.q].tobytes()
        if self._last is None or self._last[0] != key:
            self._last = (key, self._predicted(x[None, :self.q])[0])
        return self._last[1]

    def __call__(self, x: np.ndarray) -> np.ndarray | None:
        """The residuals at ``x`` (those after the head, then the head's two rows); None where the model cannot be
        integrated there."""
        try:
            tail = self.tail - x[self.q:, None] - self.model(x)
        except IdentificationError:
            return None
        return np.r_[tail.ravel(), self.root * (self.mean - x[self.q:])]

    def jacobian(self, x: np.ndarray) -> np.ndarray:
        """∂residuals/∂x (rows of :meth:`__call__`, q + 2)."""
        base = self.model(x)
        moved = self._predicted(x[None, :self.q] + np.diag(self.steps))
        n = self.tail.shape[1]
        jac = np.zeros((2 * n + 2, self.q + 2))
        jac[:2 * n, :self.q] = ((base[None] - moved).reshape(self.q, -1) / self.steps[:, None]).T
        jac[:n, self.q] = jac[n:2 * n, self.q + 1] = -1.0
        jac[2 * n, self.q] = jac[2 * n + 1, self.q + 1] = -self.root
        return jac


def _step(jac: np.ndarray, r: np.ndarray, damping: float) -> np.ndarray:
    """The Marquardt step −(JᵀJ + λ·diag JᵀJ)⁻¹Jᵀr, in column-scaled variables."""
    scale = np.linalg.norm(jac, axis=0)
    scale[scale == 0.0] = 1.0
    scaled = jac / scale
    normal = scaled.T @ scaled
    return -np.linalg.lstsq(normal + damping * np.diag(np.diag(normal)), scaled.T @ r, rcond=None)[0] / scale


def _law_fit(layout: Layout, data: Observed, x: np.ndarray, chi2: float, jac: np.ndarray | None, evaluations: int,
             converged: bool) -> LawFit:
    cov, rank = covariance(jac) if jac is not None else (np.full((x.size, x.size), np.nan), 0)
    q = len(layout.names)
    return LawFit(layout=layout, x=x, values=layout.values(x[:q]), offsets=x[q:] * data.noise, cov=cov, rank=rank,
                  chi2=chi2, residuals=data.size, evaluations=evaluations, converged=converged)


def _start(data: Observed, layout: Layout, start: dict[str, float], offsets: np.ndarray):
    model = Residuals(data, layout)
    x = np.r_[layout.variables(start), offsets / data.noise]
    r = model(x)
    if r is None:
        raise IdentificationError(f"the {layout.law} model cannot be integrated at the fit's start")
    return model, x, r


def fit_window(data: Observed, layout: Layout, start: dict[str, float], *, evaluations: int = MAX_EVALUATIONS,
               information: bool = True) -> LawFit:
    """:func:`.fit.fit_law` of a stream's window: Levenberg-Marquardt from ``start`` (offsets from
    ``data.offsets``) until a step lowers χ² by less than :data:`.fit.TOLERANCE` of it (converged) or
    ``evaluations`` residual evaluations are spent; with ``information`` the covariance from the Jacobian at the
    answer (else NaN).

    Raises
    ------
    IdentificationError
        When the model cannot be integrated at the start or at the answer's Jacobian.
    """
    model, x, r = _start(data, layout, start, data.offsets)
    chi2, count, damping, converged = float(r @ r), 1, FIRST_DAMPING, False
    jac = model.jacobian(x)
    while count < evaluations and not converged:
        step = _step(jac, r, damping)
        predicted = r + jac @ step
        if chi2 - float(predicted @ predicted) <= TOLERANCE * chi2:  # MINPACK's test on the predicted reduction
            converged = True
            break
        trial = x + step
        r_trial = model(trial)
        count += 1
        lower = r_trial is not None and float(r_trial @ r_trial) < chi2
        if not lower:
            damping *= RAISE
            converged = damping > MOST_DAMPING  # no step lowers χ²: at the minimum to the precision of the model
            continue
        assert r_trial is not None  # lower χ²
        new = float(r_trial @ r_trial)
        converged = chi2 - new <= TOLERANCE * chi2
        x, r, chi2, damping = trial, r_trial, new, max(damping * LOWER, 1e-12)
        if not converged or information:
            jac = model.jacobian(x)
    return _law_fit(layout, data, x, chi2 + model.constant, jac if information else None, count, converged)


def refine_window(data: Observed, layout: Layout, start: dict[str, float], offsets: np.ndarray, *,
                  steps: int = 1) -> LawFit:
    """:func:`.fit.refine` on the calling thread: ``steps`` Levenberg-Marquardt steps from ``start`` and
    ``offsets`` [N], [m/s²], each trying the dampings of :data:`.fit.DAMPING` in turn until χ² falls; the
    covariance from the Jacobian the last step started from. The same arithmetic as :func:`.fit.refine`, so the
    same answer.

    Raises
    ------
    IdentificationError
        When the model cannot be integrated at the start.
    """
    model, x, r = _start(data, layout, start, offsets)
    chi2, count, jac = float(r @ r), 1, None
    for _ in range(steps):
        jac = model.jacobian(x)
        for damping in DAMPING:
            trial = x + _step(jac, r, damping)
            r_trial = model(trial)
            count += 1
            if r_trial is not None and float(r_trial @ r_trial) < chi2:
                x, r, chi2 = trial, r_trial, float(r_trial @ r_trial)
                break
        else:
            break
    return _law_fit(layout, data, x, chi2 + model.constant, model.jacobian(x) if jac is None else jac, count, True)
