"""Physics of the drop-stand model checked against physics: invariants, closed forms and limits."""

from __future__ import annotations

import math

import numpy as np
import pytest

from impactometer.model import simulate, simulate_batch
from impactometer.rig import Scenario


def cumulative_impulse(time, force, delta):
    """∫Fc dt [N·s] from samples, by trapezoids, exact to O(dt²) also where a contact starts with a force jump.

    In a sample interval where the bodies meet (δ crosses 0), the force is zero up to the contact instant t_c
    (found by linear interpolation of δ) and, after it, linear through the values extrapolated from the two next
    samples; elsewhere the plain trapezoid applies.
    """
    dt = np.diff(time)
    pieces = 0.5 * (force[1:] + force[:-1]) * dt
    onsets = np.flatnonzero((delta[:-1] <= 0.0) & (delta[1:] > 0.0) & (force[1:] > 0.0))
    for i in onsets[onsets + 2 < time.size]:
        t_c = time[i] + dt[i] * (-delta[i]) / (delta[i + 1] - delta[i])
        slope = (force[i + 2] - force[i + 1]) / dt[i + 1]
        f_c = force[i + 1] - slope * (time[i + 1] - t_c)
        pieces[i] = 0.5 * (f_c + force[i + 1]) * (time[i + 1] - t_c)
    return np.concatenate(([0.0], np.cumsum(pieces)))


@pytest.mark.parametrize("law", ["hysteretic", "kelvin-voigt", "hunt-crossley", "power"])
@pytest.mark.parametrize("mass, velocity, pressure", [(30.0, 2.0, 200e3), (10.0, 3.0, 20e3)])
def test_momentum_of_the_mass(stand, law, mass, velocity, pressure):
    """M1·v1 = M1·V0 + M1·g·t − ∫Fc dt at every sample, to 1e-6 of M1·V0 (eq. 1 integrated in time)."""
    rig = stand.with_contact(law)
    r = simulate(Scenario(mass=mass, velocity=velocity, pressure_gauge=pressure), rig, duration=0.03,
                 sample_rate=1e6)
    impulse = cumulative_impulse(r.time, r.contact_force, r.u1 - r.u2)
    expected = mass * velocity + mass * rig.gravity * r.time - impulse
    assert impulse[-1] > 0.5 * mass * velocity  # several pulses took a real share of the momentum
    assert np.max(np.abs(mass * r.v1 - expected)) < 1e-6 * mass * velocity


@pytest.mark.parametrize("integrator, rtol", [("fast", 1e-9), ("reference", 1e-11)])
@pytest.mark.parametrize("law", ["hysteretic", "kelvin-voigt", "hunt-crossley", "power"])
@pytest.mark.parametrize("pressure", [20e3, 400e3])
def test_total_energy_is_conserved(stand, integrator, rtol, law, pressure):
    """Kinetic + potential + gas + elastic + dissipated energy stays constant to the integration error.

    An error-controlled integrator keeps each step's local error within about ``rtol`` of every state; the energy
    terms are led by the gas, which holds U = Σ p·V/(γ−1) (10-25 × the impact energy E0), and over N steps the local
    errors add up to at most N·rtol. So the balance error may reach N·rtol·(U + E0)/E0, with N the fast
    integrator's accepted steps at the same ``rtol`` (the eighth-order reference takes fewer); a wrong energy term
    or force shows as 1e-3 of E0 or more.
    """
    rig = stand.with_contact(law)
    scenario = Scenario(mass=30.0, velocity=2.0, pressure_gauge=pressure)
    e0 = 0.5 * scenario.mass * scenario.velocity**2
    steps = int(simulate_batch(np.array([scenario.mass]), scenario.velocity, pressure, rig=rig, duration=0.05,
                               rtol=rtol).steps[0])
    c, absolute = rig.cylinder, pressure + rig.gas.atmospheric_pressure
    volumes = c.area * c.lower_length + c.dead_volume_lower + c.annulus_area * c.upper_length + c.dead_volume_upper
    gas = absolute * volumes / (rig.gas.gamma - 1.0)
    bound = steps * rtol * (gas + e0) / e0
    r = simulate(scenario, rig, duration=0.05, integrator=integrator, rtol=rtol)
    assert r.dissipated_energy[-1] > 0.05 * e0  # energy really moved between the terms
    assert np.ptp(r.gas_energy) > 0.5 * e0
    assert 5 < gas / e0 < 100 and 100 < steps < 10**4  # the bound's ingredients are what the docstring says
    assert r.energy_balance_error < bound


