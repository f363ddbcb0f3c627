"""Compiled integrator of the controlled stand: the drop-stand model plus valve Z, its actuator and a controller.

The state is the model's (``model.dynamics``) plus the actual valve opening [m²]. A digital controller runs at
every sample instant: it reads the sensors (the model's channels plus sensor noise), updates its estimates and sets
the valve command, which is held until the next sample (zero-order hold). Between samples the state is integrated
with the adaptive Dormand-Prince 5(4) pair of ``model.fast`` (same tableau), restarted at every sample because the
command jumps there. With the valve closed the right-hand side is exactly ``model.dynamics.rhs`` with a zero
opening, so the controlled model reduces to the closed cylinder.

Controller codes (see ``control.strategies``): 0 closed, 1 constant opening, 2 real-time force control.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from numba import njit

from ..model import dynamics as d
from ..model.fast import _A, _E
from ..model.forces import friction_force, orifice_mass_flow

VALVE = d.N_STATE  # index of the valve opening in the controlled state
N_STATE = d.N_STATE + 1

CLOSED, CONSTANT, REALTIME = 0, 1, 2

# controller parameter indices
(STRATEGY, T_START, AREA_CONSTANT, MASS_HAT, VELOCITY_HAT, U_END, TAU_CONTROL, TAU_FILTER, P_CHARGE, T_CHARGE,
 CLOSE_ON_STOP, F_MAX) = range(12)
N_CONTROL = 12
# drive parameter indices
TIME_CONSTANT, MAX_RATE, MAX_AREA, ROUTE = range(4)
N_DRIVE = 4
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
def _pneumatic(p_lower, p_upper, p):
    return p_lower * p[d.AREA] - p_upper * (p[d.AREA] - p[d.ROD_AREA]) - p[d.ATMOSPHERE] * p[d.ROD_AREA]


#: the real-time controller closes the valve when the closed gas spring can absorb less than this multiple of the
#: energy still to be absorbed within the remaining stroke
CAPACITY_MARGIN = 1.2


@njit(cache=True, error_model="numpy")
def closed_capacity(p, p_lower, p_upper, piston_displacement, travel):
    """Work [J] the closed cylinder absorbs while the piston moves ``travel`` [m] down from ``piston_displacement``
    with chamber pressures ``p_lower``, ``p_upper`` [Pa]: adiabatic compression of the lower chamber, minus the
    work of the expanding upper chamber and of the atmosphere on the rod, plus the friction."""
    gamma = p[d.GAMMA]
    lower, upper = d.volumes(piston_displacement, p)
    lower_end, upper_end = d.volumes(piston_displacement + travel, p)
    if lower_end <= 0.0:
        return math.inf
    work = p_lower * lower / (gamma - 1.0) * ((lower / lower_end) ** (gamma - 1.0) - 1.0)
    work -= p_upper * upper / (gamma - 1.0) * (1.0 - (upper / upper_end) ** (gamma - 1.0))
    return work + (p[d.FRICTION] - p[d.ATMOSPHERE] * p[d.ROD_AREA]) * travel


@njit(cache=True, error_model="numpy")
def must_close(p, ctrl, velocity, piston_velocity, piston_displacement, p_lower, p_upper):
    """Supervisor of both valve strategies: True when the closed spring can no longer absorb, with margin, the
    kinetic energy of both bodies and their weight's work over the remaining usable stroke (it then also carries
    their weight at the end of the stroke, since the gas force grows along it)."""
    remaining = ctrl[U_END] - piston_displacement
    if remaining <= 0.0:
        return True
    mass = ctrl[MASS_HAT]
    needed = 0.5 * (mass * velocity * velocity + p[d.PISTON_MASS] * piston_velocity * piston_velocity) \
        + (mass + p[d.PISTON_MASS]) * p[d.GRAVITY] * remaining
    return closed_capacity(p, p_lower, p_upper, piston_displacement, remaining) < CAPACITY_MARGIN * needed


@njit(cache=True, error_model="numpy")
def realtime_command(p, ctrl, drive, velocity, displacement, p_lower, p_upper, piston_velocity,
                     piston_displacement, out):
    """Valve command [m²] of the real-time strategy from the controller's estimates; target force into ``out[0]``.

    ``velocity`` is the mass velocity [m/s], ``displacement`` the position the remaining stroke is measured from
    [m] (the loop passes the piston displacement: the piston is never behind the mass, so this is conservative).
    F* = M1·(v²/(2·s_remaining) + g) is the contact force that stops the mass within the remaining usable stroke;
    in sustained contact it needs the gas force Fp* = F*·(M1 + M2)/M1 − F_friction. The command inverts the
    chamber pressure balances: the mass flow that makes Fp relax to Fp* with time constant ``TAU_CONTROL``,
    divided by the orifice flow per unit area at the measured pressures.
    """
    mass = ctrl[MASS_HAT]
    g = p[d.GRAVITY]
    remaining = ctrl[U_END] - displacement
    if velocity > 0.0:
        if remaining <= 0.0:
            out[0] = ctrl[F_MAX]
            return 0.0
        target = mass * (velocity * velocity / (2.0 * remaining) + g)
    else:
        target = mass * g
    target = min(target, ctrl[F_MAX])
    out[0] = target
    fp_target = target * (mass + p[d.PISTON_MASS]) / mass - friction_force(velocity, p[d.FRICTION],
                                                                             p[d.FRICTION_SCALE])
    if p_lower <= p_upper or p_lower <= 0.0:
        return 0.0
    gamma = p[d.GAMMA]
    area = p[d.AREA]
    annulus = area - p[d.ROD_AREA]
    vol_lower, vol_upper = d.volumes(piston_displacement, p)
    vol_lower = max(vol_lower, 1e-3 * area * p[d.LOWER_LENGTH])
    if must_close(p, ctrl, velocity, piston_velocity, piston_displacement, p_lower, p_upper):
        return 0.0
    p_down = p[d.ATMOSPHERE] if drive[ROUTE] != 0.0 else p_upper
    # rate of the gas force with the valve closed, and its change per unit mass flow out of the lower chamber
    closed_rate = gamma * piston_velocity * (p_lower * area * area / vol_lower + p_upper * annulus * annulus
                                             / vol_upper)
    t_lower = ctrl[T_CHARGE] * (p_lower / ctrl[P_CHARGE]) ** ((gamma - 1.0) / gamma)  # isentropic outflow
    per_flow = gamma * p[d.GAS_CONSTANT] * t_lower * area / vol_lower
    if drive[ROUTE] == 0.0:
        per_flow += gamma * p[d.GAS_CONSTANT] * t_lower * annulus / vol_upper
    fp = _pneumatic(p_lower, p_upper, p)
    mdot = (closed_rate - (fp_target - fp) / ctrl[TAU_CONTROL]) / per_flow
    if mdot <= 0.0:
        return 0.0
    unit_flow = orifice_mass_flow(p_lower, t_lower, p_down, 1.0, p[d.DISCHARGE], gamma, p[d.GAS_CONSTANT])
    if unit_flow <= 0.0:
        return 0.0
    return min(mdot / unit_flow, drive[MAX_AREA])


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
        force = row[11] + noise[SENSOR_FORCE, j]
        accel = row[10] + noise[SENSOR_ACCELERATION, j]
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


def drive_vector(rig, drive) -> np.ndarray:
    """Packed drive parameters of the compiled loop for ``drive`` (a ValveDrive) on ``rig``."""
    from .valve import ROUTES

    out = np.empty(N_DRIVE)
    out[TIME_CONSTANT] = drive.time_constant
    out[MAX_RATE] = drive.max_rate
    out[MAX_AREA] = rig.valve.max_area
    out[ROUTE] = ROUTES[drive.route]
    return out


def control_vector(*, strategy: int = CLOSED, start: float = math.inf, area: float = 0.0, mass: float = 1.0,
                   velocity: float = 0.0, usable_stroke: float = 0.0, tau_control: float = 2e-3,
                   tau_filter: float = 5e-4, charge_pressure: float = 1e5, charge_temperature: float = 293.15,
                   close_on_stop: bool = True, max_force: float = math.inf) -> np.ndarray:
    """Packed controller parameters of the compiled loop (see the module constants)."""
    out = np.empty(N_CONTROL)
    out[STRATEGY] = strategy
    out[T_START] = start
    out[AREA_CONSTANT] = area
    out[MASS_HAT] = mass
    out[VELOCITY_HAT] = velocity
    out[U_END] = usable_stroke
    out[TAU_CONTROL] = tau_control
    out[TAU_FILTER] = tau_filter
    out[P_CHARGE] = charge_pressure
    out[T_CHARGE] = charge_temperature
    out[CLOSE_ON_STOP] = 1.0 if close_on_stop else 0.0
    out[F_MAX] = max_force
    return out


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
    return dataclasses.replace(result, extra=note), dict(zip(EXTRA, extra))


#: a failed run whose piston is beyond this fraction of the stroke ended at the bottom stop
BOTTOM_FRACTION = 0.95
