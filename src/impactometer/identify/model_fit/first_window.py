"""The first-window fit compiled: M1, V0 and the contact instant with the stand held, Levenberg-Marquardt in one
call on the calling thread, for a causal sensor model (the loop's records).

It is :func:`.early.fit_window` (the same residuals with the pre-trigger through its sums, the same Jacobian by
forward differences, the same damping and tests) without the ~0.1 ms of Python around each prediction and step,
which was two thirds of a first answer's time. Its predictions equal :func:`.forward.predict`'s but for the last
bit of M1 and V0 (``exp`` of the compiled code).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numba import njit

from ...model import dynamics as d
from ...model import fast
from ...model.setup import contact_state
from ...model.simulate import MAX_STEP, absolute_tolerance
from .early import (
    _CHECKED,
    _HIGH,
    _LOW,
    FIRST_DAMPING,
    LOWER,
    MOST_DAMPING,
    RAISE,
    Residuals,
    _integrate_in_turn,
    _law_fit,
)
from .fit import DAMPING, TOLERANCE, LawFit, Observed
from .forward import CHANNEL_INDEX, FIT_RTOL, MAX_FIT_STEPS, TRIAL_RANGES, Layout, _fir_decimate

#: the layout this fit takes: its names and transforms (:data:`.forward.CORE_PARAMETERS`)
CORE = (("mass", "log", 0.0), ("velocity", "log", 0.0), ("contact_time", "linear", 1.0))
#: ranges of M1 and V0 a trial point may take [kg], [m/s]
_BOUNDS = np.array([*TRIAL_RANGES[d.MASS], *TRIAL_RANGES[d.VELOCITY]])
#: what the compiled fit reports: converged, stopped at its evaluations, not integrable at the start or at the
#: Jacobian of its answer
CONVERGED, STOPPED, NO_START, NO_JACOBIAN = 0, 1, 2, 3


def takes(data: Observed, layout: Layout) -> bool:
    """Whether the compiled fit takes ``layout`` on ``data``: the core layout, a causal sensor model."""
    return data.grid.design == "causal" and tuple(
        (name, kind, param) for name, (_, kind, param) in zip(layout.names, layout.specs, strict=True)) == CORE


@njit(cache=True, error_model="numpy")
def _channels(stand, x, timing, offsets, fir, noise, tolerances, out, internal):
    """``out`` (2, n) := the channels over σ predicted at core variables ``x``; False where the model is not
    integrated there (outside the ranges, before ``timing[3]``, a stand that cannot start, a failed integration).
    ``timing``: origin of the contact instant [s], sample rate [Hz], start of the samples [s], earliest contact
    [s]; ``fir``: reversed taps; ``tolerances``: rtol then the absolute tolerances."""
    mass = np.exp(min(max(x[0], -700.0), 700.0))
    velocity = np.exp(min(max(x[1], -700.0), 700.0))
    contact = timing[0] + x[2] / timing[1]
    if not (_BOUNDS[0] <= mass <= _BOUNDS[1] and _BOUNDS[2] <= velocity <= _BOUNDS[3]
            and np.isfinite(contact) and contact >= timing[3]):
        return False
    p = stand.copy()
    p[d.MASS], p[d.VELOCITY] = mass, velocity
    y0 = np.empty(d.N_STATE)
    if not contact_state(p, y0):
        return False
    t = offsets - (contact - timing[2])
    first = max(np.searchsorted(t, 0.0, side="right") - 1, 0)
    internal[:, :first] = 0.0
    status, _ = fast.integrate_one(p, y0, t[first:], CHANNEL_INDEX, tolerances[0], tolerances[1:], MAX_STEP,
                                   MAX_FIT_STEPS, internal[:, first:])
    if status != fast.OK:
        return False
    factor = int(timing[4])
    _fir_decimate(internal, fir, int(timing[5]) - fir.size + 1, factor, out)
    for c in range(2):
        out[c] /= noise[c]
    return True


@njit(cache=True, error_model="numpy")
def _residuals(x, model, tail, head, r):
    """``r`` := the residuals after the head, then the head's two rows (``head``: root of its size, its means)."""
    n = tail.shape[1]
    for c in range(2):
        r[c * n:(c + 1) * n] = tail[c] - x[3 + c] - model[c]
        r[2 * n + c] = head[0] * (head[1 + c] - x[3 + c])
    return float(r @ r)


@njit(cache=True, error_model="numpy")
def _chi2(stand, x, timing, offsets, fir, noise, tolerances, tail, head, model, r, internal):
    """χ² less the head's constant at ``x`` (``model`` and ``r`` filled); inf where the model is not integrated
    there."""
    if not _channels(stand, x, timing, offsets, fir, noise, tolerances, model, internal):
        return np.inf
    return _residuals(x, model, tail, head, r)