@pytest.mark.parametrize("pressure", [0.0, 210e3, 400e3])
def test_adiabatic_chambers_keep_p_v_gamma(stand, pressure):
    """With the valve closed each chamber follows p·V^γ = const (relative drift below 1e-7)."""
    r = simulate(Scenario(mass=40.0, velocity=3.0, pressure_gauge=pressure), stand, duration=0.05)
    c, gamma = stand.cylinder, stand.gas.gamma
    lower = c.area * (c.lower_length - r.u2) + c.dead_volume_lower
    upper = c.annulus_area * (c.upper_length + r.u2) + c.dead_volume_upper
    assert np.ptp(r.u2) > 0.01  # the piston travels centimetres
    for p, v in ((r.pressure_lower, lower), (r.pressure_upper, upper)):
        invariant = p * v**gamma
        assert np.max(np.abs(invariant / invariant[0] - 1.0)) < 1e-7


def gas_spring_stiffness(rig, pressure, exponent):
    """Linearised stiffness of both chambers at the top stop, n·p·(A²/V_L + (A−A_rod)²/V_U) [N/m], for the
    polytropic exponent n (γ: adiabatic, 1: isothermal)."""
    c = rig.cylinder
    v_lower = c.area * c.lower_length + c.dead_volume_lower
    v_upper = c.annulus_area * c.upper_length + c.dead_volume_upper
    return exponent * pressure * (c.area**2 / v_lower + c.annulus_area**2 / v_upper)


@pytest.mark.parametrize("stiffness", [2e6, 2e8])
@pytest.mark.parametrize("mass, velocity", [(10.0, 1.0), (30.0, 2.0), (50.0, 3.0)])
def test_first_pulse_peak_of_an_undamped_contact(stand, stiffness, mass, velocity):
    """Kelvin-Voigt peak ≈ V0·sqrt(k·μ), μ = M1·M2/(M1+M2), for a nearly undamped contact.

    Gravity and friction are switched off and p0 = 0, so the piston floats at the top-stop position with no
    preload; the gas spring (stiffness K ≈ 3.6e4 N/m) is the only force neglected by the two-body formula. It is a
    first-order perturbation of relative size K/k, so K/k is the tolerance (1.8 % at k = 2e6 N/m, 1.8e-4 at
    k = 2e8 N/m); the damping (ζ ≈ 1e-6) adds nothing measurable.
    """
    rig = stand.with_contact("kelvin-voigt").replace(**{"gravity": 0.0, "friction.force": 0.0,
                                                        "contact.stiffness": stiffness, "contact.damping": 0.01})
    mu = mass * rig.cylinder.piston_mass / (mass + rig.cylinder.piston_mass)
    period = 2 * math.pi * math.sqrt(mu / stiffness)
    r = simulate(Scenario(mass=mass, velocity=velocity, pressure_gauge=0.0), rig, duration=0.6 * period,
                 sample_rate=2000 / period)
    expected = velocity * math.sqrt(stiffness * mu)
    tolerance = gas_spring_stiffness(rig, rig.gas.atmospheric_pressure, rig.gas.gamma) / stiffness
    assert abs(r.contact_force.max() / expected - 1.0) < tolerance


