"""The digital controller of valve Z: the force target, the valve laws and the stroke supervisor.

Compiled functions called by the closed loop of :mod:`impactometer.control.plant` at every sample, after the
estimator (:mod:`impactometer.control.estimator`) has read the sensors. Openings are fractions of the fully open
valve [-]. The actuator (dead time, first-order lag, rate limit, route) is described to the controller by the
drive vector (:func:`.state.pack_drive`), as its data sheet describes it to a designer.
"""

from __future__ import annotations

import math

from numba import njit

from ..model import dynamics
from ..model.forces import friction_force, pneumatic_force
from .state import Drive, Estimator, Settings, Strategy
from .target import stopping_force

#: the controller closes the valve when the closed gas spring can absorb less than this multiple of the energy
#: still to be absorbed within the remaining stroke
CAPACITY_MARGIN = 1.2
#: largest number of steps of the controller's prediction over the dead time
PREDICTION_STEPS = 20
#: the force target also stops the mass within this time [s], with at least this deceleration [m/s²]: a mass that
#: stage A has nearly stopped is not let creep down the stroke at its weight for seconds
STOP_TIME = 0.4
MIN_DECELERATION = 0.5
#: in stage B the force strategies close the valve for good once the mass is this slow [m/s]: the closed gas
#: spring takes the rest (a few millijoules), so the mass comes to rest instead of creeping on the smoothed friction;
#: should the gas then lift the bodies faster than this, the rebound brake vents it while they rise (the target is
#: the weight, and a rise uses no stroke)
REST_VELOCITY = 0.02


@njit(cache=True, error_model="numpy")
def closed_capacity(p, p_lower, p_upper, piston_displacement, travel):
    """Work [J] the closed cylinder absorbs while the piston moves ``travel`` [m] down from ``piston_displacement``
    with chamber pressures ``p_lower``, ``p_upper`` [Pa]: adiabatic compression of the lower chamber, minus the
    work of the expanding upper chamber and of the atmosphere on the rod, plus the friction."""
    gamma = p[dynamics.GAMMA]
    lower, upper = dynamics.volumes(piston_displacement, p)
    lower_end, upper_end = dynamics.volumes(piston_displacement + travel, p)
    if lower_end <= 0.0:
        return math.inf
    work = p_lower * lower / (gamma - 1.0) * ((lower / lower_end) ** (gamma - 1.0) - 1.0)
    work -= p_upper * upper / (gamma - 1.0) * (1.0 - (upper / upper_end) ** (gamma - 1.0))
    return work + (p[dynamics.FRICTION] - p[dynamics.ATMOSPHERE] * p[dynamics.ROD_AREA]) * travel


@njit(cache=True, error_model="numpy")
def must_close(p, ctrl, mass, velocity, piston_velocity, piston_displacement, p_lower, p_upper):
    """Supervisor of the valve strategies: True when the closed spring can no longer absorb, with margin, the
    kinetic energy of both bodies and their weight's work over the remaining usable stroke (it then also carries
    their weight at the end of the stroke, since the gas force grows along it)."""
    remaining = ctrl[Settings.USABLE_STROKE] - piston_displacement
    if remaining <= 0.0:
        return True
    needed = 0.5 * (mass * velocity * velocity + p[dynamics.PISTON_MASS] * piston_velocity * piston_velocity) \
        + (mass + p[dynamics.PISTON_MASS]) * p[dynamics.GRAVITY] * remaining
    return closed_capacity(p, p_lower, p_upper, piston_displacement, remaining) < CAPACITY_MARGIN * needed


@njit(cache=True, error_model="numpy")
def force_target(p, ctrl, mass, velocity, displacement):
    """Contact force [N] that stops the mass within the remaining usable stroke: F* = M1·(v²/(2·s_rem) + g)
    (M1·g once the mass moves up), with a deceleration of at least v/STOP_TIME and MIN_DECELERATION, at most
    ``max_force``; the ``level`` strategy's fixed level instead."""
    if int(ctrl[Settings.STRATEGY]) == Strategy.LEVEL:
        return ctrl[Settings.FORCE_LEVEL]
    remaining = ctrl[Settings.USABLE_STROKE] - displacement
    if velocity > 0.0:
        if remaining <= 0.0:
            return ctrl[Settings.MAX_FORCE]
        floor = mass * (max(velocity / STOP_TIME, MIN_DECELERATION) + p[dynamics.GRAVITY])
        stopping = stopping_force(mass, velocity, remaining, p[dynamics.GRAVITY])
        return min(max(stopping, floor), ctrl[Settings.MAX_FORCE])
    return min(mass * p[dynamics.GRAVITY], ctrl[Settings.MAX_FORCE])


