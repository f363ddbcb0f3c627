"""Fast batch integrator: adaptive Dormand-Prince 5(4) compiled with numba, parallel over scenarios.

The kernel is the algorithm of scipy's ``solve_ivp(method="RK45")`` step for step -- the same tableau, the same
RMS error norm with ``scale = atol + rtol·max(|y|, |y_new|)``, the same step-size controller (safety 0.9, factors
0.2-10, no growth right after a rejection) and the same initial step selection -- so that a given ``rtol``/``atol``
means the same accuracy in both. Each scenario is integrated with its own step size; histories are written at the
requested sample times through the method's 4th-order continuous extension (scipy's ``RkDenseOutput``).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from . import dynamics as d

OK, TOO_MANY_STEPS, STEP_TOO_SMALL, NOT_FINITE = 0, 1, 2, 3
STATUS_TEXT = {TOO_MANY_STEPS: "too many steps", STEP_TOO_SMALL: "step size underflow",
               NOT_FINITE: "non-finite state"}

#: Dormand-Prince 5(4) tableau (also used by other compiled kernels of the package)
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

SAFETY, MIN_FACTOR, MAX_FACTOR = 0.9, 0.2, 10.0
ERROR_EXPONENT = -1.0 / 5.0  # -1 / (error estimator order + 1)
SMALL_ERROR = 5.9e-6  # error norms below this give a step factor > MAX_FACTOR (exactly: below 5.9049e-6)
N = d.N_STATE  # loops over a compile-time state size


@njit(cache=True, inline="always", error_model="numpy")
def _rms(x, scale):
    acc = 0.0
    for i in range(x.size):
        r = x[i] / scale[i]
        acc += r * r
    return math.sqrt(acc / x.size)


@njit(cache=True, error_model="numpy")
def initial_step(p, y0, f0, t_end, rtol, atol, max_step, work, f1, scale):
    """First step size [s], as scipy's ``select_initial_step`` (Hairer, Nørsett & Wanner, Sec. II.4).

    ``work``, ``f1`` and ``scale`` are scratch arrays of the state's size.
    """
    n = y0.size
    for i in range(n):
        scale[i] = atol[i] + abs(y0[i]) * rtol
    d0 = _rms(y0, scale)
    d1 = _rms(f0, scale)
    h0 = 1e-6 if d0 < 1e-5 or d1 < 1e-5 else 0.01 * d0 / d1
    h0 = min(h0, t_end)
    for i in range(n):
        work[i] = y0[i] + h0 * f0[i]
    d.rhs(work, p, p[d.VALVE_AREA], f1)
    for i in range(n):
        work[i] = f1[i] - f0[i]
    d2 = _rms(work, scale) / h0
    h1 = max(1e-6, h0 * 1e-3) if d1 <= 1e-15 and d2 <= 1e-15 else (0.01 / max(d1, d2)) ** (1.0 / 5.0)
    return min(100.0 * h0, h1, t_end, max_step)


#: rows of the scratch array :func:`integrate_into` works in (stages, states, interpolant, tolerance scale)
WORK_ROWS = 14


@njit(cache=True, error_model="numpy")
def integrate_one(p, y0, t_out, channel_index, rtol, atol, max_step, max_steps, out):
    """Integrate one scenario from t = 0 and write ``channels[channel_index]`` at ``t_out`` into ``out``.

    Returns a status code (0 = success) and the number of accepted steps. ``max_step`` [s] bounds the step size,
    ``max_steps`` the number of accepted steps.
    """
    return integrate_into(p, y0, t_out, channel_index, rtol, atol, max_step, max_steps, out,
                          np.empty((WORK_ROWS, N)), np.empty(N, dtype=np.int64), np.empty(d.N_CHANNEL))


@njit(cache=True, error_model="numpy")
def integrate_into(p, y0, t_out, channel_index, rtol, atol, max_step, max_steps, out, work, need, row):
    """:func:`integrate_one` in caller-provided scratch memory, so that it allocates nothing and compiles for
    any numba target (the CPU here, a CUDA device in :mod:`.gpu`).

    ``work`` is a (WORK_ROWS, N_STATE) float64 array, ``need`` an (N_STATE,) int64 array and ``row`` an
    (N_CHANNEL,) float64 array; their contents on entry do not matter.
    """
    n = N  # compile-time size: the loops are unrolled
    k1, k2, k3, k4, k5, k6, k7 = work[0], work[1], work[2], work[3], work[4], work[5], work[6]
    y, y_new, ys, q1, q2, q3 = work[7], work[8], work[9], work[10], work[11], work[12]
    for i in range(n):
        y[i] = y0[i]
    full = False
    for j in range(channel_index.size):
        if channel_index[j] >= d.N_STATE:
            full = True
    # only the states the requested channels depend on are interpolated (u1..pU and the contact set for a force or
    # an acceleration)
    m = 0
    for i in range(N):
        used = full and (i <= d.P_UPPER or i == d.CONTACT_SET)
        for j in range(channel_index.size):
            used |= channel_index[j] == i
        if used:
            need[m] = i
            m += 1
    valve = p[d.VALVE_AREA]
    force_parameters = d.force_parameters(p)
    gravity, mass, piston_mass = p[d.GRAVITY], p[d.MASS], p[d.PISTON_MASS]
    fc = fp = ff = f_top = f_bottom = 0.0
    t = 0.0
    t_end = t_out[-1]
    i_out = 0
    while i_out < t_out.size and t_out[i_out] <= 0.0:
        d.channels(y, p, row)
        for j in range(channel_index.size):
            out[j, i_out] = row[channel_index[j]]
        i_out += 1
    d.rhs(y, p, valve, k1)
    h_abs = initial_step(p, y, k1, t_end, rtol, atol, max_step, ys, k2, work[13])
    steps = 0
    while t < t_end:
        if steps >= max_steps:
            return TOO_MANY_STEPS, steps
        min_step = 10.0 * abs(math.nextafter(t, math.inf) - t)
        if h_abs > max_step:
            h_abs = max_step
        elif h_abs < min_step:
            h_abs = min_step
        rejected = False
        while True:
            if h_abs < min_step:
                return STEP_TOO_SMALL, steps
            t_new = t + h_abs
            if t_new > t_end:
                t_new = t_end
            h = t_new - t
            h_abs = abs(h)
            for i in range(n):
                ys[i] = y[i] + h * (0.2 * k1[i])
            d.rhs(ys, p, valve, k2)
            for i in range(n):
                ys[i] = y[i] + h * (3 / 40 * k1[i] + 9 / 40 * k2[i])
            d.rhs(ys, p, valve, k3)
            for i in range(n):
                ys[i] = y[i] + h * (44 / 45 * k1[i] - 56 / 15 * k2[i] + 32 / 9 * k3[i])
            d.rhs(ys, p, valve, k4)
            for i in range(n):
                ys[i] = y[i] + h * (19372 / 6561 * k1[i] - 25360 / 2187 * k2[i] + 64448 / 6561 * k3[i]
                                    - 212 / 729 * k4[i])
            d.rhs(ys, p, valve, k5)
            for i in range(n):
                ys[i] = y[i] + h * (9017 / 3168 * k1[i] - 355 / 33 * k2[i] + 46732 / 5247 * k3[i]
                                    + 49 / 176 * k4[i] - 5103 / 18656 * k5[i])
            d.rhs(ys, p, valve, k6)
            for i in range(n):
                y_new[i] = y[i] + h * (35 / 384 * k1[i] + 500 / 1113 * k3[i] + 125 / 192 * k4[i]
                                       - 2187 / 6784 * k5[i] + 11 / 84 * k6[i])
            d.rhs(y_new, p, valve, k7)
            squares = 0.0  # RMS of the error estimate over scale = atol + rtol·max(|y|, |y_new|)
            for i in range(n):
                e = h * (-71 / 57600 * k1[i] + 71 / 16695 * k3[i] - 71 / 1920 * k4[i]
                         + 17253 / 339200 * k5[i] - 22 / 525 * k6[i] + 1 / 40 * k7[i])
                e /= atol[i] + max(abs(y[i]), abs(y_new[i])) * rtol
                squares += e * e
            error_norm = math.sqrt(squares / n)
            if error_norm < 1.0:
                # a small error norm gives MAX_FACTOR without the (costly) power
                factor = (MAX_FACTOR if error_norm < SMALL_ERROR
                          else min(MAX_FACTOR, SAFETY * error_norm**ERROR_EXPONENT))
                if rejected:
                    factor = min(1.0, factor)
                h_abs *= factor
                break
            if not math.isfinite(error_norm):
                h_abs *= MIN_FACTOR
                if h_abs < min_step:
                    return NOT_FINITE, steps
            else:
                h_abs *= max(MIN_FACTOR, SAFETY * error_norm**ERROR_EXPONENT)
            rejected = True
        # samples inside (t, t_new]: continuous extension y(t + θh) = y + h·θ·(Q0 + θ·(Q1 + θ·(Q2 + θ·Q3)))
        if i_out < t_out.size and t_out[i_out] <= t_new:
            for j in range(m):
                i = need[j]
                q1[i] = (_P[0, 1] * k1[i] + _P[2, 1] * k3[i] + _P[3, 1] * k4[i] + _P[4, 1] * k5[i]
                         + _P[5, 1] * k6[i] + _P[6, 1] * k7[i])
                q2[i] = (_P[0, 2] * k1[i] + _P[2, 2] * k3[i] + _P[3, 2] * k4[i] + _P[4, 2] * k5[i]
                         + _P[5, 2] * k6[i] + _P[6, 2] * k7[i])
                q3[i] = (_P[0, 3] * k1[i] + _P[2, 3] * k3[i] + _P[3, 3] * k4[i] + _P[4, 3] * k5[i]
                         + _P[5, 3] * k6[i] + _P[6, 3] * k7[i])
        while i_out < t_out.size and t_out[i_out] <= t_new:
            theta = (t_out[i_out] - t) / h
            for j in range(m):
                i = need[j]
                ys[i] = y[i] + h * theta * (k1[i] + theta * (q1[i] + theta * (q2[i] + theta * q3[i])))
            if full:  # scalars and a tuple only: a call, or an array handed on, costs as much as the forces
                fc, fp, ff, f_top, f_bottom = d.forces_of(ys[d.U1], ys[d.V1], ys[d.U2], ys[d.V2], ys[d.P_LOWER],
                                                          ys[d.P_UPPER], ys[d.CONTACT_SET], force_parameters)
            for j in range(channel_index.size):
                c = channel_index[j]
                out[j, i_out] = ys[c] if c < N else d.derived_value(c, gravity, mass, piston_mass, fc, fp, ff,
                                                                    f_top, f_bottom)
            i_out += 1
        t = t_new
        for i in range(n):
            y[i] = y_new[i]
            k1[i] = k7[i]
        steps += 1
    return OK, steps


@njit(cache=True, parallel=True, error_model="numpy")
def integrate_batch(params, y0, t_out, channel_index, rtol, atol, max_step, max_steps, out, status, steps):
    """Integrate every row of ``params`` in parallel; ``out`` has shape (n, len(channel_index), len(t_out))."""
    for s in prange(params.shape[0]):
        status[s], steps[s] = integrate_one(params[s], y0[s], t_out, channel_index, rtol, atol, max_step,
                                            max_steps, out[s])
