"""The stream's fits of its growing record, compiled for a causal sensor model (the loop's records): the first
window (M1, V0 and the contact instant with the stand held) and each update, Levenberg-Marquardt in one call on
the calling thread.

The compiled fit is :func:`.engine.fit_law` of any layout with a fitted contact instant (the same packing
:func:`.forward._pack_row`, prediction :func:`.forward._predict_row`, rows :func:`.engine._weighted`, Jacobian
:func:`.engine._differenced` and solver :func:`.engine._advance`) without the ~0.1 ms of Python around each
prediction and step, which was two thirds of a first answer's time. Every other record is fitted by
:func:`.engine.fit_law` with the predictions on the calling thread.

The integration tolerance stays :data:`.forward.FIT_RTOL`: a looser one saves little on a 4 ms window (54 steps at
1e-9, 25 at 1e-7; the output instants of the anti-alias filter cost as much) and its error, though far below the
noise (1e-7: 2e-5 of each channel's peak, against a noise of 2-5 % of its RMS), enters the finite-difference
Jacobian (:data:`.engine.STEP` moves a prediction by ~3e-4 of it): on the 27 first windows of the 3-grid it moved
σ(M1) by up to 8 % at 1e-8 and 37 % at 1e-7 (and the answers by up to 0.5 σ) and took more evaluations.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from ...errors import IdentificationError
from ...model import dynamics as d
from ...model import fast
from ...model.simulate import MAX_STEP, absolute_tolerance
from .engine import (
    ACCEPT,
    DONE,
    MAX_EVALUATIONS,
    NO_TRIAL,
    TOLERANCE,
    TRIAL,
    LawFit,
    Observed,
    Residuals,
    Solution,
    _advance,
    _begin,
    _differenced,
    _law_fit,
    _outcome,
    _variables,
    _weighted,
    fit_law,
    normal_equations,
)
from .forward import (
    CHANNEL_INDEX,
    CONTACT_TAKEN,
    FIT_RTOL,
    MAX_FIT_STEPS,
    Layout,
    _contact_refusal,
    _fir_decimate,
    _outside_ranges,
    _pack_row,
    _predict_row,
    _schedule,
)

#: rtol then the absolute tolerances of the compiled fit's integration (:data:`.forward.FIT_RTOL`), made once
_TOLERANCES = np.r_[FIT_RTOL, absolute_tolerance(FIT_RTOL)]
#: what the compiled fit reports: converged, stopped at its evaluations or Jacobians, not integrable at the start
#: or at a Jacobian
CONVERGED, STOPPED, NO_START, NO_JACOBIAN = 0, 1, 2, 3


class _Timing(NamedTuple):
    """The instants of a compiled fit: origin of the contact instant [s] (the variable counts sample periods from
    it), sample rate [Hz], start of the samples after the head [s], earliest contact [s], and the sensor model's
    oversampling factor and pad [internal samples]."""

    origin: float
    sample_rate: float
    start_time: float
    earliest: float
    factor: int
    pad: int


class _Window(NamedTuple):
    """Everything the compiled fit reads of one window: the layout (its packed held values, its
    :attr:`.forward.Layout.codes` as ``slots``, ``code`` and ``param``, whether the law is hysteretic, its own
    bounds :attr:`.forward.Layout.limits` as ``low`` and ``high``, its priors: index, mean and σ of each), the start
    vector, the finite-difference steps, the :class:`Timing`, the internal
    instants, valve Z's opening schedule (:func:`.forward._schedule`: empty for the valve of the parameters), the
    reversed FIR taps, the noise σ (2,), rtol then the absolute tolerances, the samples after the
    head over σ (2, n), and the head (root of its size, its means)."""

    base: np.ndarray
    slots: np.ndarray
    code: np.ndarray
    param: np.ndarray
    hysteretic: bool
    low: np.ndarray
    high: np.ndarray
    prior_index: np.ndarray
    prior_mean: np.ndarray
    prior_sigma: np.ndarray
    x: np.ndarray
    steps: np.ndarray
    timing: _Timing
    instants: np.ndarray
    valve_times: np.ndarray
    valve_open: np.ndarray
    fir: np.ndarray
    noise: np.ndarray
    tolerances: np.ndarray
    tail: np.ndarray
    head: np.ndarray


def _takes(data: Observed, layout: Layout) -> bool:
    """Whether the compiled fit takes ``layout`` on ``data``: a causal sensor model and a fitted contact instant (a
    record with valve Z's opening too: the compiled predictor reads its schedule)."""
    return data.grid.design == "causal" and "contact_time" in layout.names


@njit(cache=True, error_model="numpy")
def _channels(w, x, out, internal, y0, p):
    """``out`` (2, n) := the channels over σ predicted at the layout's variables ``x``; False where the model is
    not integrated there (:func:`.forward._predict_row`'s refusals, a contact before the earliest)."""
    timing = w.timing
    shift = _pack_row(w.base, x, w.slots, w.code, w.param, w.hysteretic, w.low, w.high, p)
    contact = timing.origin + shift / timing.sample_rate
    if _contact_refusal(contact, timing.earliest) != CONTACT_TAKEN:
        return False
    if _predict_row(p, y0, w.instants, contact - timing.start_time, w.valve_times, w.valve_open, CHANNEL_INDEX,
                    w.tolerances[0], w.tolerances[1:], MAX_STEP, MAX_FIT_STEPS, internal) != fast.OK:
        return False
    _fir_decimate(internal, w.fir, timing.pad - w.fir.size + 1, timing.factor, out)
    for c in range(2):
        out[c] /= w.noise[c]
    return True


@njit(cache=True, error_model="numpy")
def _chi2(w, x, model, r, internal, y0, p):
    """χ² less the head's constant at ``x`` (``model`` and ``r`` filled: :func:`.engine._weighted`); inf where the
    model is not integrated there."""
    if not _channels(w, x, model, internal, y0, p):
        return np.inf
    _weighted(w.tail, model, x, w.slots.size, w.head[0], w.head[1:], w.prior_index, w.prior_mean, w.prior_sigma, r)
    return float(r @ r)


@njit(cache=True, error_model="numpy")
def _jacobian(w, x, model, internal, y0, p, moved, jac):
    """``jac`` := ∂residuals/∂x as :meth:`.engine.Residuals.jacobian` makes it (backward differences where a
    forward step leaves the range the model is integrated in; ``moved`` (q, 2, n) scratch); False where neither is
    integrated."""
    for sign in (1.0, -1.0):
        steps = sign * w.steps
        done = True
        for j in range(steps.size):
            shifted = x.copy()
            shifted[j] += steps[j]
            if not _channels(w, shifted, moved[j], internal, y0, p):
                done = False
                break
        if done:
            _differenced(model, moved, steps, w.head[0], w.prior_index, w.prior_sigma, jac)
            return True
    return False


@njit(cache=True, error_model="numpy")
def _solve(w, evaluations, jacobians, information, jac):
    """:func:`.engine.solve` compiled from ``w.x`` (``jacobians`` <= 0: no limit): the same requests of
    :func:`.engine._advance` answered by the compiled residuals and Jacobian; returns (report, x, χ² less the
    head's constant, residual evaluations); ``jac`` holds the last Jacobian made."""
    n, rows = w.tail.shape[1], jac.shape[0]
    # the internal instants the causal FIR reads (those after the last sample's: none)
    used = w.timing.pad + (n - 1) * w.timing.factor + 1
    internal, y0, p = np.empty((2, used)), np.empty(d.N_STATE), np.empty(w.base.size)
    model, trial_model, moved = np.empty((2, n)), np.empty((2, n)), np.empty((w.steps.size, 2, n))
    r, r_trial = np.empty(rows), np.empty(rows)
    x = w.x.copy()
    chi2 = _chi2(w, x, model, r, internal, y0, p)
    if chi2 == np.inf:
        return NO_START, x, np.inf, 1
    if not _jacobian(w, x, model, internal, y0, p, moved, jac):
        return NO_JACOBIAN, x, chi2, 1
    memo, trial, new = _begin(chi2), np.empty_like(x), NO_TRIAL
    normal, gradient = normal_equations(jac, r)
    while True:
        request = _advance(memo, x, trial, normal, gradient, new, evaluations, jacobians, information, TOLERANCE)
        if request == DONE:
            break
        if request == TRIAL:
            new = _chi2(w, trial, trial_model, r_trial, internal, y0, p)
            continue
        model[:], r[:], new = trial_model, r_trial, NO_TRIAL
        if request == ACCEPT:
            break
        if not _jacobian(w, x, model, internal, y0, p, moved, jac):
            chi2, count, _ = _outcome(memo)
            return NO_JACOBIAN, x, chi2, count
        normal, gradient = normal_equations(jac, r)
    chi2, count, converged = _outcome(memo)
    return CONVERGED if converged else STOPPED, x, chi2, count


def _window(data: Observed, layout: Layout, start: dict[str, float], offsets: np.ndarray) -> tuple[
        _Window | None, Residuals]:
    """The compiled fit's :class:`Window` (None where the start is outside the ranges) and the residual problem it
    compiles (the record after the head and the head's sums)."""
    problem = Residuals(data, layout)
    grid = problem.grid
    x = _variables(layout, start, offsets, data.noise)
    if _outside_ranges(layout.packed(x[None, :problem.q])[0][0]) >= 0:
        return None, problem
    timing = _Timing(origin=float(layout.origin), sample_rate=float(layout.sample_rate), start_time=grid.start_time,
                    earliest=problem.earliest, factor=int(grid.factor), pad=int(grid.pad))
    index, code, param = layout.codes
    low, high = layout.limits
    valve_times, valve_open = _schedule(grid)
    return _Window(base=layout.base, slots=index, code=code, param=param, hysteretic=layout.law == "hysteretic",
                  low=low, high=high,
                  prior_index=problem.prior_index, prior_mean=problem.prior_mean, prior_sigma=problem.prior_sigma,
                  x=x, steps=problem.steps.astype(float), timing=timing, instants=grid.instants,
                  valve_times=valve_times, valve_open=valve_open, fir=grid.taps,
                  noise=data.noise, tolerances=_TOLERANCES,
                  tail=np.ascontiguousarray(problem.tail), head=np.array([problem.root, *problem.mean])), problem


def _fit_window(data: Observed, layout: Layout, start: dict[str, float], offsets: np.ndarray | None = None, *,
               evaluations: int = MAX_EVALUATIONS, information: bool = True, jacobians: int | None = None) -> LawFit:
    """:func:`.engine.fit_law` of a stream's window on the calling thread, compiled for the core layout on a
    causal record (:func:`_takes`).

    Raises
    ------
    IdentificationError
        When the model cannot be integrated at the start or at a Jacobian.
    """
    offsets = data.offsets if offsets is None else offsets
    if not _takes(data, layout):
        return fit_law(data, layout, start, offsets=offsets, evaluations=evaluations, information=information,
                       jacobians=jacobians, in_turn=True)
    w, problem = _window(data, layout, start, offsets)
    if w is not None:
        jac = np.empty((w.tail.size + 2 + w.prior_index.size, problem.q + 2))
        update = jacobians is not None
        report, x, chi2, count = _solve(w, int(evaluations), int(jacobians or 0), information and not update, jac)
        if report not in (NO_START, NO_JACOBIAN):
            solution = Solution(x=x, residuals=np.empty(0), chi2=chi2, jacobian=jac, evaluations=count,
                                converged=update or report == CONVERGED)
            return _law_fit(problem, solution, information=information or update)
    raise IdentificationError(f"the {layout.law} model cannot be integrated at the fit's start or its answer")


#: whether this process has its kernels compiled or loaded from the cache (:func:`warm`)
_WARM: list[bool] = []


def _warm() -> None:
    """Compile the kernels of the stream's fits, or load them from numba's cache, once per process: a real-time
    system has them before the impact (a first call in the middle of an impact took 1-3 s). Each is called with
    the argument types of its use and an M1 outside its range, so nothing is integrated."""
    if _WARM:
        return
    from .forward import _predict_in_turn

    timing = _Timing(origin=0.0, sample_rate=1.0, start_time=0.0, earliest=0.0, factor=1, pad=0)
    index, code, param = (np.array([d.MASS, d.VELOCITY, -1]), np.array([0, 0, 2]), np.array([0.0, 0.0, 1.0]))
    w = _Window(base=np.zeros(d.N_PARAM), slots=index, code=code, param=param, hysteretic=True,
               low=np.full(3, -np.inf), high=np.full(3, np.inf),
               prior_index=np.zeros(1, dtype=np.int64), prior_mean=np.zeros(1), prior_sigma=np.ones(1),
               x=np.full(5, -1e3), steps=np.ones(3), timing=timing, instants=np.zeros(4), valve_times=np.empty(0),
               valve_open=np.empty(0), fir=np.ones(1),
               noise=np.ones(2), tolerances=np.ones(1 + d.N_STATE), tail=np.zeros((2, 1)), head=np.ones(3))
    _solve(w, 1, 0, True, np.zeros((5, 5)))
    _predict_in_turn(np.zeros((1, d.N_PARAM)), np.zeros(4), np.zeros(1), np.empty(0), np.empty(0), CHANNEL_INDEX,
                     FIT_RTOL, absolute_tolerance(FIT_RTOL), MAX_STEP, MAX_FIT_STEPS, np.zeros((1, 2, 4)),
                     np.zeros(1, dtype=np.int64))
    _WARM.append(True)
