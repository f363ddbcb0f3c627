"""Right-hand side of the drop-stand model (paper eqs. 1-2) on a packed parameter vector.

State vector (indices ``U1 .. CONTACT_SET``): mass and piston displacement and velocity (axis down, both measured
from the piston's top-stop position), the pressures and gas masses of the lower and upper chambers, the energy
dissipated so far and the memory of the contact (the hysteretic law's set, the power law's turning point; see
:func:`.forces.contact_set_rate`).
Chamber pressures follow the energy balance of an adiabatic chamber, dp/dt = γ·(R·T_in·ṁ_in − R·T·ṁ_out − p·V')/V,
which reduces to dp/dt = −γ·p·V'/V for the closed cylinder.
"""

from __future__ import annotations

from numba import njit

from .forces import (
    ORIFICE,
    contact_energy,
    contact_force,
    contact_loss,
    contact_set_rate,
    friction_force,
    iso6358_mass_flow,
    orifice_mass_flow,
    pneumatic_force,
    stop_force,
)

# state indices
U1, V1, U2, V2, P_LOWER, P_UPPER, M_LOWER, M_UPPER, DISSIPATED, CONTACT_SET = range(10)
N_STATE = 10

# parameter indices
(MASS, PISTON_MASS, GRAVITY, AREA, ROD_AREA, LOWER_LENGTH, UPPER_LENGTH, DEAD_LOWER, DEAD_UPPER, STROKE,
 GAMMA, GAS_CONSTANT, ATMOSPHERE, FRICTION, FRICTION_SCALE, LAW, CONTACT_K, CONTACT_C, STOP_K, STOP_C,
 VALVE_AREA, DISCHARGE, VELOCITY, PRESSURE_GAUGE, TEMPERATURE, VALVE_MAX_AREA, VALVE_LAW, SONIC_CONDUCTANCE,
 CRITICAL_RATIO, CONTACT_N, CONTACT_M) = range(31)
N_PARAM = 31

#: channels a simulation can return, in the order of :func:`channels`
CHANNELS = ("u1", "v1", "u2", "v2", "pressure_lower", "pressure_upper", "gas_mass_lower", "gas_mass_upper",
            "dissipated_energy", "contact_set", "a1", "a2", "contact_force", "pneumatic_force", "friction_force",
            "top_stop_force", "bottom_stop_force")
N_CHANNEL = len(CHANNELS)


@njit(cache=True, inline="always", error_model="numpy")
def volumes(u2, p):
    """Lower and upper chamber volumes [m³] at piston displacement ``u2`` [m]."""
    lower = p[AREA] * (p[LOWER_LENGTH] - u2) + p[DEAD_LOWER]
    upper = (p[AREA] - p[ROD_AREA]) * (p[UPPER_LENGTH] + u2) + p[DEAD_UPPER]
    return lower, upper


@njit(cache=True, inline="always", error_model="numpy")
def force_parameters(p):
    """The parameters :func:`forces_of` depends on, as a tuple (read once, then passed by value)."""
    return (int(p[LAW]), p[CONTACT_K], p[CONTACT_C], p[AREA], p[ROD_AREA], p[ATMOSPHERE], p[FRICTION],
            p[FRICTION_SCALE], p[STOP_K], p[STOP_C], p[STROKE], p[CONTACT_N], p[CONTACT_M])


@njit(cache=True, inline="always", error_model="numpy")
def forces_of(u1, v1, u2, v2, p_lower, p_upper, contact_set, q):
    """Contact, pneumatic, friction, top-stop and bottom-stop forces [N] (signs as in :mod:`.forces`) of the
    displacements [m], velocities [m/s], chamber pressures [Pa] and contact set [m]; ``q`` from
    :func:`force_parameters`."""
    law, k, c, area, rod_area, atmosphere, friction, friction_scale, stop_k, stop_c, stroke, n, m = q
    fc = contact_force(u1 - u2, v1 - v2, contact_set, law, k, c, n, m)
    fp = pneumatic_force(p_lower, p_upper, area, rod_area, atmosphere)
    ff = friction_force(v2, friction, friction_scale)
    f_top = stop_force(-u2, -v2, stop_k, stop_c)
    f_bottom = stop_force(u2 - stroke, v2, stop_k, stop_c)
    return fc, fp, ff, f_top, f_bottom


