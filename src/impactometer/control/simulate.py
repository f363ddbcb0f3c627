"""Compiled integrator of the controlled stand: the drop-stand model plus valve Z, its actuator and a controller.

The state is the model's (``model.dynamics``) plus the actual valve opening [m²]. A digital controller runs at
every sample instant: it reads the sensors (the model's channels plus sensor noise), updates its estimates and sets
the valve command, which is held until the next sample (zero-order hold). Between samples the state is integrated
with the adaptive Dormand-Prince 5(4) pair of ``model.fast`` (same tableau), restarted at every sample because the
command jumps there. With the valve closed the right-hand side is exactly ``model.dynamics.rhs`` with a zero
opening, so the controlled model reduces to the closed cylinder.

The controller itself (strategy codes, packed parameters, the real-time law and the supervisor) is in
``control.controller``.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from numba import njit

from ..model import dynamics as d
from ..model.fast import _A, _E
from ..model.forces import orifice_mass_flow
from .controller import (
    AREA_CONSTANT,
    CLOSE_ON_STOP,
    CLOSED,
    CONSTANT,
    MASS_HAT,
    MAX_AREA,
    MAX_RATE,
    ROUTE,
    STRATEGY,
    T_START,
    TAU_FILTER,
    TIME_CONSTANT,
    VELOCITY_HAT,
    bounce_gate,
    control_vector,
    drive_vector,
    must_close,
    realtime_command,
)

VALVE = d.N_STATE  # index of the valve opening in the controlled state
FORCE_CHANNEL = d.CHANNELS.index("contact_force")
ACCELERATION_CHANNEL = d.CHANNELS.index("a2")
N_STATE = d.N_STATE + 1

# sensor rows of the noise matrix
SENSOR_FORCE, SENSOR_ACCELERATION, SENSOR_P_LOWER, SENSOR_P_UPPER, SENSOR_DISPLACEMENT = range(5)
N_SENSOR = 5
# extra output rows
EXTRA = ("valve_area", "valve_command", "target_force", "estimated_velocity",
         "estimated_piston_displacement")
N_EXTRA = len(EXTRA)

OK, STEP_TOO_SMALL, NOT_FINITE, TOO_MANY_STEPS = 0, 1, 2, 3
STATUS_TEXT = {STEP_TOO_SMALL: "step size underflow", NOT_FINITE: "non-finite state",
               TOO_MANY_STEPS: "too many steps"}


@njit(cache=True, error_model="numpy")
def controlled_rhs(y, p, command, drive, dy):
    """Time derivative of the controlled state (model state + valve opening) for a valve ``command`` [m²]."""
    area = min(max(y[VALVE], 0.0), drive[MAX_AREA])
    if drive[ROUTE] == 0.0:
        d.rhs(y, p, area, dy)
    else:  # the lower chamber vents to atmosphere: the model's closed cylinder plus an outflow
        d.rhs(y, p, 0.0, dy)
        if area > 0.0 and y[d.P_LOWER] > p[d.ATMOSPHERE]:
            vol_lower, _ = d.volumes(y[d.U2], p)
            t_lower = y[d.P_LOWER] * vol_lower / (y[d.M_LOWER] * p[d.GAS_CONSTANT])
            mdot = orifice_mass_flow(y[d.P_LOWER], t_lower, p[d.ATMOSPHERE], area, p[d.DISCHARGE], p[d.GAMMA],
                                     p[d.GAS_CONSTANT])
            dy[d.P_LOWER] -= p[d.GAMMA] * p[d.GAS_CONSTANT] * t_lower * mdot / vol_lower
            dy[d.M_LOWER] -= mdot
    rate = (command - y[VALVE]) / drive[TIME_CONSTANT]
    dy[VALVE] = max(-drive[MAX_RATE], min(drive[MAX_RATE], rate))


@njit(cache=True, error_model="numpy")
def _attempt(y, h, k, p, command, drive, rtol, atol, y_new):
    """One Dormand-Prince 5(4) step of size ``h`` from ``y`` (``k[0]`` holds f(y)); returns the error norm."""
    n = y.size
    for s in range(1, 7):
        for i in range(n):
            acc = 0.0
            for m in range(s):
                acc += _A[s, m] * k[m, i]
            y_new[i] = y[i] + h * acc
        controlled_rhs(y_new, p, command, drive, k[s])
    norm = 0.0
    for i in range(n):
        acc = 0.0
        for m in range(7):
            acc += _E[m] * k[m, i]
        e = abs(h * acc) / (atol[i] + rtol * max(abs(y[i]), abs(y_new[i])))
        norm = max(norm, e)
    return norm


@njit(cache=True, error_model="numpy")
def advance(y, p, command, drive, interval, h0, rtol, atol, k, y_new):
    """Integrate ``y`` in place over ``interval`` [s] with a held command; returns (status, next step size)."""
    t = 0.0
    h = min(h0, interval)
    controlled_rhs(y, p, command, drive, k[0])
    steps = 0
    while t < interval:
        last = t + h >= interval * (1.0 - 1e-12)
        step = interval - t if last else h
        norm = _attempt(y, step, k, p, command, drive, rtol, atol, y_new)
        if not math.isfinite(norm):
            h = 0.2 * step
        elif norm <= 1.0:
            t = interval if last else t + step
            for i in range(y.size):
                y[i] = y_new[i]
                k[0, i] = k[6, i]
            factor = 5.0 if norm == 0.0 else min(5.0, 0.9 * norm ** -0.2)
            h = step * factor if not last or factor < 1.0 else max(h, step * factor)
        else:
            h = step * max(0.2, 0.9 * norm ** -0.2)
        steps += 1
        if h < 1e-14:
            return (NOT_FINITE if not math.isfinite(norm) else STEP_TOO_SMALL), h
        if steps > 100_000:
            return TOO_MANY_STEPS, h
    return OK, h


@njit(cache=True, error_model="numpy")
def run_loop(p, y0, ctrl, drive, noise, sample_rate, rtol, atol, out, extra):
    """Closed-loop simulation sampled at ``sample_rate`` for ``out.shape[1]`` samples.

    ``noise`` (N_SENSOR, n) is added to the sensors the controller reads (contact force, piston acceleration,
    chamber pressures, piston displacement); ``out`` (N_CHANNEL, n) receives the model channels and ``extra``
    (N_EXTRA, n) the valve opening, the command, the target force and the controller's estimates: the mass
    velocity propagated from the identified V0 by the momentum balance v1 = V0 + g·t − ∫F dt / M1, and the
    filtered piston displacement. The piston velocity is the integrated piston acceleration (the piston starts at
    rest). Returns a status code and the index of the last sample written.
    """
    n = out.shape[1]
    dt = 1.0 / sample_rate
    y = np.empty(N_STATE)
    y[:d.N_STATE] = y0
    y[VALVE] = 0.0
    k = np.zeros((7, N_STATE))
    y_new = np.empty(N_STATE)
    row = np.empty(d.N_CHANNEL)
    target = np.zeros(1)
    g = p[d.GRAVITY]
    impulse = 0.0  # ∫F dt of the measured contact force
    v2 = 0.0  # piston velocity from the integrated acceleration
    u2 = y0[d.U2]  # filtered piston displacement
    f_prev = 0.0
    a_prev = 0.0
    alpha = dt / (ctrl[TAU_FILTER] + dt)
    pl_f = y0[d.P_LOWER]
    pu_f = y0[d.P_UPPER]
    latched = False
    h = dt
    for j in range(n):
        t = j * dt
        d.channels(y, p, row)
        for i in range(d.N_CHANNEL):
            out[i, j] = row[i]
        force = row[FORCE_CHANNEL] + noise[SENSOR_FORCE, j]
        accel = row[ACCELERATION_CHANNEL] + noise[SENSOR_ACCELERATION, j]
        if j > 0:
            impulse += 0.5 * (f_prev + force) * dt
            v2 += 0.5 * (a_prev + accel) * dt
        f_prev = force
        a_prev = accel
        pl_f += alpha * (y[d.P_LOWER] + noise[SENSOR_P_LOWER, j] - pl_f)
        pu_f += alpha * (y[d.P_UPPER] + noise[SENSOR_P_UPPER, j] - pu_f)
        u2 += alpha * (y[d.U2] + noise[SENSOR_DISPLACEMENT, j] - u2)
        mass = ctrl[MASS_HAT]
        velocity = ctrl[VELOCITY_HAT] + g * t - impulse / mass
        command = 0.0
        target[0] = math.nan
        strategy = int(ctrl[STRATEGY])
        if t >= ctrl[T_START] and strategy != CLOSED and not latched:
            if strategy == CONSTANT:
                if ctrl[CLOSE_ON_STOP] != 0.0 and (velocity <= 0.0 or must_close(p, ctrl, velocity, v2, u2, pl_f,
                                                                                   pu_f)):
                    latched = True
                else:
                    command = ctrl[AREA_CONSTANT]
            else:
                command = realtime_command(p, ctrl, drive, velocity, u2, pl_f, pu_f, v2, u2, target)
                command = bounce_gate(ctrl, command, velocity - v2)
        extra[0, j] = y[VALVE]
        extra[1, j] = command
        extra[2, j] = target[0]
        extra[3, j] = velocity
        extra[4, j] = u2
        if j == n - 1:
            break
        status, h = advance(y, p, command, drive, dt, h, rtol, atol, k, y_new)
        if status != OK:
            return status, j
    return OK, n - 1


def simulate_controlled(scenario, rig=None, *, control: np.ndarray | None = None, drive=None,
                        duration: float = 0.3, sample_rate: float = 50e3, sensor_noise: np.ndarray | None = None,
                        rtol: float = 1e-7):
    """Simulate one drop test with valve Z driven by a controller.

    Parameters
    ----------
    scenario : Scenario
        The impact (true M1 [kg], V0 [m/s], p0 [Pa gauge]).
    rig : Rig, optional
        The stand (default ``drop-stand``); ``rig.valve`` gives A_max and C_d (its constant ``area`` is ignored).
    control : ndarray, optional
        Packed controller parameters from :func:`control_vector` (default: valve closed throughout).
    drive : ValveDrive, optional
        Valve actuator (default ``ValveDrive()``).
    duration, sample_rate : float
        Simulated time after first contact [s] and the controller/sensor rate [Hz].
    sensor_noise : ndarray, optional
        Noise (N_SENSOR, n_samples) added to the sensors the controller reads [N, m/s², Pa, Pa, m].
    rtol : float
        Relative tolerance of the integrator.

    Returns
    -------
    (SimulationResult, dict)
        The model histories and the controller's histories (``valve_area`` [m²], ``valve_command`` [m²],
        ``target_force`` [N], ``estimated_velocity`` (mass) [m/s], ``estimated_piston_displacement`` [m]).
    """
    from ..errors import SimulationError
    from ..model.setup import initial_state, pack
    from ..model.simulate import _result, absolute_tolerance, sample_times
    from ..rig import get_rig
    from .valve import ValveDrive

    rig = get_rig(rig)
    drive = ValveDrive() if drive is None else drive
    control = control_vector() if control is None else np.asarray(control, dtype=float)
    t = sample_times(duration, sample_rate)
    p = pack(rig, scenario)
    p[d.VALVE_AREA] = 0.0
    y0 = initial_state(p)
    noise = np.zeros((N_SENSOR, t.size)) if sensor_noise is None else np.ascontiguousarray(sensor_noise, float)
    if noise.shape != (N_SENSOR, t.size):
        raise SimulationError(f"sensor_noise must have shape {(N_SENSOR, t.size)}, got {noise.shape}")
    atol = np.append(absolute_tolerance(rtol), rtol * 1e-6)
    chans = np.empty((d.N_CHANNEL, t.size))
    extra = np.empty((N_EXTRA, t.size))
    status, last = run_loop(p, y0, control, drive_vector(rig, drive), noise, float(sample_rate), rtol, atol, chans,
                            extra)
    note = {}
    if status != OK:
        if chans[d.CHANNELS.index("u2"), last] < BOTTOM_FRACTION * rig.cylinder.stroke:
            raise SimulationError(f"controlled simulation failed ({STATUS_TEXT[status]}) at t = {t[last]:.6f} s "
                                  f"for {scenario}")
        # the piston reached the bottom with the lower chamber emptied through the valve: the run ends there
        note = {"ended_at_bottom": float(t[last])}
        t, chans, extra = t[:last + 1], chans[:, :last + 1], extra[:, :last + 1]
    result = _result(t, chans, p, y0, rig, scenario, "controlled")
    return dataclasses.replace(result, extra=note), dict(zip(EXTRA, extra, strict=False))


#: a failed run whose piston is beyond this fraction of the stroke ended at the bottom stop
BOTTOM_FRACTION = 0.95
