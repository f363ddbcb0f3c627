"""Fast batch integrator: adaptive Dormand-Prince 5(4) compiled with numba, parallel over scenarios.

Each scenario is integrated with its own step size by the package's one Dormand-Prince step and step controller
(:mod:`.stepper`, scipy's ``solve_ivp(method="RK45")`` algorithm step for step); histories are written at the
requested sample times through the method's 4th-order continuous extension (scipy's ``RkDenseOutput``).
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from . import dynamics as d
from . import stepper
from .forces import KELVIN_VOIGT

OK = stepper.OK
STATUS_TEXT = stepper.STATUS_TEXT
N = d.N_STATE  # loops over a compile-time state size
_P = stepper.DENSE  # a module-level constant: the compiler folds its entries
#: rows of the scratch array of :func:`integrate_into`: the step's work rows (stages, new state, stage state, the
#: last also the interpolated state), then the state, the interpolant's coefficients and the tolerance scale
STATE, Q1, Q2, Q3, SCALE = range(stepper.WORK_ROWS, stepper.WORK_ROWS + 5)
WORK_ROWS = stepper.WORK_ROWS + 5


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
    (N_CHANNEL,) float64 array; their contents on entry do not matter. An ``out`` with fewer columns than
    ``t_out`` is filled at the first instants only, and the integration stops once it is: the steps up to then are
    those to ``t_out[-1]`` (a causal filter reads none of the instants after its last output).
    """
    n = N  # compile-time size: the loops are unrolled
    k = work  # its first stepper.WORK_ROWS rows are the step's work array
    y, ys, q1, q2, q3 = work[STATE], work[stepper.STAGE_STATE], work[Q1], work[Q2], work[Q3]
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
    force_parameters = d.force_parameters(p)
    gravity, mass, piston_mass = p[d.GRAVITY], p[d.MASS], p[d.PISTON_MASS]
    # a contact whose force jumps where it closes (a Kelvin-Voigt pad's c·δ', a damped stop's c·v2): the jump is
    # spread over the samples around it (:func:`share_jump`), so that they move with the closing instant rather
    # than in steps of the grid; the closings at the last sample (the pad's is 0 at first contact, t = 0)
    gap_pad, gap_top, gap_bottom = closings(y, force_parameters)
    fc = fp = ff = f_top = f_bottom = 0.0
    t = 0.0
    t_end = t_out[-1]
    size = min(t_out.size, out.shape[1])  # the instants written
    i_out = 0
    while i_out < size and t_out[i_out] <= 0.0:
        d.channels(y, p, row)
        for j in range(channel_index.size):
            out[j, i_out] = row[channel_index[j]]
        i_out += 1
    stepper.evaluate(stepper.PLAIN, y, p, row, k[0])  # the plain system has no inputs: any array will do
    h_abs = stepper.initial_step(stepper.PLAIN, p, row, y, k[0], t_end, rtol, atol, max_step, ys, k[1],
                                 work[SCALE])
    steps = 0
    while t < t_end and i_out < size:
        if steps >= max_steps:
            return stepper.TOO_MANY_STEPS, steps
        status, t_new, h_abs = stepper.step(stepper.PLAIN, y, t, t_end, h_abs, p, row, rtol, atol, max_step, k)
        if status != OK:
            return status, steps
        h = t_new - t
        # samples inside (t, t_new]: continuous extension y(t + θh) = y + h·θ·(Q0 + θ·(Q1 + θ·(Q2 + θ·Q3))), the
        # stage state's row reused for the interpolated state
        if i_out < size and t_out[i_out] <= t_new:
            for j in range(m):
                i = need[j]
                q1[i] = (_P[0, 1] * k[0, i] + _P[2, 1] * k[2, i] + _P[3, 1] * k[3, i] + _P[4, 1] * k[4, i]
                         + _P[5, 1] * k[5, i] + _P[6, 1] * k[6, i])
                q2[i] = (_P[0, 2] * k[0, i] + _P[2, 2] * k[2, i] + _P[3, 2] * k[3, i] + _P[4, 2] * k[4, i]
                         + _P[5, 2] * k[5, i] + _P[6, 2] * k[6, i])
                q3[i] = (_P[0, 3] * k[0, i] + _P[2, 3] * k[2, i] + _P[3, 3] * k[3, i] + _P[4, 3] * k[4, i]
                         + _P[5, 3] * k[5, i] + _P[6, 3] * k[6, i])
        while i_out < size and t_out[i_out] <= t_new:
            theta = (t_out[i_out] - t) / h
            for j in range(m):
                i = need[j]
                ys[i] = y[i] + h * theta * (k[0, i] + theta * (q1[i] + theta * (q2[i] + theta * q3[i])))
            if full:  # scalars and a tuple only: a call, or an array handed on, costs as much as the forces
                fc, fp, ff, f_top, f_bottom = d.forces_of(ys[d.U1], ys[d.V1], ys[d.U2], ys[d.V2], ys[d.P_LOWER],
                                                          ys[d.P_UPPER], ys[d.CONTACT_SET], force_parameters)
            for j in range(channel_index.size):
                c = channel_index[j]
                out[j, i_out] = ys[c] if c < N else d.derived_value(c, gravity, mass, piston_mass, fc, fp, ff,
                                                                    f_top, f_bottom)
            if full:  # jumps of contacts that closed since the last sample spread: spread_closings written out
                after_pad, after_top, after_bottom = closings(ys, force_parameters)
                if i_out > 0:
                    if gap_pad <= 0.0 < after_pad:
                        share_jump(out, channel_index, i_out, t_out[i_out - 1], t_out[i_out], gap_pad, after_pad)
                    if gap_top <= 0.0 < after_top:
                        share_jump(out, channel_index, i_out, t_out[i_out - 1], t_out[i_out], gap_top, after_top)
                    if gap_bottom <= 0.0 < after_bottom:
                        share_jump(out, channel_index, i_out, t_out[i_out - 1], t_out[i_out], gap_bottom,
                                   after_bottom)
                gap_pad, gap_top, gap_bottom = after_pad, after_top, after_bottom
            i_out += 1
        t = t_new
        stepper.accept(y, k)
        steps += 1
    return OK, steps


