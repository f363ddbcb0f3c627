"""Reference integrator (scipy ``solve_ivp`` with tight tolerances) and the check of the fast one against it."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit
from scipy.integrate import solve_ivp

from ..errors import ParameterError, SimulationError
from . import dynamics as d
from .fast import spread_closings

#: right-hand-side evaluations per step of each ``solve_ivp`` method, for the step budget
_EVALUATIONS_PER_STEP = {"RK45": 6, "DOP853": 12, "RK23": 3}


def integrate(p: np.ndarray, y0: np.ndarray, t_out: np.ndarray, *, rtol: float = 1e-10,
              atol: np.ndarray, method: str = "DOP853", max_step: float = np.inf,
              max_steps: int | None = None) -> np.ndarray:
    """States at ``t_out`` (shape (N_STATE, len(t_out))) integrated by ``solve_ivp``.

    Parameters
    ----------
    p, y0 : ndarray
        Packed parameters and initial state (see :mod:`.setup`).
    t_out : ndarray
        Sample instants [s], starting at 0.
    rtol, atol : float, ndarray
        Relative and per-state absolute tolerances.
    method : {"DOP853", "RK45", "RK23"}
        ``solve_ivp`` method.
    max_step : float
        Largest step [s].
    max_steps : int, optional
        Budget of steps (counted as right-hand-side evaluations / evaluations per step, rejected steps included).

    Raises
    ------
    SimulationError
        If the solver does not reach the end time or exceeds ``max_steps``; no partial result is returned.
    """
    if method not in _EVALUATIONS_PER_STEP:
        raise ParameterError(f"method must be one of {sorted(_EVALUATIONS_PER_STEP)}, got {method!r}")
    valve = float(p[d.VALVE_AREA])
    budget = np.inf if max_steps is None else (max_steps + 1) * _EVALUATIONS_PER_STEP[method] + 2
    calls = [0]

    def fun(_t, y):
        calls[0] += 1
        if calls[0] > budget:
            raise SimulationError(f"reference integrator ({method}) failed: more than {max_steps} steps")
        dy = np.empty_like(y)
        d.rhs(y, p, valve, dy)
        return dy

    sol = solve_ivp(fun, (0.0, float(t_out[-1])), y0, method=method, t_eval=t_out, rtol=rtol, atol=atol,
                    max_step=max_step)
    if sol.status != 0 or sol.y.shape[1] != t_out.size or not np.all(np.isfinite(sol.y)):
        raise SimulationError(f"reference integrator ({method}) failed: {sol.message}")
    return sol.y


@njit(cache=True, error_model="numpy")
def _channels_of(states, p, time, out):
    row = np.empty(d.N_CHANNEL)
    y = np.empty(d.N_STATE)
    every = np.arange(d.N_CHANNEL)
    q = d.force_parameters(p)
    pad = top = bottom = -1.0
    for i in range(states.shape[1]):
        for j in range(d.N_STATE):
            y[j] = states[j, i]
        d.channels(y, p, row)
        for j in range(d.N_CHANNEL):
            out[j, i] = row[j]
        # jumps spread as the fast integrator spreads them
        pad, top, bottom = spread_closings(out, every, i, time, pad, top, bottom, y, q)


def channels_of(states: np.ndarray, p: np.ndarray, time: np.ndarray) -> np.ndarray:
    """Every channel (shape (N_CHANNEL, n)) for states of shape (N_STATE, n) at ``time`` (n,) [s] after first
    contact; a jump where a contact closes is spread over the samples around it as :func:`.fast.share_jump`
    spreads it, so that both integrators sample the same way."""
    out = np.empty((d.N_CHANNEL, states.shape[1]))
    _channels_of(np.ascontiguousarray(states, dtype=float), p, np.ascontiguousarray(time, dtype=float), out)
    return out


def pulse_peaks(time: np.ndarray, force: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Peak times [s] and peak forces [N] of every contact pulse of a sampled force.

    A pulse is a run of force above 1e-6 of the largest force: below that a "pulse" is the rounding of the
    integrator (a hysteretic contact whose set follows the receding body can touch at 1e-4 N). The peak time is
    refined by the parabola through the largest sample of the pulse and its two neighbours; a pulse whose largest
    sample is at its edge keeps that sample's time.
    """
    time, force = np.asarray(time, dtype=float), np.asarray(force, dtype=float)
    if time.ndim != 1 or time.shape != force.shape or time.size < 3:
        raise ParameterError(f"time and force must be 1-D arrays of equal length >= 3, got shapes {time.shape} "
                             f"and {force.shape}")
    above = np.concatenate(([False], force > 1e-6 * max(float(force.max()), 0.0), [False]))
    edges = np.flatnonzero(np.diff(above.astype(np.int8)))
    times, peaks = [], []
    for start, stop in zip(edges[::2], edges[1::2], strict=False):
        i = start + int(np.argmax(force[start:stop]))
        t_peak = time[i]
        if start < i < stop - 1:
            f0, f1, f2 = force[i - 1], force[i], force[i + 1]
            curvature = f0 - 2.0 * f1 + f2
            if curvature < 0.0:
                t_peak = time[i] + 0.5 * (f0 - f2) / curvature * (time[1] - time[0])
        times.append(t_peak)
        peaks.append(force[i])
    return np.array(times), np.array(peaks)


@dataclass(frozen=True, kw_only=True)
class Agreement:
    """Largest fast-vs-reference differences over a set of scenarios.

    ``peak_force`` and ``impulse`` are relative to the reference [-]; ``peak_time`` is the largest difference of
    the refined time of any contact-pulse peak [s]; ``pulse_count_mismatches`` counts scenarios whose records have
    different numbers of contact pulses (their peak times are not compared).
    """

    scenarios: int
    peak_force: float
    impulse: float
    peak_time: float
    pulse_count_mismatches: int
    pulses: int


def agreement(fast_force: np.ndarray, reference_force: np.ndarray, time: np.ndarray) -> Agreement:
    """Compare contact-force histories (n, samples) of the fast and the reference integrator on ``time`` [s]."""
    fast_force = np.atleast_2d(fast_force)
    reference_force = np.atleast_2d(reference_force)
    if fast_force.shape != reference_force.shape or fast_force.shape[1] != time.size:
        raise ParameterError(f"force histories must have equal shapes (n, {time.size}), got {fast_force.shape} and "
                             f"{reference_force.shape}")
    peak = np.abs(fast_force.max(axis=1) / reference_force.max(axis=1) - 1.0)
    impulse = np.abs(np.trapezoid(fast_force, time, axis=1) / np.trapezoid(reference_force, time, axis=1) - 1.0)
    worst_time, mismatches, pulses = 0.0, 0, 0
    for fast_row, ref_row in zip(fast_force, reference_force, strict=False):
        t_fast, _ = pulse_peaks(time, fast_row)
        t_ref, _ = pulse_peaks(time, ref_row)
        if t_fast.size != t_ref.size:
            mismatches += 1
            continue
        pulses += t_ref.size
        if t_ref.size:
            worst_time = max(worst_time, float(np.abs(t_fast - t_ref).max()))
    return Agreement(scenarios=fast_force.shape[0], peak_force=float(peak.max()), impulse=float(impulse.max()),
                     peak_time=worst_time, pulse_count_mismatches=mismatches, pulses=pulses)