@pytest.mark.parametrize("mass, velocity", [(10.0, 1.0), (50.0, 3.0)])
def test_first_pulse_peak_of_an_undamped_hertz_contact(free_bodies, mass, velocity):
    """Hunt-Crossley with α = 0 is Hertz: peak = k·δm^1.5 with δm = (5·μ·V0²/(4·k))^(2/5), to 1e-6."""
    rig = free_bodies.replace(**{"contact.law": "hunt-crossley", "contact.damping": 0.0})
    mu = mass * rig.cylinder.piston_mass / (mass + rig.cylinder.piston_mass)
    k = rig.contact.stiffness
    delta_max = (5.0 * mu * velocity**2 / (4.0 * k)) ** 0.4
    duration = 4.0 * delta_max / velocity  # the Hertz pulse lasts ≈ 2.94·δm/V0
    r = simulate(Scenario(mass=mass, velocity=velocity, pressure_gauge=0.0), rig, duration=duration,
                 sample_rate=4000 / duration)
    # refine the sampled maximum by the parabola through its neighbours
    i = int(np.argmax(r.contact_force))
    f0, f1, f2 = r.contact_force[i - 1:i + 2]
    peak = f1 - (f0 - f2) ** 2 / (8.0 * (f0 - 2.0 * f1 + f2))
    assert abs(peak / (k * delta_max**1.5) - 1.0) < 1e-6


def restitution_closed_form(zeta):
    """Coefficient of restitution of a compressive-only Kelvin-Voigt contact between two free bodies.

    With δ(t) = V0/ωd·e^(−ζω0t)·sin(ωd t) the force k·δ + c·δ' = −μ·δ'' reaches zero, and the bodies separate,
    when tan(ωd t) = −2ζ·sqrt(1−ζ²)/(1−2ζ²), i.e. at ωd·ts = π − 2·arcsin ζ -- before δ returns to zero. There
    −δ'(ts)/V0 = exp(−ζ·(π − 2·arcsin ζ)/sqrt(1−ζ²)) (valid for ζ < 1/√2).
    """
    return math.exp(-zeta * (math.pi - 2.0 * math.asin(zeta)) / math.sqrt(1.0 - zeta**2))


@pytest.mark.parametrize("zeta", [0.02, 0.1, 0.3, 0.6])
def test_kelvin_voigt_restitution_of_two_free_bodies(free_bodies, zeta):
    """Relative velocity after separation / V0 equals the closed form to 1e-5 (the naive e^(−ζπ/sqrt(1−ζ²)),
    which assumes separation at δ = 0, is off by 2e-4 at ζ = 0.02 up to 160 % at ζ = 0.6)."""
    mass, velocity = 30.0, 2.0
    mu = mass * free_bodies.cylinder.piston_mass / (mass + free_bodies.cylinder.piston_mass)
    k = free_bodies.contact.stiffness
    rig = free_bodies.replace(**{"contact.damping": zeta * 2.0 * math.sqrt(k * mu)})
    r = simulate(Scenario(mass=mass, velocity=velocity, pressure_gauge=0.0), rig, duration=0.01,
                 sample_rate=1e4)
    assert r.contact_force[-10:].max() == 0.0  # separated and flying apart
    measured = (r.v2[-1] - r.v1[-1]) / velocity
    assert abs(measured / restitution_closed_form(zeta) - 1.0) < 1e-5


def test_first_contact_separates_before_the_overlap_closes(free_bodies):
    """The clamped Kelvin-Voigt force vanishes while δ > 0: the overlap then closes in free flight."""
    rig = free_bodies.replace(**{"contact.damping": 1000.0})
    r = simulate(Scenario(mass=30.0, velocity=2.0, pressure_gauge=0.0), rig, duration=0.006, sample_rate=1e6)
    delta = r.u1 - r.u2
    end_of_force = np.flatnonzero(r.contact_force > 0.0)[-1] + 1
    assert delta[end_of_force] > 1e-5
    relative_velocity = r.v1 - r.v2
    after = slice(end_of_force + 1, None)
    assert np.ptp(relative_velocity[after]) < 1e-6 * 2.0  # no force: constant relative velocity


