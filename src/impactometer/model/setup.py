"""Packing of stand + scenario into the compiled model's parameter vector, and the initial equilibrium."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from numba import njit, prange

from ..errors import ParameterError
from ..rig import Rig, Scenario, parameter_names
from ..validation import real_array
from . import dynamics as d
from .forces import LAW_CODES, VALVE_LAWS, pneumatic_force, stop_force


def pack(rig: Rig, scenario: Scenario) -> np.ndarray:
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
    # the second contact parameter: the damping, the unloading stiffness k2 of the hysteretic law [N/m] or the
    # plastic set fraction of the power law [-]; the exponents of the power law (1 for the others, unused)
    if rig.contact.law == "hysteretic":
        p[d.CONTACT_C] = rig.contact.unloading_stiffness
    else:
        p[d.CONTACT_C] = rig.contact.set_fraction if rig.contact.law == "power" else rig.contact.damping
    p[d.CONTACT_N] = rig.contact.exponent or 1.0
    p[d.CONTACT_M] = rig.contact.unloading_exponent or 1.0
    p[d.STOP_K] = rig.stops.stiffness
    p[d.STOP_C] = rig.stops.damping
    p[d.VALVE_AREA] = rig.valve.area
    p[d.DISCHARGE] = rig.valve.discharge_coefficient
    p[d.VALVE_MAX_AREA] = rig.valve.max_area
    p[d.VALVE_LAW] = VALVE_LAWS[rig.valve.law]
    p[d.SONIC_CONDUCTANCE] = rig.valve.sonic_conductance or 0.0
    p[d.CRITICAL_RATIO] = rig.valve.critical_ratio or 0.5  # unused by the orifice law
    p[d.VELOCITY] = scenario.velocity
    p[d.PRESSURE_GAUGE] = scenario.pressure_gauge
    return p


def pack_batch(rig: Rig, mass, velocity, pressure_gauge,
               overrides: Mapping[str, object] | None = None) -> np.ndarray:
    """Parameter matrix (n, N_PARAM) for arrays of M1 [kg], V0 [m/s], p0 [Pa gauge] and stand overrides.

    ``overrides`` maps dotted stand parameter names (``"contact.stiffness"``, ``"cylinder.piston_mass"``) to
    scalars or arrays broadcast against the scenario arrays. Every row is validated like a single scenario; the
    error names the first offending row.
    """
    overrides = dict(overrides or {})
    names = parameter_names()
    for key in overrides:
        if key not in names:
            raise ParameterError(f"unknown stand parameter {key!r} in overrides; expected one of {names}")
    named = {"mass": (mass, " [kg]"), "velocity": (velocity, " [m/s]"), "pressure_gauge": (pressure_gauge, " [Pa]"),
             **{f"overrides[{key!r}]": (value, "") for key, value in overrides.items()}}
    numbers = [real_array(name, value, unit=unit) for name, (value, unit) in named.items()]
    try:
        arrays = np.broadcast_arrays(*numbers)
    except ValueError as exc:
        raise ParameterError(f"mass, velocity, pressure_gauge and overrides must broadcast together: {exc}") from None
    flat = [np.atleast_1d(a).ravel() for a in arrays]
    if flat[0].size == 0:
        raise ParameterError("mass, velocity, pressure_gauge must hold at least one scenario, got empty arrays")
    for name, values, unit, zero_ok in (("mass", flat[0], "kg", False), ("velocity", flat[1], "m/s", False),
                                        ("pressure_gauge", flat[2], "Pa", True)):
        bad = ~np.isfinite(values) | ((values < 0.0) if zero_ok else (values <= 0.0))
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise ParameterError(f"{name}[{i}] must be a finite number {'>=' if zero_ok else '>'} 0 [{unit}], "
                                 f"got {float(values[i])!r}")
    placeholder = Scenario(mass=1.0, velocity=1.0, pressure_gauge=0.0)
    rows = np.repeat(pack(rig, placeholder)[None, :], flat[0].size, axis=0)
    if overrides:  # one validated stand per distinct combination of override values
        combos, inverse = np.unique(np.column_stack(flat[3:]), axis=0, return_inverse=True)
        for j, combo in enumerate(combos):
            stand = rig.replace(**dict(zip(overrides, map(float, combo), strict=False)))
            rows[inverse.ravel() == j] = pack(stand, placeholder)
    rows[:, d.MASS], rows[:, d.VELOCITY], rows[:, d.PRESSURE_GAUGE] = flat[0], flat[1], flat[2]
    rated = _rated_pressure(rig, overrides, flat)
    over = flat[2] > rated
    if over.any():
        i = int(np.flatnonzero(over)[0])
        raise ParameterError(f"pressure_gauge[{i}] must be <= the rated {rated[i]:g} Pa of {rig.name!r}, "
                             f"got {flat[2][i]!r}")
    return rows


def _rated_pressure(rig: Rig, overrides: dict, flat: list[np.ndarray]) -> np.ndarray:
    key = "cylinder.rated_pressure_gauge"
    if key in overrides:
        return flat[3 + list(overrides).index(key)]
    return np.full(flat[0].size, rig.cylinder.rated_pressure_gauge)


@njit(cache=True, error_model="numpy")
def settled_pressures(u2, p):
    """Chamber pressures [Pa] with the piston at rest at ``u2`` [m], charged at the top stop, settled isothermally."""
    charge = p[d.ATMOSPHERE] + p[d.PRESSURE_GAUGE]
    lower0, upper0 = d.volumes(0.0, p)
    lower, upper = d.volumes(u2, p)
    return charge * lower0 / lower, charge * upper0 / upper


@njit(cache=True, error_model="numpy")
def piston_net_force(u2, p):
    """Downward force on the piston at rest at ``u2`` [m] with no contact, gas settled isothermally [N]."""
    pl, pu = settled_pressures(u2, p)
    fp = pneumatic_force(pl, pu, p[d.AREA], p[d.ROD_AREA], p[d.ATMOSPHERE])
    f_top = stop_force(-u2, 0.0, p[d.STOP_K], p[d.STOP_C])
    f_bottom = stop_force(u2 - p[d.STROKE], 0.0, p[d.STOP_K], p[d.STOP_C])
    return p[d.PISTON_MASS] * p[d.GRAVITY] - fp + f_top - f_bottom


@njit(cache=True, error_model="numpy")
def equilibrium_position(p):
    """Rest position u2 [m] of the piston (NaN when the gas cannot carry it off the bottom stop).

    The net force is monotonic in u2 (the stops and the gas spring stiffen downwards), so bisection between a point
    above the compressed top stop and the bottom of the stroke converges to the unique root, to the last bit.
    """
    low = -(10.0 * p[d.PISTON_MASS] * max(p[d.GRAVITY], 1.0) + p[d.PRESSURE_GAUGE] * p[d.AREA]) / p[d.STOP_K] - 1e-9
    high = min(p[d.STROKE], p[d.LOWER_LENGTH] + p[d.DEAD_LOWER] / p[d.AREA]) * (1.0 - 1e-9)
    if piston_net_force(high, p) > 0.0:
        return np.nan
    for _ in range(200):
        mid = 0.5 * (low + high)
        if mid <= low or mid >= high:
            break
        if piston_net_force(mid, p) > 0.0:
            low = mid
        else:
            high = mid
    return low if abs(piston_net_force(low, p)) < abs(piston_net_force(high, p)) else high


@njit(cache=True, error_model="numpy")
def contact_state(p, y):
    """``y`` := the state at first contact of packed row ``p`` (:func:`initial_state`, one row, on the calling
    thread); False, with the piston's position NaN, where the charge cannot carry the piston."""
    u2 = equilibrium_position(p)
    y[:] = 0.0
    pl, pu = settled_pressures(u2, p)
    lower0, upper0 = d.volumes(0.0, p)
    charge = p[d.ATMOSPHERE] + p[d.PRESSURE_GAUGE]
    y[d.U1] = u2
    y[d.V1] = p[d.VELOCITY]
    y[d.U2] = u2
    y[d.P_LOWER] = pl
    y[d.P_UPPER] = pu
    y[d.M_LOWER] = charge * lower0 / (p[d.GAS_CONSTANT] * p[d.TEMPERATURE])
    y[d.M_UPPER] = charge * upper0 / (p[d.GAS_CONSTANT] * p[d.TEMPERATURE])
    return not np.isnan(u2)