@njit(cache=True, error_model="numpy")
def _begin(stand, x, timing, offsets, fir, noise, tolerances, tail, head):
    """χ² at the start (inf where the model is not integrated there) and the scratch arrays of a fit: internal
    histories, model, trial model, moved model, residuals, trial residuals."""
    n = tail.shape[1]
    internal, model = np.empty((2, offsets.size)), np.empty((2, n))
    r = np.empty(2 * n + 2)
    chi2 = _chi2(stand, x, timing, offsets, fir, noise, tolerances, tail, head, model, r, internal)
    return chi2, internal, model, np.empty((2, n)), np.empty((2, n)), r, np.empty(2 * n + 2)


@njit(cache=True, error_model="numpy")
def _jacobian(stand, x, model, steps, timing, offsets, fir, noise, tolerances, internal, moved, jac, head):
    n = model.shape[1]
    jac[:] = 0.0
    for j in range(3):
        shifted = x.copy()
        shifted[j] += steps[j]
        if not _channels(stand, shifted, timing, offsets, fir, noise, tolerances, moved, internal):
            return False
        for c in range(2):
            jac[c * n:(c + 1) * n, j] = (model[c] - moved[c]) / steps[j]
    jac[:n, 3] = -1.0
    jac[n:2 * n, 4] = -1.0
    jac[2 * n, 3] = jac[2 * n + 1, 4] = -head[0]
    return True


@njit(cache=True, error_model="numpy")
def _step(jac, r, damping):
    scale = np.sqrt(np.sum(jac * jac, axis=0))
    for k in range(scale.size):
        if scale[k] == 0.0:
            scale[k] = 1.0
    scaled = jac / scale
    normal = scaled.T @ scaled
    lifted = normal + damping * np.diag(np.diag(normal))
    return -np.linalg.lstsq(lifted, scaled.T @ r)[0] / scale


@njit(cache=True, error_model="numpy")
def _fit(stand, x, steps, timing, offsets, fir, noise, tolerances, tail, head, evaluations, jac):
    """Levenberg-Marquardt from ``x`` (as :func:`.early.fit_window`); returns (report, x, χ² less the head's
    constant, residual evaluations); ``jac`` holds the Jacobian at the answer."""
    chi2, internal, model, trial_model, moved, r, r_trial = _begin(stand, x, timing, offsets, fir, noise,
                                                                   tolerances, tail, head)
    if chi2 == np.inf:
        return NO_START, x, np.inf, 1
    count, damping, report = 1, FIRST_DAMPING, STOPPED
    if not _jacobian(stand, x, model, steps, timing, offsets, fir, noise, tolerances, internal, moved, jac, head):
        return NO_JACOBIAN, x, chi2, count
    while count < evaluations:
        step = _step(jac, r, damping)
        predicted = r + jac @ step
        if chi2 - float(predicted @ predicted) <= TOLERANCE * chi2:  # MINPACK's test on the predicted reduction
            return CONVERGED, x, chi2, count
        trial = x + step
        count += 1
        new = _chi2(stand, trial, timing, offsets, fir, noise, tolerances, tail, head, trial_model, r_trial, internal)
        if not new < chi2:
            damping *= RAISE
            if damping > MOST_DAMPING:  # no step lowers χ²: at the minimum to the precision of the model
                return CONVERGED, x, chi2, count
            continue
        report = CONVERGED if chi2 - new <= TOLERANCE * chi2 else STOPPED
        x, chi2, damping = trial, new, max(damping * LOWER, 1e-12)
        model[:], r[:] = trial_model, r_trial
        if not _jacobian(stand, x, model, steps, timing, offsets, fir, noise, tolerances, internal, moved, jac,
                         head):
            return NO_JACOBIAN, x, chi2, count
        if report == CONVERGED:
            return report, x, chi2, count
    return STOPPED, x, chi2, count


