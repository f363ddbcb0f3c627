"""The stream's fits of its growing record, with the compiled first-window fit: M1, V0 and the contact instant with
the stand held, Levenberg-Marquardt in one call on the calling thread, for a causal sensor model (the loop's
records).

The compiled fit is :func:`.engine.fit_law` of that layout (the same residuals with the pre-trigger through its
sums, the same Jacobian by forward differences, the same damping step :func:`.engine.damped_step` and stopping
rule :func:`.engine.stops`) without the ~0.1 ms of Python around each prediction and step, which was two thirds of
a first answer's time. Its predictions equal :func:`.forward.predict`'s but for the last bit of M1 and V0 (``exp``
of the compiled code). Every other layout is fitted by :func:`.engine.fit_law` with the predictions on the
calling thread.

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
    FIRST_DAMPING,
    MAX_EVALUATIONS,
    TOLERANCE,
    LawFit,
    Observed,
    Residuals,
    Solution,
    adapt,
    damped_step,
    fit_law,
    law_fit,
    stops,
    variables,
)
from .forward import CHANNEL_INDEX, FIT_RTOL, MAX_FIT_STEPS, Layout, _fir_decimate, outside_ranges, predict_row

#: the layout this fit takes: its names and transforms (:data:`.forward.CORE_PARAMETERS`)
CORE = (("mass", "log", 0.0), ("velocity", "log", 0.0), ("contact_time", "linear", 1.0))
#: what the compiled fit reports: converged, stopped at its evaluations or Jacobians, not integrable at the start
#: or at a Jacobian
CONVERGED, STOPPED, NO_START, NO_JACOBIAN = 0, 1, 2, 3


class Timing(NamedTuple):
    """The instants of a compiled fit: origin of the contact instant [s] (the variable counts sample periods from
    it), sample rate [Hz], start of the samples after the head [s], earliest contact [s], and the sensor model's
    oversampling factor and pad [internal samples]."""

    origin: float
    sample_rate: float
    start_time: float
    earliest: float
    factor: int
    pad: int


class Window(NamedTuple):
    """Everything the compiled fit reads of one window: the packed stand, the start vector, the
    finite-difference steps, the :class:`Timing`, the internal instants, the reversed FIR taps, the noise σ (2,),
    rtol then the absolute tolerances, the samples after the head over σ (2, n), and the head (root of its size,
    its means)."""

    stand: np.ndarray
    x: np.ndarray
    steps: np.ndarray
    timing: Timing
    offsets: np.ndarray
    fir: np.ndarray
    noise: np.ndarray
    tolerances: np.ndarray
    tail: np.ndarray
    head: np.ndarray


def takes(data: Observed, layout: Layout) -> bool:
    """Whether the compiled fit takes ``layout`` on ``data``: the core layout, a causal sensor model."""
    return data.grid.design == "causal" and tuple(
        (name, kind, param) for name, (_, kind, param) in zip(layout.names, layout.specs, strict=True)) == CORE


@njit(cache=True, error_model="numpy")
def _channels(w, x, out, internal, y0):
    """``out`` (2, n) := the channels over σ predicted at core variables ``x``; False where the model is not
    integrated there (:func:`.forward.predict_row`'s refusals, a contact before the earliest)."""
    timing = w.timing
    p = w.stand.copy()
    p[d.MASS] = np.exp(min(max(x[0], -700.0), 700.0))
    p[d.VELOCITY] = np.exp(min(max(x[1], -700.0), 700.0))
    contact = timing.origin + x[2] / timing.sample_rate
    if not (np.isfinite(contact) and contact >= timing.earliest):
        return False
    if predict_row(p, y0, w.offsets, contact - timing.start_time, CHANNEL_INDEX, w.tolerances[0],
                   w.tolerances[1:], MAX_STEP, MAX_FIT_STEPS, internal) != fast.OK:
        return False
    _fir_decimate(internal, w.fir, timing.pad - w.fir.size + 1, timing.factor, out)
    for c in range(2):
        out[c] /= w.noise[c]
    return True


@njit(cache=True, error_model="numpy")
def _chi2(w, x, model, r, internal, y0):
    """χ² less the head's constant at ``x`` (``model`` and ``r`` filled: the residuals after the head, then the
    head's two rows); inf where the model is not integrated there."""
    if not _channels(w, x, model, internal, y0):
        return np.inf
    n = w.tail.shape[1]
    for c in range(2):
        r[c * n:(c + 1) * n] = w.tail[c] - x[3 + c] - model[c]
        r[2 * n + c] = w.head[0] * (w.head[1 + c] - x[3 + c])
    return float(r @ r)


@njit(cache=True, error_model="numpy")
def _jacobian(w, x, model, internal, y0, moved, jac):
    n = model.shape[1]
    jac[:] = 0.0
    for j in range(3):
        shifted = x.copy()
        shifted[j] += w.steps[j]
        if not _channels(w, shifted, moved, internal, y0):
            return False
        for c in range(2):
            jac[c * n:(c + 1) * n, j] = (model[c] - moved[c]) / w.steps[j]
    jac[:n, 3] = -1.0
    jac[n:2 * n, 4] = -1.0
    jac[2 * n, 3] = jac[2 * n + 1, 4] = -w.head[0]
    return True


@njit(cache=True, error_model="numpy")
def _solve(w, evaluations, jacobians, information, jac):
    """:func:`.engine.solve` compiled from ``w.x`` (``jacobians`` <= 0: no limit); returns (report, x, χ² less the
    head's constant, residual evaluations); ``jac`` holds the last Jacobian made."""
    n = w.tail.shape[1]
    internal, y0 = np.empty((2, w.offsets.size)), np.empty(d.N_STATE)
    model, trial_model, moved = np.empty((2, n)), np.empty((2, n)), np.empty((2, n))
    r, r_trial = np.empty(2 * n + 2), np.empty(2 * n + 2)
    x = w.x
    chi2 = _chi2(w, x, model, r, internal, y0)
    if chi2 == np.inf:
        return NO_START, x, np.inf, 1
    count, made, damping, growth = 1, 1, FIRST_DAMPING, 2.0
    if not _jacobian(w, x, model, internal, y0, moved, jac):
        return NO_JACOBIAN, x, chi2, count
    while count < evaluations:
        step = damped_step(jac, r, damping)
        predicted = r + jac @ step
        lower = float(predicted @ predicted)
        if stops(chi2, lower, damping, TOLERANCE):
            return CONVERGED, x, chi2, count
        trial = x + step
        count += 1
        new = _chi2(w, trial, trial_model, r_trial, internal, y0)
        damping, growth = adapt(damping, growth, (chi2 - new) / max(chi2 - lower, 1e-300))
        if not new < chi2:
            if stops(chi2, new, damping, TOLERANCE):  # no damping lowers χ²: at the minimum to the model precision
                return CONVERGED, x, chi2, count
            continue
        converged = stops(chi2, new, damping, TOLERANCE)
        x, chi2 = trial, new
        model[:], r[:] = trial_model, r_trial
        if jacobians > 0 and made >= jacobians:
            return CONVERGED if converged else STOPPED, x, chi2, count
        if not converged or information:
            if not _jacobian(w, x, model, internal, y0, moved, jac):
                return NO_JACOBIAN, x, chi2, count
            made += 1
        if converged:
            return CONVERGED, x, chi2, count
    return STOPPED, x, chi2, count


def _window(data: Observed, layout: Layout, start: dict[str, float], offsets: np.ndarray) -> tuple[
        Window | None, Residuals]:
    """The compiled fit's :class:`Window` (None where the start is outside the ranges) and the residual problem it
    compiles (the record after the head and the head's sums)."""
    problem = Residuals(data, layout)
    grid = problem.grid
    x = variables(layout, start, offsets, data.noise)
    stand = layout.packed(x[None, :3])[0][0]
    if outside_ranges(stand) >= 0:
        return None, problem
    timing = Timing(origin=float(layout.origin), sample_rate=float(layout.sample_rate), start_time=grid.start_time,
                    earliest=problem.earliest, factor=int(grid.factor), pad=int(grid.pad))
    return Window(stand=stand, x=x, steps=problem.steps.astype(float), timing=timing, offsets=grid.offsets,
                  fir=grid.taps, noise=data.noise, tolerances=np.r_[FIT_RTOL, absolute_tolerance(FIT_RTOL)],
                  tail=np.ascontiguousarray(problem.tail), head=np.r_[problem.root, problem.mean]), problem


def fit_window(data: Observed, layout: Layout, start: dict[str, float], offsets: np.ndarray | None = None, *,
               evaluations: int = MAX_EVALUATIONS, information: bool = True, jacobians: int | None = None) -> LawFit:
    """:func:`.engine.fit_law` of a stream's window on the calling thread, compiled for the core layout on a
    causal record (:func:`takes`).

    Raises
    ------
    IdentificationError
        When the model cannot be integrated at the start or at a Jacobian.
    """
    offsets = data.offsets if offsets is None else offsets
    if not takes(data, layout):
        return fit_law(data, layout, start, offsets=offsets, evaluations=evaluations, information=information,
                       jacobians=jacobians, in_turn=True)
    w, problem = _window(data, layout, start, offsets)
    if w is not None:
        jac = np.empty((w.tail.size + 2, 5))
        update = jacobians is not None
        report, x, chi2, count = _solve(w, int(evaluations), int(jacobians or 0), information and not update, jac)
        if report not in (NO_START, NO_JACOBIAN):
            solution = Solution(x=x, residuals=np.empty(0), chi2=chi2, jacobian=jac, evaluations=count,
                                converged=update or report == CONVERGED)
            return law_fit(problem, solution, information=information or update)
    raise IdentificationError(f"the {layout.law} model cannot be integrated at the fit's start or its answer")


#: whether this process has its kernels compiled or loaded from the cache (:func:`warm`)
_WARM: list[bool] = []


def warm() -> None:
    """Compile the kernels of the stream's fits, or load them from numba's cache, once per process: a real-time
    system has them before the impact (a first call in the middle of an impact took 1-3 s). Each is called with
    the argument types of its use and an M1 outside its range, so nothing is integrated."""
    if _WARM:
        return
    from .forward import _predict_in_turn

    timing = Timing(origin=0.0, sample_rate=1.0, start_time=0.0, earliest=0.0, factor=1, pad=0)
    w = Window(stand=np.zeros(d.N_PARAM), x=np.full(5, -1e3), steps=np.ones(3), timing=timing, offsets=np.zeros(4),
               fir=np.ones(1), noise=np.ones(2), tolerances=np.ones(1 + d.N_STATE), tail=np.zeros((2, 1)),
               head=np.ones(3))
    _solve(w, 1, 0, True, np.zeros((4, 5)))
    _predict_in_turn(np.zeros((1, d.N_PARAM)), np.zeros(4), np.zeros(1), CHANNEL_INDEX, FIT_RTOL,
                     absolute_tolerance(FIT_RTOL), MAX_STEP, MAX_FIT_STEPS, np.zeros((1, 2, 4)),
                     np.zeros(1, dtype=np.int64))
    _WARM.append(True)