@njit(cache=True, parallel=True, error_model="numpy")
def _initial_states(params, out):
    for s in prange(params.shape[0]):  # ~1 µs each: millions of scenarios (a GPU batch) take seconds on one core
        contact_state(params[s], out[s])


def initial_states(params: np.ndarray) -> np.ndarray:
    """States at first contact (n, N_STATE) for parameter rows (n, N_PARAM); see :func:`initial_state`."""
    params = np.ascontiguousarray(np.atleast_2d(params), dtype=float)
    if params.ndim != 2 or params.shape[1] != d.N_PARAM:
        raise ParameterError(f"params must have shape (n, {d.N_PARAM}) (see pack/pack_batch), got {params.shape}")
    out = np.empty((params.shape[0], d.N_STATE))
    _initial_states(params, out)
    bad = np.flatnonzero(np.isnan(out[:, d.U2]))
    if bad.size:
        i = int(bad[0])
        raise ParameterError(f"pressure_gauge is too low to carry the piston: it would rest on the bottom stop; got "
                             f"{params[i, d.PRESSURE_GAUGE]!r} Pa (scenario {i}); expected a charge that holds "
                             f"the piston above the bottom of the stroke")
    return out


def initial_state(p: np.ndarray) -> np.ndarray:
    """State at first contact: mass at the rod tip moving at V0, piston at rest in static equilibrium.

    Both chambers are charged to p_atm + p0 with the piston at the top stop. The piston stays pressed against
    the top stop (slightly compressing it) when the gas force can hold it there; otherwise it settles,
    isothermally, at the gas-spring equilibrium below it.
    """
    return initial_states(p)[0]