@njit(cache=True, inline="always", error_model="numpy")
def lower_temperature(ctrl, p_lower, gamma):
    """Lower-chamber gas temperature [K] from the isentropic relation (exact for a chamber that only loses gas)."""
    ratio = p_lower / ctrl[Settings.PRESSURE_LOWER_START]
    return ctrl[Settings.TEMPERATURE_LOWER_START] * ratio ** ((gamma - 1.0) / gamma)


@njit(cache=True, error_model="numpy")
def needed_opening(p, ctrl, drive, fp_target, p_lower, p_upper, piston_velocity, piston_displacement):
    """Opening [-] that makes the gas force Fp relax to ``fp_target`` [N] with the time constant ``tau_control``.

    Inverts the chamber pressure balances: the rate of Fp with the valve closed, γ·v2·(pL·A²/VL + pU·A_ann²/VU),
    minus (Fp* − Fp)/τ, divided by the change of Fp per unit mass flow out of the lower chamber, is the mass flow
    needed; divided by the flow of the fully open valve at these pressures, the opening.
    """
    if p_lower <= p_upper or p_lower <= 0.0:
        return 0.0
    gamma = p[dynamics.GAMMA]
    area = p[dynamics.AREA]
    annulus = area - p[dynamics.ROD_AREA]
    vol_lower, vol_upper = dynamics.volumes(piston_displacement, p)
    vol_lower = max(vol_lower, 1e-3 * area * p[dynamics.LOWER_LENGTH])
    p_down = p[dynamics.ATMOSPHERE] if drive[Drive.ROUTE] != 0.0 else p_upper
    closed_rate = gamma * piston_velocity * (p_lower * area * area / vol_lower + p_upper * annulus * annulus
                                             / vol_upper)
    t_lower = lower_temperature(ctrl, p_lower, gamma)
    per_flow = gamma * p[dynamics.GAS_CONSTANT] * t_lower * area / vol_lower
    if drive[Drive.ROUTE] == 0.0:
        per_flow += gamma * p[dynamics.GAS_CONSTANT] * t_lower * annulus / vol_upper
    fp = pneumatic_force(p_lower, p_upper, area, p[dynamics.ROD_AREA], p[dynamics.ATMOSPHERE])
    mdot = (closed_rate - (fp_target - fp) / ctrl[Settings.TAU_CONTROL]) / per_flow
    if mdot <= 0.0:
        return 0.0
    full = dynamics.valve_mass_flow(p_lower, t_lower, p_down, p[dynamics.VALVE_MAX_AREA], p)
    if full <= 0.0:
        return 0.0
    return min(mdot / full, 1.0)


@njit(cache=True, error_model="numpy")
def bounce_gate(ctrl, command, relative_velocity):
    """Opening command [-] after the optional bounce gate of the real-time strategy.

    The net gas force Fp pushes the piston towards the mass: on the relative coordinate δ = u1 − u2 it delivers
    the power μ·Fp·δ'/M2, with μ = M1·M2/(M1 + M2). While the bodies approach each other (δ' = v1 − v2 > 0) Fp
    feeds the relative (bounce) motion; while they part it takes energy out of it. A valve can only lower Fp, so
    lowering it only while they approach dissipates bounce energy (a one-sided, semi-active damper on δ'). With
    the gate on the command is held back (valve closed) while ``relative_velocity`` = v1 − v2 [m/s] is below
    ``bounce_threshold``.
    """
    if ctrl[Settings.BOUNCE_GATE] != 0.0 and relative_velocity < ctrl[Settings.BOUNCE_THRESHOLD]:
        return 0.0
    return command


@njit(cache=True, inline="always", error_model="numpy")
def actuator_step(opening, command, dt, drive):
    """Opening [-] after ``dt`` [s] of the first-order lag with rate limit from ``opening`` under ``command``."""
    target = command + (opening - command) * math.exp(-dt / drive[Drive.TIME_CONSTANT])
    limit = drive[Drive.MAX_RATE] * dt
    return opening + max(-limit, min(limit, target - opening))