@njit(cache=True, inline="always", error_model="numpy")
def derived_value(index, gravity, mass, piston_mass, fc, fp, ff, f_top, f_bottom):
    """Value of the channel ``CHANNELS[index]`` (index >= N_STATE) given the forces of :func:`forces_of`."""
    if index == N_STATE:  # a1
        return gravity - fc / mass
    if index == N_STATE + 1:  # a2
        return gravity + (fc - fp - ff + f_top - f_bottom) / piston_mass
    return (fc, fp, ff, f_top, f_bottom)[index - N_STATE - 2]


@njit(cache=True, error_model="numpy")
def channels(y, p, out):
    """Fill ``out`` (length N_CHANNEL) with the state and the forces and accelerations it implies."""
    for i in range(N_STATE):
        out[i] = y[i]
    fc, fp, ff, f_top, f_bottom = forces_of(y[U1], y[V1], y[U2], y[V2], y[P_LOWER], y[P_UPPER], y[CONTACT_SET],
                                         force_parameters(p))
    for i in range(N_STATE, N_CHANNEL):
        out[i] = derived_value(i, p[GRAVITY], p[MASS], p[PISTON_MASS], fc, fp, ff, f_top, f_bottom)


@njit(cache=True, inline="always", error_model="numpy")
def valve_mass_flow(p_up, t_up, p_down, valve_area, p):
    """Mass flow through valve Z [kg/s] (>= 0) at opening ``valve_area`` [m²] from the upstream gas (pressure
    [Pa], temperature [K]) to the downstream pressure [Pa], by the valve's flow law: an orifice of that area with
    the discharge coefficient, or the ISO 6358 law of the fully open valve with its sonic conductance scaled by
    ``valve_area / max_area``."""
    if p[VALVE_LAW] == ORIFICE:
        return orifice_mass_flow(p_up, t_up, p_down, valve_area, p[DISCHARGE], p[GAMMA], p[GAS_CONSTANT])
    return iso6358_mass_flow(p_up, t_up, p_down, p[SONIC_CONDUCTANCE] * valve_area / p[VALVE_MAX_AREA],
                             p[CRITICAL_RATIO])