@njit(cache=True, error_model="numpy")
def _refine(stand, x, steps, timing, offsets, fir, noise, tolerances, tail, head, dampings, count_steps, jac):
    """:func:`.early.refine_window` compiled: ``count_steps`` steps from ``x``, each trying ``dampings`` in turn
    until χ² falls; returns (report, x, χ² less the head's constant, residual evaluations); ``jac`` holds the
    Jacobian the last step started from."""
    chi2, internal, model, trial_model, moved, r, r_trial = _begin(stand, x, timing, offsets, fir, noise,
                                                                   tolerances, tail, head)
    if chi2 == np.inf:
        return NO_START, x, np.inf, 1
    count = 1
    for _ in range(max(count_steps, 1)):
        if not _jacobian(stand, x, model, steps, timing, offsets, fir, noise, tolerances, internal, moved, jac,
                         head):
            return NO_JACOBIAN, x, chi2, count
        lowered = False
        for damping in dampings[:dampings.size if count_steps > 0 else 0]:
            trial = x + _step(jac, r, damping)
            count += 1
            new = _chi2(stand, trial, timing, offsets, fir, noise, tolerances, tail, head, trial_model, r_trial,
                        internal)
            if new < chi2:
                x, chi2, lowered = trial, new, True
                model[:], r[:] = trial_model, r_trial
                break
        if not lowered:
            break
    return CONVERGED, x, chi2, count


def _inputs(data: Observed, layout: Layout, start: dict[str, float],
            offsets: np.ndarray) -> tuple[tuple[Any, ...] | None, float]:
    """The compiled fits' arguments up to the evaluations (None where the start is outside the ranges), and the
    head's χ² constant."""
    residuals = Residuals(data, layout)  # the record after the head and the head's sums
    grid = residuals.grid
    x = np.r_[layout.variables(start), offsets / data.noise]
    stand = layout.packed(x[None, :3])[0][0]
    if not np.all((stand[_CHECKED] >= _LOW) & (stand[_CHECKED] <= _HIGH)):  # the start: outside the ranges
        return None, residuals.constant
    timing = np.array([layout.origin, layout.sample_rate, grid.start_time, residuals.earliest, grid.factor,
                       grid.pad])
    tolerances = np.r_[FIT_RTOL, absolute_tolerance(FIT_RTOL)]
    return (stand, x, residuals.steps.astype(float), timing, grid.offsets, grid.taps, data.noise, tolerances,
            np.ascontiguousarray(residuals.tail), np.r_[residuals.root, residuals.mean]), residuals.constant


def refine_first_window(data: Observed, layout: Layout, start: dict[str, float], offsets: np.ndarray, *,
                        steps: int = 1) -> LawFit | None:
    """:func:`.early.refine_window` of the core layout (:func:`takes`) compiled; None where the model cannot be
    integrated at the start."""
    inputs, constant = _inputs(data, layout, start, offsets)
    if inputs is None:
        return None
    jac = np.empty((inputs[8].size + 2, 5))
    report, x, chi2, count = _refine(*inputs, np.array(DAMPING), int(steps), jac)  # type: ignore[call-arg]
    if report in (NO_START, NO_JACOBIAN):
        return None
    return _law_fit(layout, data, x, chi2 + constant, jac, count, True)


def fit_first_window(data: Observed, layout: Layout, start: dict[str, float], *, evaluations: int,
                     information: bool = True) -> LawFit | None:
    """:func:`.early.fit_window` of the core layout (:func:`takes`) compiled; None where the model cannot be
    integrated at the start or at the answer (the caller's fit then says why)."""
    inputs, constant = _inputs(data, layout, start, data.offsets)
    if inputs is None:
        return None
    jac = np.empty((inputs[8].size + 2, 5))
    report, x, chi2, count = _fit(*inputs, int(evaluations), jac)  # type: ignore[call-arg]
    if report in (NO_START, NO_JACOBIAN):
        return None
    return _law_fit(layout, data, x, chi2 + constant, jac if information else None, count, report == CONVERGED)


#: whether this process has its kernels compiled or loaded from the cache (:func:`warm`)
_WARM: list[bool] = []


def warm() -> None:
    """Compile the kernels of the stream's fits, or load them from numba's cache, once per process: a real-time
    system has them before the impact (a first call in the middle of an impact took 1-3 s). Each is called with
    the argument types of its use and an M1 outside its range, so nothing is integrated."""
    if _WARM:
        return
    stand, x, rows, two = np.zeros(d.N_PARAM), np.full(5, -1e3), np.zeros((1, d.N_PARAM)), np.ones(2)
    args = (stand, x, np.ones(3), np.zeros(6), np.zeros(4), np.ones(1), two, np.ones(1 + d.N_STATE),
            np.zeros((2, 1)), np.ones(3))
    _fit(*args, 1, np.zeros((4, 5)))
    _refine(*args, np.array(DAMPING), 1, np.zeros((4, 5)))
    _integrate_in_turn(rows, np.zeros(4), np.zeros(1), FIT_RTOL, absolute_tolerance(FIT_RTOL), MAX_STEP,
                       MAX_FIT_STEPS, np.zeros((1, 2, 4)), np.zeros(1, dtype=np.int64))
    _WARM.append(True)
