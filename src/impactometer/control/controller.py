"""The digital controller of valve Z: packed parameters, the real-time force law and the stroke supervisor.

Compiled functions called by the closed loop of :mod:`impactometer.control.simulate` at every sample; the
strategies (:mod:`impactometer.control.strategies`) fill the packed parameter vectors.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..model import dynamics as d
from ..model.forces import friction_force, orifice_mass_flow

CLOSED, CONSTANT, REALTIME = 0, 1, 2

# controller parameter indices
(STRATEGY, T_START, AREA_CONSTANT, MASS_HAT, VELOCITY_HAT, U_END, TAU_CONTROL, TAU_FILTER, P_CHARGE, T_CHARGE,
 CLOSE_ON_STOP, F_MAX, BOUNCE_GATE, BOUNCE_THRESHOLD) = range(14)
N_CONTROL = 14
# drive parameter indices
TIME_CONSTANT, MAX_RATE, MAX_AREA, ROUTE = range(4)
N_DRIVE = 4


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
def bounce_gate(ctrl, command, relative_velocity):
    """Valve command [m²] after the optional bounce gate of the real-time strategy.

    The net gas force Fp pushes the piston towards the mass: on the relative coordinate δ = u1 − u2 (the contact
    compression, or minus the gap) it delivers the power μ·Fp·δ'/M2, with μ = M1·M2/(M1 + M2). While the bodies
    approach each other (δ' = v1 − v2 > 0: closing the gap or compressing the contact) Fp feeds the relative
    (bounce) motion; while they part it takes energy out of it. A valve can only lower Fp, so lowering it only
    while they approach dissipates bounce energy (a one-sided, semi-active damper on δ'). With the gate on
    (``BOUNCE_GATE``) the force-law command is held back (valve closed) while ``relative_velocity`` =
    v1 − v2 [m/s] is below ``BOUNCE_THRESHOLD``.
    """
    if ctrl[BOUNCE_GATE] != 0.0 and relative_velocity < ctrl[BOUNCE_THRESHOLD]:
        return 0.0
    return command


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
                   close_on_stop: bool = True, max_force: float = math.inf, bounce_gate: bool = False,
                   bounce_threshold: float = 0.0) -> np.ndarray:
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
    out[BOUNCE_GATE] = 1.0 if bounce_gate else 0.0
    out[BOUNCE_THRESHOLD] = bounce_threshold
    return out