@njit(cache=True, inline="always", error_model="numpy")
def rhs(y, p, valve_area, dy):
    """Time derivative of the state ``y`` into ``dy`` for a valve opening ``valve_area`` [m²] (inlined into each
    stage of the step: the same bits, a tenth less time per step than a call handing on three arrays)."""
    u2 = y[U2]
    v2 = y[V2]
    delta = y[U1] - u2
    delta_rate = y[V1] - v2
    law = int(p[LAW])
    # the forces of forces_of, written out: the benchmark's plain-Python model runs this function as Python
    contact_set = y[CONTACT_SET]
    fc = contact_force(delta, delta_rate, contact_set, law, p[CONTACT_K], p[CONTACT_C], p[CONTACT_N], p[CONTACT_M])
    set_rate = contact_set_rate(delta, delta_rate, contact_set, law, p[CONTACT_K], p[CONTACT_C])
    fp = pneumatic_force(y[P_LOWER], y[P_UPPER], p[AREA], p[ROD_AREA], p[ATMOSPHERE])
    ff = friction_force(v2, p[FRICTION], p[FRICTION_SCALE])
    top_pen = -u2
    bottom_pen = u2 - p[STROKE]
    f_top = stop_force(top_pen, -v2, p[STOP_K], p[STOP_C])
    f_bottom = stop_force(bottom_pen, v2, p[STOP_K], p[STOP_C])
    dy[U1] = y[V1]
    dy[V1] = p[GRAVITY] - fc / p[MASS]
    dy[U2] = v2
    dy[V2] = p[GRAVITY] + (fc - fp - ff + f_top - f_bottom) / p[PISTON_MASS]

    vol_lower, vol_upper = volumes(u2, p)
    dvol_lower = -p[AREA] * v2
    dvol_upper = (p[AREA] - p[ROD_AREA]) * v2
    gamma = p[GAMMA]
    # gas flow through the valve, positive from the lower to the upper chamber
    flow_enthalpy = 0.0  # R·T of the gas that flows, times the mass flow [W·(γ−1)/γ]
    mdot = 0.0
    if valve_area > 0.0:
        r_gas = p[GAS_CONSTANT]
        t_lower = y[P_LOWER] * vol_lower / (y[M_LOWER] * r_gas)
        t_upper = y[P_UPPER] * vol_upper / (y[M_UPPER] * r_gas)
        if y[P_LOWER] >= y[P_UPPER]:
            mdot = valve_mass_flow(y[P_LOWER], t_lower, y[P_UPPER], valve_area, p)
            flow_enthalpy = r_gas * t_lower * mdot
        else:
            mdot = -valve_mass_flow(y[P_UPPER], t_upper, y[P_LOWER], valve_area, p)
            flow_enthalpy = r_gas * t_upper * mdot
    dy[P_LOWER] = gamma * (-flow_enthalpy - y[P_LOWER] * dvol_lower) / vol_lower
    dy[P_UPPER] = gamma * (flow_enthalpy - y[P_UPPER] * dvol_upper) / vol_upper
    dy[M_LOWER] = -mdot
    dy[M_UPPER] = mdot

    # dissipated power: work of the non-conservative parts of contact, stops and friction
    power = contact_loss(delta, delta_rate, contact_set, set_rate, fc, law, p[CONTACT_K], p[CONTACT_C],
                         p[CONTACT_N], p[CONTACT_M]) + ff * v2
    if top_pen > 0.0:
        power += (f_top - p[STOP_K] * top_pen) * (-v2)
    if bottom_pen > 0.0:
        power += (f_bottom - p[STOP_K] * bottom_pen) * v2
    dy[DISSIPATED] = power
    dy[CONTACT_SET] = set_rate


@njit(cache=True, error_model="numpy")
def stored_energy(y, p):
    """Mechanical + gas energy of the state [J]: kinetic, potential (gravity, atmosphere), gas internal, elastic.

    ``stored_energy(y) + y[DISSIPATED]`` is conserved by the model.
    """
    kinetic = 0.5 * p[MASS] * y[V1] ** 2 + 0.5 * p[PISTON_MASS] * y[V2] ** 2
    potential = -p[GRAVITY] * (p[MASS] * y[U1] + p[PISTON_MASS] * y[U2]) - p[ATMOSPHERE] * p[ROD_AREA] * y[U2]
    vol_lower, vol_upper = volumes(y[U2], p)
    gas = (y[P_LOWER] * vol_lower + y[P_UPPER] * vol_upper) / (p[GAMMA] - 1.0)
    delta = y[U1] - y[U2]
    law = int(p[LAW])
    force = contact_force(delta, y[V1] - y[V2], y[CONTACT_SET], law, p[CONTACT_K], p[CONTACT_C], p[CONTACT_N],
                          p[CONTACT_M])
    elastic = contact_energy(delta, force, y[CONTACT_SET], law, p[CONTACT_K], p[CONTACT_C], p[CONTACT_M])
    top_pen = -y[U2]
    bottom_pen = y[U2] - p[STROKE]
    if top_pen > 0.0:
        elastic += 0.5 * p[STOP_K] * top_pen**2
    if bottom_pen > 0.0:
        elastic += 0.5 * p[STOP_K] * bottom_pen**2
    return kinetic, potential, gas, elastic