@njit(cache=True, inline="always", error_model="numpy")
def closings(y, q):
    """Compression [m] of each contact whose force jumps where it closes, at state ``y`` (``q`` from
    :func:`.dynamics.force_parameters`): the pad under a Kelvin-Voigt law, the top and the bottom stop where
    they are damped; −1 for one that does not jump (the others' forces start from zero)."""
    law, stop_c, stroke = q[0], q[9], q[10]
    pad = y[d.U1] - y[d.U2] if law == KELVIN_VOIGT else -1.0
    if stop_c <= 0.0:
        return pad, -1.0, -1.0
    return pad, -y[d.U2], y[d.U2] - stroke


@njit(cache=True, inline="always", error_model="numpy")
def spread_closings(out, channel_index, i_out, t_out, pad, top, bottom, y, q):
    """The closings (:func:`closings`) at sample ``i_out`` of state ``y``; each contact that closed since the sample
    before (its compression there, ``pad``, ``top`` or ``bottom``, <= 0, now > 0) has its jump spread over the two
    (:func:`share_jump`). Returns the closings, those before the next sample.

    :func:`integrate_into` has these lines written out in its loop: called there (inlined or not), the function
    cost as much as the rest of a sample's output, the integration twice the time.
    """
    after_pad, after_top, after_bottom = closings(y, q)
    if i_out > 0:
        if pad <= 0.0 < after_pad:
            share_jump(out, channel_index, i_out, t_out[i_out - 1], t_out[i_out], pad, after_pad)
        if top <= 0.0 < after_top:
            share_jump(out, channel_index, i_out, t_out[i_out - 1], t_out[i_out], top, after_top)
        if bottom <= 0.0 < after_bottom:
            share_jump(out, channel_index, i_out, t_out[i_out - 1], t_out[i_out], bottom, after_bottom)
    return after_pad, after_top, after_bottom


@njit(cache=True, inline="always", error_model="numpy")
def share_jump(out, channel_index, i_out, t_before, t_after, gap_before, gap_after):
    """Spread a jump at a contact closing over the samples whose intervals hold it, each sample standing for the
    interval of one sample period centred on it (a box): the sample before the closing (at ``t_before`` [s],
    compression ``gap_before`` <= 0 [m]) and the one after it (``t_after``, ``gap_after`` > 0) of the derived
    channels (forces, accelerations; the states are continuous) take the share of their box that lies after the
    closing, the jump being the change from one to the other.

    The closing instant is where the compression, linear over the interval, crosses zero; first contact is at
    t = 0 (the samples at t <= 0 hold the state at contact). Point samples would move only when the closing
    crosses a sample instant: a prediction in steps of the grid, whose finite differences in the parameters miss
    how the closing instant trades against them (a Fisher information several times too large). Spread, the
    samples are continuous in the closing instant, and their trapezoidal integral is the jump's impulse.
    """
    period = t_after - t_before
    closing = 0.0 if t_before <= 0.0 else t_before + period * (-gap_before) / (gap_after - gap_before)
    before = min(max((closing - t_before) / period, 0.0), 1.0)  # where the closing falls in the interval [-]
    for j in range(channel_index.size):
        if channel_index[j] >= N:
            jump = out[j, i_out] - out[j, i_out - 1]
            if before < 0.5:  # in the box of the sample before
                out[j, i_out - 1] += (0.5 - before) * jump
            else:  # in the box of the sample after
                out[j, i_out] = out[j, i_out - 1] + (1.5 - before) * jump


@njit(cache=True, parallel=True, error_model="numpy")
def integrate_batch(params, y0, t_out, channel_index, rtol, atol, max_step, max_steps, out, status, steps):
    """Integrate every row of ``params`` in parallel; ``out`` has shape (n, len(channel_index), len(t_out))."""
    for s in prange(params.shape[0]):
        status[s], steps[s] = integrate_one(params[s], y0[s], t_out, channel_index, rtol, atol, max_step,
                                            max_steps, out[s])
