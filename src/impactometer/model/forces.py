"""Force laws of the drop-stand model (paper eqs. 1-2), as compiled scalar functions.

Sign convention: the axis points down; a positive contact force pushes the mass up and the rod down; the
pneumatic force Fp and the friction act upward on the piston for positive values; the top stop pushes down, the
bottom stop pushes up.
"""

from __future__ import annotations

import math

from numba import njit

KELVIN_VOIGT = 0
HUNT_CROSSLEY = 1
HYSTERETIC = 2
POWER = 3
#: contact law name -> code used by the compiled model
LAW_CODES = {"kelvin-voigt": KELVIN_VOIGT, "hunt-crossley": HUNT_CROSSLEY, "hysteretic": HYSTERETIC, "power": POWER}
#: flow laws of valve Z: name -> code used by the compiled model
ORIFICE, ISO6358 = 0, 1
VALVE_LAWS = {"orifice": ORIFICE, "iso6358": ISO6358}
#: ISO 6358-1 reference conditions of the sonic conductance: density [kg/m³] and temperature [K] of air
ISO_REFERENCE_DENSITY = 1.185
ISO_REFERENCE_TEMPERATURE = 293.15
#: compression at which the power law's stiffness is its secant stiffness [m]: F = k·δr·(δ/δr)^n, so that k [N/m]
#: means the same for every exponent n and a fit tells it apart from n (pads are compressed by millimetres)
REFERENCE_COMPRESSION = 0.01
#: |x| from which math.tanh(x) is exactly ±1 in double precision (true from 19.06 on)
TANH_SATURATION = 20.0


@njit(cache=True, inline="always", error_model="numpy")
def contact_force(delta, delta_rate, contact_set, law, stiffness, damping, exponent, unloading_exponent):
    """Compressive-only contact force [N] for compression ``delta`` [m], its rate [m/s] and the contact's memory.

    Kelvin-Voigt: k·δ + c·δ'; Hunt-Crossley: k·δ^1.5·(1 + 1.5·α·δ') with ``damping`` = α [s/m];
    hysteretic (Walton-Braun): min(k1·δ, k2·(δ − s)) with ``stiffness`` = k1, ``damping`` = k2 [N/m] and the
    contact's memory ``contact_set`` = s [m] (see :func:`contact_set_rate`); power (Masing-type, plastic set):
    k·δr·(δ/δr)^n while δ >= δmax, else F_max·((δ − s)/(δmax − s))^m with F_max the loading force at δmax and
    s = φ·δmax, where ``stiffness`` = k [N/m] (the secant stiffness at δr = ``REFERENCE_COMPRESSION``),
    ``damping`` = φ [-], ``exponent`` = n, ``unloading_exponent`` = m and the memory ``contact_set`` = δmax [m],
    the turning point; the other laws ignore the memory and the exponents.
    Zero when the bodies are apart (δ <= 0, or δ <= s) and never negative (no adhesion).
    """
    if delta <= 0.0:
        return 0.0
    if law == POWER:
        scale = stiffness * REFERENCE_COMPRESSION
        if delta >= contact_set:
            return scale * (delta / REFERENCE_COMPRESSION) ** exponent
        plastic_set = damping * contact_set
        if delta <= plastic_set:
            return 0.0
        return scale * (contact_set / REFERENCE_COMPRESSION) ** exponent \
            * ((delta - plastic_set) / (contact_set - plastic_set)) ** unloading_exponent
    if law == HYSTERETIC:
        force = min(stiffness * delta, damping * (delta - contact_set))
    elif law == HUNT_CROSSLEY:
        force = stiffness * delta * math.sqrt(delta) * (1.0 + 1.5 * damping * delta_rate)
    else:
        force = stiffness * delta + damping * delta_rate
    return force if force > 0.0 else 0.0


