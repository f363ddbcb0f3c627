"""Packing of stand + scenario into the compiled model's parameter vector, and the initial equilibrium."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from scipy.optimize import brentq

from .. import rig as rigmod
from ..errors import ParameterError
from . import dynamics as d
from .forces import LAW_CODES, pneumatic_force, stop_force


def pack(rig: rigmod.Rig, scenario: rigmod.Scenario) -> np.ndarray:
    """Parameter vector of the compiled model for one scenario on ``rig``."""
    scenario.check_against(rig)
    c, g = rig.cylinder, rig.gas
    p = np.empty(d.N_PARAM)
    p[d.MASS] = scenario.mass
    p[d.PISTON_MASS] = c.piston_mass
    p[d.GRAVITY] = rig.gravity
    p[d.AREA] = c.area
    p[d.ROD_AREA] = c.rod_area
    p[d.LOWER_LENGTH] = c.lower_length
    p[d.UPPER_LENGTH] = c.upper_length
    p[d.DEAD_LOWER] = c.dead_volume_lower
    p[d.DEAD_UPPER] = c.dead_volume_upper
    p[d.STROKE] = c.stroke
    p[d.GAMMA] = g.gamma
    p[d.GAS_CONSTANT] = g.gas_constant
    p[d.ATMOSPHERE] = g.atmospheric_pressure
    p[d.TEMPERATURE] = g.temperature
    p[d.FRICTION] = rig.friction.force
    p[d.FRICTION_SCALE] = rig.friction.velocity_scale
    p[d.LAW] = LAW_CODES[rig.contact.law]
    p[d.CONTACT_K] = rig.contact.stiffness
    p[d.CONTACT_C] = rig.contact.damping
    p[d.STOP_K] = rig.stops.stiffness
    p[d.STOP_C] = rig.stops.damping
    p[d.VALVE_AREA] = rig.valve.area
    p[d.DISCHARGE] = rig.valve.discharge_coefficient
    p[d.VELOCITY] = scenario.velocity
    p[d.PRESSURE_GAUGE] = scenario.pressure_gauge
    return p


def pack_batch(rig: rigmod.Rig, mass, velocity, pressure_gauge,
               overrides: Mapping[str, object] | None = None) -> np.ndarray:
    """Parameter matrix (n, N_PARAM) for arrays of M1 [kg], V0 [m/s], p0 [Pa gauge] and stand overrides.

    ``overrides`` maps dotted stand parameter names (``"contact.stiffness"``, ``"cylinder.piston_mass"``) to
    scalars or arrays broadcast against the scenario arrays. Every row is validated like a single scenario.
    """
    overrides = dict(overrides or {})
    names = rigmod.parameter_names()
    for key in overrides:
        if key not in names:
            raise ParameterError(f"unknown stand parameter {key!r} in overrides; expected one of {names}")
    try:
        arrays = np.broadcast_arrays(*(np.asarray(a, dtype=float) for a in
                                       (mass, velocity, pressure_gauge, *overrides.values())))
    except ValueError as exc:
        raise ParameterError(f"mass, velocity, pressure_gauge and overrides must broadcast together: {exc}") from None
    except TypeError:
        raise ParameterError("mass, velocity, pressure_gauge and overrides must be numbers or numeric arrays") from None
    flat = [np.atleast_1d(a).ravel() for a in arrays]
    rows = np.empty((flat[0].size, d.N_PARAM))
    cache: dict[tuple, rigmod.Rig] = {}
    for i in range(flat[0].size):
        key = tuple(float(a[i]) for a in flat[3:])
        if key not in cache:
            cache[key] = rig.replace(**dict(zip(overrides, key))) if overrides else rig
        scenario = rigmod.Scenario(mass=float(flat[0][i]), velocity=float(flat[1][i]),
                                   pressure_gauge=float(flat[2][i]))
        rows[i] = pack(cache[key], scenario)
    return rows


def piston_net_force(u2: float, p: np.ndarray) -> float:
    """Downward force on the piston at rest at ``u2`` [m] with no contact, gas settled isothermally [N]."""
    pl, pu = _settled_pressures(u2, p)
    fp = pneumatic_force(pl, pu, p[d.AREA], p[d.ROD_AREA], p[d.ATMOSPHERE])
    f_top = stop_force(-u2, 0.0, p[d.STOP_K], p[d.STOP_C])
    f_bottom = stop_force(u2 - p[d.STROKE], 0.0, p[d.STOP_K], p[d.STOP_C])
    return p[d.PISTON_MASS] * p[d.GRAVITY] - fp + f_top - f_bottom


def _settled_pressures(u2: float, p: np.ndarray) -> tuple[float, float]:
    charge = p[d.ATMOSPHERE] + p[d.PRESSURE_GAUGE]
    lower0, upper0 = d.volumes(0.0, p)
    lower, upper = d.volumes(u2, p)
    return charge * lower0 / lower, charge * upper0 / upper


def initial_state(p: np.ndarray) -> np.ndarray:
    """State at first contact: mass at the rod tip moving at V0, piston at rest in static equilibrium.

    Both chambers are charged to p_atm + p0 with the piston at the top stop. The piston stays pressed against
    the top stop (slightly compressing it) when the gas force can hold it there; otherwise it settles,
    isothermally, at the gas-spring equilibrium below it.
    """
    lowest = min(p[d.STROKE], p[d.LOWER_LENGTH] + p[d.DEAD_LOWER] / p[d.AREA]) * (1.0 - 1e-9)
    highest = -10.0 * p[d.PISTON_MASS] * max(p[d.GRAVITY], 1.0) / p[d.STOP_K] - 1e-9 \
        - p[d.PRESSURE_GAUGE] * p[d.AREA] / p[d.STOP_K]
    if piston_net_force(lowest, p) > 0.0:
        raise ParameterError("pressure_gauge is too low to carry the piston: it would rest on the bottom stop; "
                             f"got {p[d.PRESSURE_GAUGE]!r} Pa")
    u2 = brentq(piston_net_force, highest, lowest, args=(p,), xtol=1e-16, rtol=1e-15, maxiter=500)
    pl, pu = _settled_pressures(u2, p)
    lower0, upper0 = d.volumes(0.0, p)
    charge = p[d.ATMOSPHERE] + p[d.PRESSURE_GAUGE]
    y = d.empty_state()
    y[d.U1] = u2
    y[d.V1] = p[d.VELOCITY]
    y[d.U2] = u2
    y[d.P_LOWER] = pl
    y[d.P_UPPER] = pu
    y[d.M_LOWER] = charge * lower0 / (p[d.GAS_CONSTANT] * p[d.TEMPERATURE])
    y[d.M_UPPER] = charge * upper0 / (p[d.GAS_CONSTANT] * p[d.TEMPERATURE])
    return y
