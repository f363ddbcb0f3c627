"""Fast batch integrator: adaptive Dormand-Prince 5(4) compiled with numba, parallel over scenarios.

Each scenario is integrated with its own step size; histories are written at the requested sample times
through the method's 4th-order continuous extension (the same one scipy's ``RK45`` uses).
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from . import dynamics as d

OK, TOO_MANY_STEPS, STEP_TOO_SMALL, NOT_FINITE = 0, 1, 2, 3
STATUS_TEXT = {TOO_MANY_STEPS: "too many steps", STEP_TOO_SMALL: "step size underflow",
               NOT_FINITE: "non-finite state"}

_C = np.array([0.0, 1 / 5, 3 / 10, 4 / 5, 8 / 9, 1.0, 1.0])
_A = np.array([
    [0, 0, 0, 0, 0, 0],
    [1 / 5, 0, 0, 0, 0, 0],
    [3 / 40, 9 / 40, 0, 0, 0, 0],
    [44 / 45, -56 / 15, 32 / 9, 0, 0, 0],
    [19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729, 0, 0],
    [9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656, 0],
    [35 / 384, 0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84]])
_E = np.array([-71 / 57600, 0, 71 / 16695, -71 / 1920, 17253 / 339200, -22 / 525, 1 / 40])
_P = np.array([
    [1, -8048581381 / 2820520608, 8663915743 / 2820520608, -12715105075 / 11282082432],
    [0, 0, 0, 0],
    [0, 131558114200 / 32700410799, -68118460800 / 10900136933, 87487479700 / 32700410799],
    [0, -1754552775 / 470086768, 14199869525 / 1410260304, -10690763975 / 1880347072],
    [0, 127303824393 / 49829197408, -318862633887 / 49829197408, 701980252875 / 199316789632],
    [0, -282668133 / 205662961, 2019193451 / 616988883, -1453857185 / 822651844],
    [0, 40617522 / 29380423, -110615467 / 29380423, 69997945 / 29380423]])


@njit(cache=True, error_model="numpy")
def integrate_one(p, y0, t_out, channel_index, rtol, atol, max_step, max_steps, out):
    """Integrate one scenario from t = 0 and write ``channels[channel_index]`` at ``t_out`` into ``out``.

    Returns a status code (0 = success) and the number of accepted steps.
    """
    n = y0.size
    k = np.zeros((7, n))
    y = y0.copy()
    y_new = np.empty(n)
    y_stage = np.empty(n)
    y_dense = np.empty(n)
    dense = np.empty((4, n))
    row = np.empty(d.N_CHANNEL)
    valve = p[d.VALVE_AREA]
    t = 0.0
    t_end = t_out[-1]
    i_out = 0
    while i_out < t_out.size and t_out[i_out] <= 0.0:
        d.channels(y, p, row)
        for j in range(channel_index.size):
            out[j, i_out] = row[channel_index[j]]
        i_out += 1
    d.rhs(y, p, valve, k[0])
    h = min(1e-6, max_step)
    steps = 0
    while t < t_end:
        if steps >= max_steps:
            return TOO_MANY_STEPS, steps
        if t + h > t_end:
            h = t_end - t
        for s in range(1, 7):
            for i in range(n):
                acc = 0.0
                for m in range(s):
                    acc += _A[s, m] * k[m, i]
                y_stage[i] = y[i] + h * acc
            d.rhs(y_stage, p, valve, k[s])
        # y_stage now holds the 5th-order solution (stage 7 is evaluated at it: FSAL)
        error_norm = 0.0
        for i in range(n):
            y_new[i] = y_stage[i]
            acc = 0.0
            for m in range(7):
                acc += _E[m] * k[m, i]
            scale = atol[i] + rtol * max(abs(y[i]), abs(y_new[i]))
            e = abs(h * acc) / scale
            if e > error_norm:
                error_norm = e
        if not np.isfinite(error_norm):
            h *= 0.2
            if h < 1e-14:
                return NOT_FINITE, steps
            continue
        if error_norm <= 1.0:
            t_next = t + h
            if i_out < t_out.size and t_out[i_out] <= t_next:
                for i in range(n):  # coefficients of the continuous extension on this step
                    for j in range(4):
                        acc = 0.0
                        for m in range(7):
                            acc += k[m, i] * _P[m, j]
                        dense[j, i] = h * acc
            while i_out < t_out.size and t_out[i_out] <= t_next:
                theta = (t_out[i_out] - t) / h
                for i in range(n):
                    y_dense[i] = y[i] + theta * (dense[0, i] + theta * (dense[1, i] + theta * (
                        dense[2, i] + theta * dense[3, i])))
                d.channels(y_dense, p, row)
                for j in range(channel_index.size):
                    out[j, i_out] = row[channel_index[j]]
                i_out += 1
            t = t_next
            for i in range(n):
                y[i] = y_new[i]
                k[0, i] = k[6, i]
            steps += 1
            factor = 5.0 if error_norm == 0.0 else min(5.0, 0.9 * error_norm ** -0.2)
        else:
            factor = max(0.2, 0.9 * error_norm ** -0.2)
        h = min(h * factor, max_step)
        if h < 1e-14:
            return STEP_TOO_SMALL, steps
    return OK, steps


@njit(cache=True, parallel=True, error_model="numpy")
def integrate_batch(params, y0, t_out, channel_index, rtol, atol, max_step, max_steps, out, status, steps):
    """Integrate every row of ``params`` in parallel; ``out`` has shape (n, len(channel_index), len(t_out))."""
    for s in prange(params.shape[0]):
        status[s], steps[s] = integrate_one(params[s], y0[s], t_out, channel_index, rtol, atol, max_step,
                                            max_steps, out[s])