@pytest.mark.parametrize("integrator, slope_range", [("fast", (0.85, 1.15)), ("reference", (0.75, 1.25))])
def test_convergence_under_tolerance_refinement(free_bodies, integrator, slope_range):
    """Over the smooth first contact (closed form δ(t)), the global error falls ∝ rtol.

    For an error-per-step controller with local extrapolation the local error of the propagated solution is
    ∝ tol^((p+1)/p) with steps ∝ tol^(−1/p), hence a global error ∝ tol: the log-log slope must be ~1, and every
    tenfold tightening must reduce the error.
    """
    mass, velocity, zeta = 30.0, 2.0, 0.1
    mu = mass * free_bodies.cylinder.piston_mass / (mass + free_bodies.cylinder.piston_mass)
    k = free_bodies.contact.stiffness
    rig = free_bodies.replace(**{"contact.damping": zeta * 2.0 * math.sqrt(k * mu)})
    w0 = math.sqrt(k / mu)
    wd = w0 * math.sqrt(1.0 - zeta**2)
    duration = 0.9 * (math.pi - 2.0 * math.asin(zeta)) / wd  # before separation: the force stays smooth
    rtols = np.array([1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10])
    errors = []
    for rtol in rtols:
        r = simulate(Scenario(mass=mass, velocity=velocity, pressure_gauge=0.0), rig, duration=duration,
                     sample_rate=2000 / duration, rtol=rtol, integrator=integrator)
        exact = velocity / wd * np.exp(-zeta * w0 * r.time) * np.sin(wd * r.time)
        errors.append(np.max(np.abs(r.u1 - r.u2 - exact)) / (velocity / w0))
    errors = np.array(errors)
    slope = np.polyfit(np.log(rtols), np.log(errors), 1)[0]
    assert slope_range[0] < slope < slope_range[1]
    assert np.all(np.diff(errors) < 0.0)


@pytest.mark.parametrize("pressure, on_stop", [(200e3, True), (100e3, True), (60e3, False), (20e3, False)])
def test_equilibrium_start(stand, pressure, on_stop):
    """At t = 0 the piston is at rest in static equilibrium: on the top stop when the gas can hold it
    (p0·A_rod > M2·g, i.e. p0 > 80 kPa here), else floating on the gas spring; its acceleration is ~0."""
    c = stand.cylinder
    r = simulate(Scenario(mass=30.0, velocity=1e-9, pressure_gauge=pressure), stand, duration=1e-3,
                 sample_rate=1e5)
    weight = c.piston_mass * stand.gravity
    assert (pressure * c.rod_area > weight) == on_stop
    if on_stop:  # the stop, in parallel with the (isothermally settled) gas spring, carries the excess gas force
        preload = pressure * c.rod_area - weight
        gas = gas_spring_stiffness(stand, stand.gas.atmospheric_pressure + pressure, 1.0)
        assert r.u2[0] == pytest.approx(-preload / (stand.stops.stiffness + gas), rel=1e-5)
        assert r.top_stop_force[0] == pytest.approx(preload, rel=3e-3)
    else:  # the gas alone carries the weight
        assert r.u2[0] > 1e-4
        assert r.pneumatic_force[0] == pytest.approx(weight, rel=1e-9)
    assert r.v2[0] == 0.0
    assert abs(r.a2[0]) < 1e-6  # [m/s²], against g


def test_friction_is_the_smoothed_coulomb_law():
    """F·tanh(v/v_s) (evaluated through exp for 0.5 <= |x| < 20) within 4 ulp of the library tanh, odd, and
    exactly ±F from |v/v_s| = 20 on; seeded random velocities over ±0.5 m/s plus the branch edges."""
    from impactometer.model.forces import friction_force

    rng = np.random.default_rng(11)
    scale = 0.01
    x = np.concatenate([rng.uniform(-50.0, 50.0, 20_000), [0.0, 0.5, -0.5, 0.4999999, 19.999999, 20.0, -20.0]])
    for xi in x:
        got = friction_force(xi * scale, 30.0, scale)
        want = 30.0 * math.tanh(xi * scale / scale)
        assert abs(got - want) <= 4 * np.spacing(abs(want)) + 1e-300, (xi, got, want)
        assert friction_force(-xi * scale, 30.0, scale) == -got
        if abs(xi) >= 20.0:
            assert got == math.copysign(30.0, xi)


def test_kinetic_energy_is_absolute(stand):
    """The kinetic energy of the result is ½M1v1² + ½m2v2², never a change from t = 0."""
    from impactometer import Scenario, simulate

    result = simulate(Scenario(mass=30.0, velocity=2.0, pressure_gauge=200e3), stand, duration=0.05)
    assert result.kinetic_energy[0] == pytest.approx(0.5 * 30.0 * 2.0**2, rel=1e-6)
    assert result.kinetic_energy.min() >= 0.0