@njit(cache=True, inline="always", error_model="numpy")
def contact_set_rate(delta, delta_rate, contact_set, law, stiffness, damping):
    """Rate of the contact's memory [m/s]: the hysteretic law's set s, the power law's turning point δmax (zero
    for the other laws).

    Hysteretic: the set is the compression at which the unloading line F = k2·(δ − s) reaches zero force. While
    the contact is compressed further (δ' > 0) the set grows as (1 − k1/k2)·r²·δ', with r = F/(k1·δ) the force
    relative to the loading line: on the loading line (r = 1) this keeps F = k1·δ exactly, and on a reloading line
    (r < 1) the force bends smoothly back onto the loading line instead of meeting it at a corner (a Masing-type
    minor loop: every closed load cycle dissipates energy). While the contact unloads the set is frozen, so the
    force follows the stiffer unloading line; once the force is zero (δ <= s) the set follows the compression down
    to zero, so a contact that opens fully starts the next pulse as a fresh pad.

    Power: the turning point follows the compression while the pad is loaded beyond it (δ >= δmax, δ' > 0) and is
    kept otherwise: unloading and reloading run along the same curve below it, and the plastic set φ·δmax stays
    for the rest of the record (the rate is continuous: δ' is zero where the pad turns).
    """
    if law == POWER:
        if delta_rate > 0.0 and delta > 0.0 and delta >= contact_set:
            return delta_rate
        return 0.0
    if law != HYSTERETIC:
        return 0.0
    if delta_rate > 0.0:
        if delta <= 0.0 or delta <= contact_set:
            return 0.0
        ratio = min(1.0, damping * (delta - contact_set) / (stiffness * delta))
        return (1.0 - stiffness / damping) * ratio * ratio * delta_rate
    if delta_rate < 0.0 and delta <= contact_set and contact_set > 0.0:
        return delta_rate
    return 0.0


@njit(cache=True, inline="always", error_model="numpy")
def contact_loss(delta, delta_rate, contact_set, set_rate, force, law, stiffness, damping, exponent,
                 unloading_exponent):
    """Power dissipated in the contact [W] (force times rate, minus the rate of its stored energy,
    :func:`contact_energy`).

    Power law on its loading curve (δ >= δmax): the stored energy F·(δ − φ·δmax)/(m + 1) with F ∝ δ^n grows at
    less than F·δ' (a fraction (n + 1)·(1 − φ)/(m + 1) of it while δmax = δ); below the turning point the
    unloading-reloading curve stores exactly the work done on it (no loss).
    """
    if law == HYSTERETIC:
        return force * set_rate
    if delta <= 0.0:
        return 0.0
    if law == POWER:
        if delta < contact_set:
            return 0.0
        scale = 1.0 / (unloading_exponent + 1.0)
        slope = scale * (exponent * force / delta * (delta - damping * contact_set) + force)  # ∂E/∂δ
        return (force - slope) * delta_rate + scale * force * damping * set_rate
    if law == HUNT_CROSSLEY:
        return (force - stiffness * delta * math.sqrt(delta)) * delta_rate
    return (force - stiffness * delta) * delta_rate


@njit(cache=True, inline="always", error_model="numpy")
def contact_energy(delta, force, contact_set, law, stiffness, damping, unloading_exponent):
    """Elastic energy stored in the contact [J] at compression ``delta`` [m] carrying ``force`` [N], with the
    contact's memory ``contact_set`` [m].

    Hysteretic: the energy the unloading line gives back, F²/(2·k2). Power: the energy the unloading curve gives
    back, F·(δ − φ·δmax)/(m + 1) (zero below the plastic set).
    """
    if delta <= 0.0:
        return 0.0
    if law == POWER:
        return force * max(delta - damping * contact_set, 0.0) / (unloading_exponent + 1.0)
    if law == HYSTERETIC:
        return 0.5 * force * force / damping
    if law == HUNT_CROSSLEY:
        return 0.4 * stiffness * delta * delta * math.sqrt(delta)
    return 0.5 * stiffness * delta * delta


@njit(cache=True, inline="always", error_model="numpy")
def stop_force(penetration, penetration_rate, stiffness, damping):
    """Push-only spring-damper force of a stop [N] for a penetration [m] and its rate [m/s]."""
    if penetration <= 0.0:
        return 0.0
    force = stiffness * penetration + damping * penetration_rate
    return force if force > 0.0 else 0.0


