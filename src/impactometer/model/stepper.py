"""One Dormand-Prince 5(4) step and its step-size controller, shared by every compiled integrator of the package.

The algorithm is scipy's ``solve_ivp(method="RK45")`` step for step: the same tableau, the same RMS error norm
with ``scale = atol + rtol·max(|y|, |y_new|)``, the same step-size controller (safety 0.9, factors 0.2-10, no growth
right after a rejection) and the same initial step selection, so that a given ``rtol``/``atol`` means the same
accuracy everywhere. Two systems share it (``system`` argument):

- ``PLAIN``: the drop-stand model (:func:`.dynamics.rhs`) with the constant valve opening of its parameters;
- ``ACTUATED``: the model plus valve Z's actuator (:func:`.actuated.derivatives`), whose opening is one more state and
  command is held in the input vector ``u`` (a zero-order hold between controller samples).

:func:`plain.integrate_one <.fast.integrate_one>` samples a whole record through the method's continuous extension;
the controlled loop (``control.plant``) integrates from one controller sample to the next.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from . import actuated
from . import dynamics as d

OK, TOO_MANY_STEPS, STEP_TOO_SMALL, NOT_FINITE = 0, 1, 2, 3
STATUS_TEXT = {TOO_MANY_STEPS: "too many steps", STEP_TOO_SMALL: "step size underflow",
               NOT_FINITE: "non-finite state"}
#: the systems a step can integrate
PLAIN, ACTUATED = 0, 1

#: Dormand-Prince 5(4) tableau: nodes, coupling coefficients, error weights (5th minus 4th order) and the
#: coefficients of the 4th-order continuous extension (scipy's ``RkDenseOutput``)
NODES = np.array([0.0, 1 / 5, 3 / 10, 4 / 5, 8 / 9, 1.0, 1.0])
COUPLING = np.array([
    [0, 0, 0, 0, 0, 0],
    [1 / 5, 0, 0, 0, 0, 0],
    [3 / 40, 9 / 40, 0, 0, 0, 0],
    [44 / 45, -56 / 15, 32 / 9, 0, 0, 0],
    [19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729, 0, 0],
    [9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656, 0],
    [35 / 384, 0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84]])
ERROR_WEIGHTS = np.array([-71 / 57600, 0, 71 / 16695, -71 / 1920, 17253 / 339200, -22 / 525, 1 / 40])
DENSE = np.array([
    [1, -8048581381 / 2820520608, 8663915743 / 2820520608, -12715105075 / 11282082432],
    [0, 0, 0, 0],
    [0, 131558114200 / 32700410799, -68118460800 / 10900136933, 87487479700 / 32700410799],
    [0, -1754552775 / 470086768, 14199869525 / 1410260304, -10690763975 / 1880347072],
    [0, 127303824393 / 49829197408, -318862633887 / 49829197408, 701980252875 / 199316789632],
    [0, -282668133 / 205662961, 2019193451 / 616988883, -1453857185 / 822651844],
    [0, 40617522 / 29380423, -110615467 / 29380423, 69997945 / 29380423]])

SAFETY, MIN_FACTOR, MAX_FACTOR = 0.9, 0.2, 10.0
ERROR_EXPONENT = -1.0 / 5.0  # -1 / (error estimator order + 1)
SMALL_ERROR = 5.9e-6  # error norms below this give a step factor > MAX_FACTOR (exactly: below 5.9049e-6)
#: stages of one step (the last one is f(y_new), the first of the next step)
STAGES = 7
#: rows of the work array of a step: the stages, then the new state and the stage state
NEW_STATE, STAGE_STATE = STAGES, STAGES + 1
WORK_ROWS = STAGES + 2


@njit(cache=True, inline="always", error_model="numpy")
def evaluate(system, y, p, u, dy):
    """Right-hand side of ``system`` at state ``y`` into ``dy``; ``u`` holds the inputs of the actuated system."""
    if system == PLAIN:
        d.rhs(y, p, p[d.VALVE_AREA], dy)
    else:
        actuated.derivatives(y, p, u, dy)


@njit(cache=True, inline="always", error_model="numpy")
def rms(x, scale):
    """Root mean square of ``x / scale``."""
    acc = 0.0
    for i in range(x.size):
        r = x[i] / scale[i]
        acc += r * r
    return math.sqrt(acc / x.size)


@njit(cache=True, error_model="numpy")
def initial_step(system, p, u, y0, f0, t_end, rtol, atol, max_step, work, f1, scale):
    """First step size [s], as scipy's ``select_initial_step`` (Hairer, Nørsett & Wanner, Sec. II.4).

    ``work``, ``f1`` and ``scale`` are scratch arrays of the state's size (nothing is allocated, so that the step
    compiles for any numba target).
    """
    n = y0.size
    for i in range(n):
        scale[i] = atol[i] + abs(y0[i]) * rtol
    d0 = rms(y0, scale)
    d1 = rms(f0, scale)
    h0 = 1e-6 if d0 < 1e-5 or d1 < 1e-5 else 0.01 * d0 / d1
    h0 = min(h0, t_end)
    for i in range(n):
        work[i] = y0[i] + h0 * f0[i]
    evaluate(system, work, p, u, f1)
    for i in range(n):
        work[i] = f1[i] - f0[i]
    d2 = rms(work, scale) / h0
    h1 = max(1e-6, h0 * 1e-3) if d1 <= 1e-15 and d2 <= 1e-15 else (0.01 / max(d1, d2)) ** (1.0 / 5.0)
    return min(100.0 * h0, h1, t_end, max_step)


@njit(cache=True, inline="always", error_model="numpy")
def state_size(system):
    """Size of the state of ``system`` (a compile-time constant wherever ``system`` is one)."""
    return d.N_STATE if system == PLAIN else actuated.N_STATE


@njit(cache=True, inline="always", error_model="numpy")
def attempt(system, y, h, k, p, u, rtol, atol):
    """One Dormand-Prince 5(4) step of size ``h`` [s] from ``y``; returns the RMS error norm.

    ``k`` (WORK_ROWS, n) holds f(y) in its first row on entry; on return its first STAGES rows hold every stage
    (the last one is f(y_new)) and row NEW_STATE the new state. One work array instead of nine arguments: every
    array handed to a compiled function costs reference counting, as much as a tenth of a step. The stage sums are
    written out with the coefficients of :data:`COUPLING` and :data:`ERROR_WEIGHTS` (tested against them) so that
    the compiler sees constants.
    """
    n = state_size(system)
    y_new = k[NEW_STATE]
    ys = k[STAGE_STATE]
    for i in range(n):
        ys[i] = y[i] + h * (0.2 * k[0, i])
    evaluate(system, ys, p, u, k[1])
    for i in range(n):
        ys[i] = y[i] + h * (3 / 40 * k[0, i] + 9 / 40 * k[1, i])
    evaluate(system, ys, p, u, k[2])
    for i in range(n):
        ys[i] = y[i] + h * (44 / 45 * k[0, i] - 56 / 15 * k[1, i] + 32 / 9 * k[2, i])
    evaluate(system, ys, p, u, k[3])
    for i in range(n):
        ys[i] = y[i] + h * (19372 / 6561 * k[0, i] - 25360 / 2187 * k[1, i] + 64448 / 6561 * k[2, i]
                            - 212 / 729 * k[3, i])
    evaluate(system, ys, p, u, k[4])
    for i in range(n):
        ys[i] = y[i] + h * (9017 / 3168 * k[0, i] - 355 / 33 * k[1, i] + 46732 / 5247 * k[2, i]
                            + 49 / 176 * k[3, i] - 5103 / 18656 * k[4, i])
    evaluate(system, ys, p, u, k[5])
    for i in range(n):
        y_new[i] = y[i] + h * (35 / 384 * k[0, i] + 500 / 1113 * k[2, i] + 125 / 192 * k[3, i]
                               - 2187 / 6784 * k[4, i] + 11 / 84 * k[5, i])
    evaluate(system, y_new, p, u, k[6])
    squares = 0.0  # RMS of the error estimate over scale = atol + rtol·max(|y|, |y_new|)
    for i in range(n):
        e = h * (-71 / 57600 * k[0, i] + 71 / 16695 * k[2, i] - 71 / 1920 * k[3, i]
                 + 17253 / 339200 * k[4, i] - 22 / 525 * k[5, i] + 1 / 40 * k[6, i])
        e /= atol[i] + max(abs(y[i]), abs(y_new[i])) * rtol
        squares += e * e
    return math.sqrt(squares / n)


@njit(cache=True, inline="always", error_model="numpy")
def step(system, y, t, t_end, h_abs, p, u, rtol, atol, max_step, k):
    """One accepted step from ``t`` towards ``t_end`` [s] (never beyond it), rejected attempts included.

    ``k`` is the work array of :func:`attempt` with f(y) in its first row. Returns ``(status, t_new, h_abs)``: on
    success ``k`` holds the step's stages and the new state (row NEW_STATE) and ``h_abs`` is the next step size
    proposed by the controller; :func:`accept` then moves the new state into ``y``.
    """
    min_step = 10.0 * abs(math.nextafter(t, math.inf) - t)
    if h_abs > max_step:
        h_abs = max_step
    elif h_abs < min_step:
        h_abs = min_step
    rejected = False
    while True:
        if h_abs < min_step:
            return STEP_TOO_SMALL, t, h_abs
        t_new = t + h_abs
        if t_new > t_end:
            t_new = t_end
        h = t_new - t
        h_abs = abs(h)
        error_norm = attempt(system, y, h, k, p, u, rtol, atol)
        if error_norm < 1.0:
            # a small error norm gives MAX_FACTOR without the (costly) power
            factor = (MAX_FACTOR if error_norm < SMALL_ERROR
                      else min(MAX_FACTOR, SAFETY * error_norm**ERROR_EXPONENT))
            if rejected:
                factor = min(1.0, factor)
            return OK, t_new, h_abs * factor
        if not math.isfinite(error_norm):
            h_abs *= MIN_FACTOR
            if h_abs < min_step:
                return NOT_FINITE, t, h_abs
        else:
            h_abs *= max(MIN_FACTOR, SAFETY * error_norm**ERROR_EXPONENT)
        rejected = True


@njit(cache=True, inline="always", error_model="numpy")
def accept(y, k):
    """Move the new state of an accepted step into ``y`` and its last stage, f(y_new), into the first row."""
    for i in range(y.size):
        y[i] = k[NEW_STATE, i]
        k[0, i] = k[STAGES - 1, i]


@njit(cache=True, error_model="numpy")
def advance(system, y, p, u, interval, h_abs, rtol, atol, max_step, max_steps, k):
    """Integrate ``y`` in place over ``interval`` [s] with the inputs ``u`` held (``k``: a work array of
    :func:`attempt`, its first row filled here). Returns ``(status, next step size [s], accepted steps)``.
    """
    evaluate(system, y, p, u, k[0])
    t = 0.0
    steps = 0
    while t < interval:
        if steps >= max_steps:
            return TOO_MANY_STEPS, h_abs, steps
        status, t, h_abs = step(system, y, t, interval, h_abs, p, u, rtol, atol, max_step, k)
        if status != OK:
            return status, h_abs, steps
        accept(y, k)
        steps += 1
    return OK, h_abs, steps