@njit(cache=True, error_model="numpy")
def predict(p, ctrl, drive, e, v, history, newest, delay, dt):
    """State after the dead time as the controller predicts it: (pL, pU, u2, opening).

    The opening follows the controller's model of the actuator through the commands already sent (``history``,
    newest at index ``newest``, ``delay`` samples of dead time); the chambers follow their balances with the
    piston moving at its estimated mean velocity ``v`` [m/s].
    """
    p_lower, p_upper, x = e[Estimator.P_LOWER_F], e[Estimator.P_UPPER_F], e[Estimator.X_HAT]
    opening = e[Estimator.OPENING_MODEL]
    if delay <= 0:
        return p_lower, p_upper, x, opening
    gamma, r_gas = p[dynamics.GAMMA], p[dynamics.GAS_CONSTANT]
    area, annulus = p[dynamics.AREA], p[dynamics.AREA] - p[dynamics.ROD_AREA]
    size = history.size
    per = max(1, (delay + PREDICTION_STEPS - 1) // PREDICTION_STEPS)
    k = 0
    while k < delay:
        m = min(per, delay - k)
        h = m * dt
        command = history[(newest - delay + 1 + k + size) % size]  # the command that acts during this step
        vol_lower, vol_upper = dynamics.volumes(x, p)
        mdot = 0.0
        t_lower = lower_temperature(ctrl, p_lower, gamma)
        if opening > 0.0:
            p_down = p[dynamics.ATMOSPHERE] if drive[Drive.ROUTE] != 0.0 else p_upper
            if p_lower > p_down:
                mdot = dynamics.valve_mass_flow(p_lower, t_lower, p_down, opening * p[dynamics.VALVE_MAX_AREA], p)
        enthalpy = r_gas * t_lower * mdot
        dp_lower = gamma * (-enthalpy + p_lower * area * v) / vol_lower
        dp_upper = -gamma * p_upper * annulus * v / vol_upper
        if drive[Drive.ROUTE] == 0.0:
            dp_upper += gamma * enthalpy / vol_upper
        p_lower = max(p_lower + h * dp_lower, 1.0)
        p_upper = max(p_upper + h * dp_upper, 1.0)
        x += v * h
        opening = actuator_step(opening, command, h, drive)
        k += m
    return p_lower, p_upper, x, opening


@njit(cache=True, error_model="numpy")
def command_of(t, dt, p, ctrl, drive, e, history, newest, delay):
    """Opening command [-] at sample time ``t`` [s] from the controller state ``e`` (after the estimator's update);
    the target force goes into ``e[TARGET]``. ``history`` holds the commands sent so far (newest at ``newest``)."""
    strategy = int(ctrl[Settings.STRATEGY])
    mass = e[Estimator.MASS]
    e[Estimator.TARGET] = math.nan
    velocity, x = e[Estimator.VELOCITY], e[Estimator.X_HAT]
    v2 = velocity if e[Estimator.STAGE_B] != 0.0 else e[Estimator.V_SLOW]  # the mean motion of the piston
    # the force strategies act as soon as they know M1 and v1
    waits = strategy in (Strategy.CONSTANT, Strategy.LEVEL)
    if not mass > 0.0 or not math.isfinite(velocity):
        return 0.0
    # the rebound brake: after the stop, the gas the stroke compressed throws the bodies back up; the force
    # strategies let it out while they rise (the stroke below is not used, so the supervisor has nothing to guard)
    braking = e[Estimator.STAGE_B] != 0.0 and strategy in (Strategy.REALTIME, Strategy.PREDICTIVE) \
        and velocity < -REST_VELOCITY
    if strategy == Strategy.CLOSED or (waits and t < ctrl[Settings.START]) \
            or (e[Estimator.LATCHED] != 0.0 and not braking):
        return 0.0
    p_lower, p_upper = e[Estimator.P_LOWER_F], e[Estimator.P_UPPER_F]
    if ctrl[Settings.SUPERVISE] != 0.0 and strategy != Strategy.LEVEL and not braking \
            and must_close(p, ctrl, mass, velocity, v2, x, p_lower, p_upper):
        return 0.0
    if strategy == Strategy.CONSTANT:
        if ctrl[Settings.CLOSE_ON_STOP] != 0.0 and velocity <= 0.0:
            e[Estimator.LATCHED] = 1.0
            return 0.0
        return ctrl[Settings.OPENING]
    if strategy != Strategy.LEVEL and e[Estimator.STAGE_B] != 0.0 and abs(velocity) < REST_VELOCITY:
        e[Estimator.LATCHED] = 1.0
        return 0.0
    target = force_target(p, ctrl, mass, velocity, x)
    e[Estimator.TARGET] = target
    fp_target = target * (mass + p[dynamics.PISTON_MASS]) / mass \
        - friction_force(velocity, p[dynamics.FRICTION], p[dynamics.FRICTION_SCALE])
    if strategy == Strategy.REALTIME:
        command = needed_opening(p, ctrl, drive, fp_target, p_lower, p_upper, v2, x)
        return bounce_gate(ctrl, command, velocity - v2)
    # predictive and level: the law on the state predicted over the dead time, with the lag compensated
    p_lower, p_upper, x, opening = predict(p, ctrl, drive, e, v2, history, newest, delay, dt)
    need = needed_opening(p, ctrl, drive, fp_target, p_lower, p_upper, v2, x)
    decay = math.exp(-ctrl[Settings.TAU_CONTROL] / drive[Drive.TIME_CONSTANT])
    return max(0.0, min(1.0, (need - opening * decay) / (1.0 - decay)))

