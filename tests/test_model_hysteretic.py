"""The hysteretic (Walton-Braun) contact law against its closed forms and against physics."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from impactometer.model import simulate
from impactometer.model.forces import HYSTERETIC, contact_energy, contact_force, contact_loss, contact_set_rate
from impactometer.rig import Scenario


@pytest.fixture(scope="module")
def free_pad(free_bodies):
    """Two free bodies meeting through the hysteretic pad of the built-in stand (its law's default parameters)."""
    return free_bodies.replace(**{"contact.law": "hysteretic"})


@pytest.mark.parametrize("restitution", [0.2, 0.5, 0.8, 1.0])
@pytest.mark.parametrize("mass, velocity", [(10.0, 1.0), (50.0, 3.0)])
def test_isolated_collision_keeps_e_squared_of_the_relative_kinetic_energy(free_pad, restitution, mass, velocity):
    """Between two free bodies the relative velocity after separation is −e·V0: the collision loses
    (1 − e²) of the kinetic energy of the relative motion, ½·μ·V0², with e = sqrt(k1/k2). To 1e-5."""
    rig = free_pad.replace(**{"contact.restitution": restitution})
    m2 = rig.cylinder.piston_mass
    mu = mass * m2 / (mass + m2)
    duration = 2.0 * math.pi * math.sqrt(mu / rig.contact.stiffness)  # > loading + unloading quarter periods
    r = simulate(Scenario(mass=mass, velocity=velocity, pressure_gauge=0.0), rig, duration=duration,
                 sample_rate=4000 / duration)
    assert r.contact_force[-20:].max() == 0.0  # separated
    relative = (r.v1[-1] - r.v2[-1]) / velocity
    assert relative == pytest.approx(-restitution, abs=1e-5)
    lost = r.dissipated_energy[-1] / (0.5 * mu * velocity**2)
    assert lost == pytest.approx(1.0 - restitution**2, abs=1e-5)
    assert mass * r.v1[-1] + m2 * r.v2[-1] == pytest.approx(mass * velocity, rel=1e-9)  # momentum of the pair


def test_force_peaks_where_the_bodies_move_together(free_pad, free_bodies):
    """The rate-independent law peaks exactly at zero relative velocity (to one 1 µs sample); a viscous contact
    of the same restitution peaks measurably earlier, which is what biases the paper's eqs. (3)-(5) there."""
    scenario = Scenario(mass=30.0, velocity=2.0, pressure_gauge=0.0)

    def lag(rig):
        m2 = rig.cylinder.piston_mass
        # a quarter period of the loading line, doubled: past the peak for either contact
        duration = math.pi * math.sqrt(scenario.mass * m2 / (scenario.mass + m2) / rig.contact.stiffness)
        r = simulate(scenario, rig, duration=duration, sample_rate=1e6)
        peak = int(np.argmax(r.contact_force))
        relative = r.v1 - r.v2
        together = int(np.flatnonzero(relative <= 0.0)[0])  # first sample with v1 <= v2
        return (together - peak) * 1e-6

    assert abs(lag(free_pad)) <= 1e-6
    assert lag(free_bodies.replace(**{"contact.damping": 1500.0})) > 20e-6


def test_contact_energy_balance_along_a_prescribed_cycle():
    """Along any compression history δ(t), the work done on the contact, ∫F dδ, equals the change of its stored
    energy plus the loss ∫F·ds/dt dt; on minor load cycles (reloading below the loading line) the loss grows by a
    positive amount every cycle, so oscillations in sustained contact die out."""
    k1, e = 2e6, 0.5
    k2 = k1 / e**2
    omega = 2.0 * math.pi * 200.0

    def history(t):
        # compress to 1 mm, then cycle between 0.6 and 1.0 mm
        if t < 0.25 / 200.0:
            return 1e-3 * math.sin(omega * t), 1e-3 * omega * math.cos(omega * t)
        return 0.8e-3 + 0.2e-3 * math.sin(omega * t), 0.2e-3 * omega * math.cos(omega * t)

    def rhs(t, y):
        delta, rate = history(t)
        s = y[0]
        force = contact_force(delta, rate, s, HYSTERETIC, k1, k2, 1.0, 1.0)
        s_rate = contact_set_rate(delta, rate, s, HYSTERETIC, k1, k2)
        return [s_rate, force * rate, contact_loss(delta, rate, s, s_rate, force, HYSTERETIC, k1, k2, 1.0, 1.0)]

    cycles = 5
    ends = [(0.25 + n) / 200.0 for n in range(cycles + 1)]  # the same δ = 1 mm at every end
    sol = solve_ivp(rhs, (0.0, ends[-1]), [0.0, 0.0, 0.0], t_eval=ends, rtol=1e-10, atol=1e-14, max_step=2e-5)
    s, work, loss = sol.y
    stored = np.array([contact_energy(history(t)[0], contact_force(*history(t), si, HYSTERETIC, k1, k2, 1.0, 1.0),
                                      si, HYSTERETIC, k1, k2, 1.0) for t, si in zip(ends, s, strict=True)])
    np.testing.assert_allclose(work, stored + loss, rtol=1e-6, atol=1e-9)
    per_cycle = np.diff(loss)
    assert np.all(per_cycle > 1e-3 * loss[0])  # every minor cycle dissipates
    assert loss[0] == pytest.approx(0.5 * k1 * 1e-6 * (1.0 - k1 / k2), rel=1e-6)  # first loading: closed form


@pytest.mark.parametrize("delta, rate, s, expected", [
    (-1e-4, 1.0, 0.0, 0.0),  # apart
    (1e-3, 1.0, 0.0, 2e3),  # loading line k1·δ
    (1e-3, -1.0, 0.8e-3, 1.6e3),  # unloading line k2·(δ − s)
    (0.5e-3, -1.0, 0.8e-3, 0.0),  # below the set: no force, no pull
])
def test_force_law_branches(delta, rate, s, expected):
    assert contact_force(delta, rate, s, HYSTERETIC, 2e6, 8e6, 1.0, 1.0) == pytest.approx(expected)


def test_the_set_follows_a_receding_body_and_a_fresh_pulse_starts_from_it():
    assert contact_set_rate(0.5e-3, -2.0, 0.8e-3, HYSTERETIC, 2e6, 8e6) == -2.0
    assert contact_set_rate(0.9e-3, -2.0, 0.8e-3, HYSTERETIC, 2e6, 8e6) == 0.0  # unloading: frozen
    assert contact_set_rate(1e-3, 2.0, 0.0, HYSTERETIC, 2e6, 8e6) == pytest.approx(2.0 * 0.75)  # loading line
    assert contact_set_rate(-1e-4, -2.0, 0.0, HYSTERETIC, 2e6, 8e6) == 0.0  # fully open: set stays at zero