@njit(cache=True, inline="always", error_model="numpy")
def friction_force(velocity, coulomb_force, velocity_scale):
    """Smoothed Coulomb friction [N], opposing the piston velocity: F·tanh(v2 / v_s).

    tanh is evaluated as ±(1 − 2/(exp(2|x|) + 1)) for 0.5 <= |x| < 20 (within 3 ulp of the library tanh, at less
    than half its cost) and is exactly ±1 from |x| = 20 on (1 − tanh < 1e-17 there, below half an ulp of 1).
    """
    x = velocity / velocity_scale
    if x >= TANH_SATURATION:
        return coulomb_force
    if x <= -TANH_SATURATION:
        return -coulomb_force
    if x >= 0.5:
        return coulomb_force * (1.0 - 2.0 / (math.exp(2.0 * x) + 1.0))
    if x <= -0.5:
        return -coulomb_force * (1.0 - 2.0 / (math.exp(-2.0 * x) + 1.0))
    return coulomb_force * math.tanh(x)


@njit(cache=True, inline="always", error_model="numpy")
def pneumatic_force(pressure_lower, pressure_upper, area, rod_area, atmospheric_pressure):
    """Net upward gas force on the piston [N]: Fp = pL·A − pU·(A − A_rod) − p_atm·A_rod."""
    return pressure_lower * area - pressure_upper * (area - rod_area) - atmospheric_pressure * rod_area


#: pressure ratio above which the orifice flow is taken linear in the pressure difference (laminar transition);
#: the isentropic law has an infinite slope at p_down/p_up -> 1, which stalls any integrator when chambers equalise
LAMINAR_RATIO = 0.999


@njit(cache=True, inline="always", error_model="numpy")
def _flow_function(ratio, gamma):
    """Dimensionless flow function ψ of the isentropic orifice at pressure ratio p_down/p_up (unchoked)."""
    return math.sqrt(2.0 * gamma / (gamma - 1.0) * (ratio ** (2.0 / gamma) - ratio ** ((gamma + 1.0) / gamma)))


@njit(cache=True, inline="always", error_model="numpy")
def orifice_mass_flow(p_up, t_up, p_down, area, discharge_coefficient, gamma, gas_constant):
    """Compressible flow through an orifice [kg/s] from the upstream to the downstream side (>= 0).

    Choked when p_down/p_up is below the critical ratio (2/(γ+1))^(γ/(γ−1)), isentropic otherwise; above the
    laminar transition ratio ``LAMINAR_RATIO`` the flow falls linearly to zero with the pressure difference.
    """
    if area <= 0.0 or p_up <= p_down:
        return 0.0
    ratio = p_down / p_up
    critical = (2.0 / (gamma + 1.0)) ** (gamma / (gamma - 1.0))
    if ratio <= critical:
        psi = math.sqrt(gamma * (2.0 / (gamma + 1.0)) ** ((gamma + 1.0) / (gamma - 1.0)))
    elif ratio <= LAMINAR_RATIO:
        psi = _flow_function(ratio, gamma)
    else:
        psi = _flow_function(LAMINAR_RATIO, gamma) * (1.0 - ratio) / (1.0 - LAMINAR_RATIO)
    return discharge_coefficient * area * p_up * psi / math.sqrt(gas_constant * t_up)


@njit(cache=True, inline="always", error_model="numpy")
def iso6358_mass_flow(p_up, t_up, p_down, conductance, critical_ratio):
    """Mass flow through a pneumatic component rated by ISO 6358 [kg/s] from the upstream to the downstream side.

    q = C·p_up·ρ0·sqrt(T0/T_up) when choked (p_down/p_up <= b), times sqrt(1 − ((r − b)/(1 − b))²) above it, with
    the sonic conductance C [m³/(s·Pa)], the critical pressure ratio b [-] and the standard's reference density
    ρ0 = 1.185 kg/m³ at T0 = 293.15 K (the conditions catalogue values of C refer to). Above ``LAMINAR_RATIO`` the
    flow falls linearly to zero with the pressure difference, as for the orifice (the elliptic law also has an
    infinite slope at r -> 1).
    """
    if conductance <= 0.0 or p_up <= p_down:
        return 0.0
    ratio = p_down / p_up
    r = min(ratio, LAMINAR_RATIO)
    x = max(r - critical_ratio, 0.0) / (1.0 - critical_ratio)
    shape = math.sqrt(1.0 - x * x)
    if ratio > LAMINAR_RATIO:
        shape *= (1.0 - ratio) / (1.0 - LAMINAR_RATIO)
    return conductance * p_up * ISO_REFERENCE_DENSITY * math.sqrt(ISO_REFERENCE_TEMPERATURE / t_up) * shape
