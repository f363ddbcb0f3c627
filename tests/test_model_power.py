"""The power contact law (Masing-type unloading and reloading with a plastic set) against its closed forms and
against physics."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from impactometer.errors import ParameterError
from impactometer.model import simulate
from impactometer.model.forces import (
    POWER,
    REFERENCE_COMPRESSION,
    contact_energy,
    contact_force,
    contact_loss,
    contact_set_rate,
)
from impactometer.model.simulate import compare_integrators
from impactometer.rig import Contact, Scenario

#: k [N/m at 1 cm], n, m, φ of the checks on the law alone
K, N, M, PHI = 8e5, 1.5, 3.5, 0.4


def force(delta, rate, turning):
    return contact_force(delta, rate, turning, POWER, K, PHI, N, M)


def loading(delta, stiffness=K, exponent=N):
    """The loading curve k·δr·(δ/δr)^n [N]."""
    return stiffness * REFERENCE_COMPRESSION * (delta / REFERENCE_COMPRESSION) ** exponent


@pytest.fixture(scope="module")
def free_pad(free_bodies):
    """Two free bodies meeting through the power-law pad (the law's default parameters)."""
    return free_bodies.replace(**{"contact.law": "power"})


def test_force_law_branches_and_continuity():
    """Loading k·δ^n beyond the turning point, the unloading curve through (δmax, F_max) and (φ·δmax, 0) below it:
    continuous at both ends, zero below the plastic set and when apart."""
    turning = 4e-3
    peak = loading(turning)
    assert force(-1e-4, 1.0, 0.0) == 0.0
    assert force(5e-3, 1.0, turning) == pytest.approx(loading(5e-3))
    assert force(REFERENCE_COMPRESSION, 1.0, 0.0) == pytest.approx(K * REFERENCE_COMPRESSION)  # secant stiffness
    assert force(turning, -1.0, turning) == pytest.approx(peak)
    assert force(turning * (1 - 1e-12), -1.0, turning) == pytest.approx(peak, rel=1e-10)
    middle = 0.5 * (1 + PHI) * turning  # halfway between the set and the turning point
    assert force(middle, -1.0, turning) == pytest.approx(peak * 0.5**M)
    assert force(PHI * turning, -1.0, turning) == 0.0
    assert force(PHI * turning * (1 + 1e-9), -1.0, turning) == pytest.approx(0.0, abs=1e-20 * peak)
    assert force(0.3 * PHI * turning, 1.0, turning) == 0.0  # inside the set: no force, no pull
    # the memory follows the compression only while the pad is loaded beyond its turning point
    assert contact_set_rate(5e-3, 2.0, turning, POWER, K, PHI) == 2.0
    assert contact_set_rate(3e-3, 2.0, turning, POWER, K, PHI) == 0.0  # reloading below it
    assert contact_set_rate(5e-3, -2.0, turning, POWER, K, PHI) == 0.0  # unloading


def test_contact_energy_balance_along_a_prescribed_cycle():
    """Along a compression history δ(t) with a first loading, unloading below the set, reloading beyond the first
    turning point and minor cycles, the work ∫F dδ equals the stored energy plus the loss; the first loading loses
    (1 − e²) of its work, e² = (n + 1)·(1 − φ)/(m + 1), and the unloading-reloading curve loses nothing."""
    frequency = 200.0
    omega = 2.0 * math.pi * frequency

    def history(t):
        # 0 -> 1 mm -> 0 (below the set) -> 1.5 mm -> cycles between 1.1 and 1.5 mm
        if t < 1.0 / frequency:
            return 0.5e-3 * (1 - math.cos(omega * t)), 0.5e-3 * omega * math.sin(omega * t)
        if t < 1.5 / frequency:
            return 0.75e-3 * (1 - math.cos(omega * t)), 0.75e-3 * omega * math.sin(omega * t)
        return 1.3e-3 - 0.2e-3 * math.cos(omega * t), 0.2e-3 * omega * math.sin(omega * t)

    def rhs(t, y):
        delta, rate = history(t)
        f = force(delta, rate, y[0])
        s_rate = contact_set_rate(delta, rate, y[0], POWER, K, PHI)
        return [s_rate, f * rate, contact_loss(delta, rate, y[0], s_rate, f, POWER, K, PHI, N, M)]

    ends = [0.5 / frequency, 1.0 / frequency, 1.5 / frequency, 2.5 / frequency, 3.5 / frequency]
    sol = solve_ivp(rhs, (0.0, ends[-1]), [0.0, 0.0, 0.0], t_eval=ends, rtol=1e-11, atol=1e-15, max_step=1e-5)
    turning, work, loss = sol.y
    stored = np.array([contact_energy(history(t)[0], force(*history(t), s), s, POWER, K, PHI, M)
                       for t, s in zip(ends, turning, strict=True)])
    np.testing.assert_allclose(work, stored + loss, rtol=1e-6, atol=1e-9)
    e2 = (N + 1) * (1 - PHI) / (M + 1)
    assert turning[0] == pytest.approx(1e-3, rel=1e-6) and turning[2] == pytest.approx(1.5e-3, rel=1e-6)
    assert loss[0] == pytest.approx((1 - e2) * loading(1e-3) * 1e-3 / (N + 1), rel=1e-6)  # first loading
    assert loss[1] == pytest.approx(loss[0], rel=1e-9)  # unloading: no loss
    assert stored[1] == 0.0  # below the set
    assert loss[4] == pytest.approx(loss[3], rel=1e-9)  # minor cycles below the turning point: no loss


@pytest.mark.parametrize("mass, velocity", [(10.0, 1.0), (50.0, 3.0)])
@pytest.mark.parametrize("exponent, unloading_exponent, set_fraction", [(1.5, 3.5, 0.4), (1.0, 1.0, 0.0),
                                                                        (2.2, 6.0, 0.1)])
def test_isolated_collision_keeps_e_squared_of_the_relative_kinetic_energy(free_pad, mass, velocity, exponent,
                                                                           unloading_exponent, set_fraction):
    """Between two free bodies the rate-independent pad returns e² = (n + 1)·(1 − φ)/(m + 1) of the relative
    kinetic energy ½·μ·V0²: relative velocity −e·V0 after separation, to 1e-6; momentum kept."""
    m2 = free_pad.cylinder.piston_mass
    mu = mass * m2 / (mass + m2)
    peak, n = 3e-3, exponent  # δmax of the loading curve [m]: the stiffness that stops the bodies there
    rig = free_pad.replace(**{"contact.exponent": exponent, "contact.unloading_exponent": unloading_exponent,
                              "contact.set_fraction": set_fraction,
                              "contact.stiffness": 0.5 * mu * velocity**2 * (n + 1) / (peak * loading(peak, 1.0, n))})
    e = math.sqrt(rig.contact.restitution_squared)
    duration = 12.0 * peak / velocity  # loading and unloading take a few δmax/V0
    r = simulate(Scenario(mass=mass, velocity=velocity, pressure_gauge=0.0), rig, duration=duration,
                 sample_rate=4000 / duration)
    assert r.contact_force[-20:].max() == 0.0  # separated
    assert r.contact_set[-1] == pytest.approx(peak, rel=1e-6)  # the turning point, the memory of the pad
    assert (r.v1[-1] - r.v2[-1]) / velocity == pytest.approx(-e, abs=1e-6)
    assert r.dissipated_energy[-1] / (0.5 * mu * velocity**2) == pytest.approx(1.0 - e**2, abs=1e-6)
    assert mass * r.v1[-1] + m2 * r.v2[-1] == pytest.approx(mass * velocity, rel=1e-7)  # gas spring: ~1e-9


@pytest.mark.parametrize("integrator", ["fast", "reference"])
def test_convergence_under_tolerance_refinement(free_pad, integrator):
    """The error of the restitution of an isolated collision (closed form e) falls as the tolerance tightens:
    every hundredfold tightening cuts it, and at rtol 1e-10 it is below 1e-7."""
    mass, velocity = 30.0, 2.0
    e = math.sqrt(free_pad.contact.restitution_squared)
    errors = []
    for rtol in (1e-5, 1e-7, 1e-9, 1e-11):
        r = simulate(Scenario(mass=mass, velocity=velocity, pressure_gauge=0.0), free_pad, duration=0.02,
                     sample_rate=20e3, rtol=rtol, integrator=integrator)
        errors.append(abs((r.v1[-1] - r.v2[-1]) / velocity + e))
    assert np.all(np.diff(errors) < 0.0) or errors[-1] < 1e-10, errors
    assert errors[-2] < 1e-7


def test_fast_agrees_with_reference_on_the_stand(stand):
    """On the stand (gas spring, friction, stops; several pulses and the sustained contact), 27 scenarios of the
    paper grid's corners and centres: peak force and impulse within 1e-4 relative, peak times within 1 µs."""
    grid = np.meshgrid([10.0, 30.0, 50.0], [1.0, 2.0, 3.0], [20e3, 210e3, 400e3], indexing="ij")
    result = compare_integrators(*grid, stand.with_contact("power"), duration=0.05, sample_rate=200e3, rtol=1e-10)
    assert result.scenarios == 27 and result.pulse_count_mismatches == 0
    assert result.pulses >= 27
    assert result.peak_force < 1e-4 and result.impulse < 1e-4 and result.peak_time < 1e-6


@pytest.mark.parametrize("kwargs, match", [
    ({"exponent": 0.2}, "contact.exponent must be a number within"),
    ({"unloading_exponent": 30.0}, "contact.unloading_exponent must be a number within"),
    ({"set_fraction": 1.0}, "contact.set_fraction must be a number within"),
    ({"set_fraction": -0.1}, "contact.set_fraction must be a number within"),
    ({"exponent": 3.0, "unloading_exponent": 1.0, "set_fraction": 0.0}, "gives back no more energy than it takes"),
    ({"damping": 100.0}, "contact.damping is not a parameter of the power"),
])
def test_bad_parameters_are_refused(kwargs, match):
    with pytest.raises(ParameterError, match=match):
        Contact(law="power", **kwargs)


def test_aliases_and_restitution():
    assert Contact(law="masing") == Contact(law="power-set") == Contact.preset("power")
    assert Contact.preset("power").restitution_squared == pytest.approx(2.5 * 0.6 / 4.5)
    with pytest.raises(ParameterError, match="power law only"):
        _ = Contact(law="hysteretic").restitution_squared
