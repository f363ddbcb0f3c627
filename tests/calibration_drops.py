"""Calibration sets of a stand unlike every preset, made with the reference integrator (shared by the calibration
tests)."""

from __future__ import annotations

import dataclasses

import numpy as np

from impactometer.calibrate.synthetic import reference_drop
from impactometer.components import Contact, Cylinder, Friction
from impactometer.rig import Rig, Scenario

#: the lab's stand: other bore, rod, stroke, piston mass, pad stiffness and restitution, friction, dead volumes
TRUE_STAND = Rig(name="lab-stand", cylinder=Cylinder(piston_mass=2.6, bore=0.063, rod_diameter=0.02, stroke=0.16,
                                                     lower_length=0.17, upper_length=0.015, dead_volume_lower=3.2e-5,
                                                     dead_volume_upper=0.6e-5),
                 contact=Contact(law="hysteretic", stiffness=1.3e6, restitution=0.55), friction=Friction(force=120.0))
#: what the lab knows before calibrating: the geometry, piston mass and gas; the pad, friction and dead volumes at
#: the built-in stand's values
BASE_STAND = dataclasses.replace(
    TRUE_STAND, name="lab-stand", contact=Contact(), friction=Friction(),
    cylinder=dataclasses.replace(TRUE_STAND.cylinder, dead_volume_lower=2e-5, dead_volume_upper=1e-5))
TRUTH = {"contact.stiffness": 1.3e6, "contact.restitution": 0.55, "friction.force": 120.0,
         "cylinder.dead_volume_lower": 3.2e-5, "cylinder.dead_volume_upper": 0.6e-5}
#: (M1 [kg], V0 [m/s], p0 [Pa gauge]) of the calibration drops and of the held-back ones
CALIBRATION = [(12.0, 1.5, 150e3), (20.0, 2.5, 250e3), (35.0, 1.2, 300e3), (25.0, 3.0, 100e3), (45.0, 2.0, 200e3),
               (15.0, 2.2, 350e3)]
HELD_BACK = [(18.0, 1.8, 180e3), (30.0, 2.6, 280e3), (40.0, 1.4, 120e3), (22.0, 2.1, 220e3)]
#: relative σ of the light gate
GATE = 0.005


def drops(cases, *, noise, seed, stand=TRUE_STAND, duration=0.1, gate=GATE):
    """Recordings of ``cases`` with the truth in their metadata, V0 read by a light gate of relative σ ``gate``
    (the true V0 kept as ``true_velocity_m_s``)."""
    rng = np.random.default_rng(seed)
    out = []
    for i, (mass, velocity, pressure) in enumerate(cases):
        rec = reference_drop(Scenario(mass=mass, velocity=velocity, pressure_gauge=pressure), stand, noise=noise,
                             duration=duration, seed=seed * 100 + i)
        rec.metadata.update(velocity_m_s=velocity * (1.0 + gate * rng.standard_normal()), true_velocity_m_s=velocity)
        out.append(rec)
    return out
