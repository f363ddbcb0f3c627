"""Calibration sets of known truth: drops simulated with the reference integrator (scipy's DOP853, written apart
from the compiled integrator the fit uses) and passed through the sensor model, for tests, benchmarks and a dry
run of a calibration before the stand is built."""

from __future__ import annotations

import dataclasses

import numpy as np

from ..model.simulate import simulate
from ..recording import Recording
from ..rig import STAND_KEY, Contact, Cylinder, Friction, Rig, Scenario, fingerprint, get_rig
from ..sensors import apply_sensors, internal_layout

__all__ = ["EXAMPLE_BASE", "EXAMPLE_DROPS", "EXAMPLE_HELD_BACK", "EXAMPLE_STAND", "EXAMPLE_TRUTH", "example_set",
           "reference_drop"]

#: relative tolerance of the reference integrations (the model error it leaves is far below any sensor noise)
REFERENCE_RTOL = 1e-9
#: a lab's stand unlike every preset: other bore, rod, stroke, piston mass, pad stiffness and restitution, friction
#: and dead volumes
EXAMPLE_STAND = Rig(name="lab-stand", cylinder=Cylinder(piston_mass=2.6, bore=0.063, rod_diameter=0.02, stroke=0.16,
                                                        lower_length=0.17, upper_length=0.015,
                                                        dead_volume_lower=3.2e-5, dead_volume_upper=0.6e-5),
                    contact=Contact(law="hysteretic", stiffness=1.3e6, restitution=0.55),
                    friction=Friction(force=120.0))
#: what the lab knows of it before calibrating: the geometry, piston mass and gas, with the pad, the friction and
#: the dead volumes at the built-in stand's values
EXAMPLE_BASE = dataclasses.replace(
    EXAMPLE_STAND, contact=Contact(), friction=Friction(),
    cylinder=dataclasses.replace(EXAMPLE_STAND.cylinder, dead_volume_lower=2e-5, dead_volume_upper=1e-5))
#: the example stand's values of the parameters a calibration fits by default [SI]
EXAMPLE_TRUTH = {"contact.stiffness": 1.3e6, "contact.restitution": 0.55, "friction.force": 120.0,
                 "cylinder.dead_volume_lower": 3.2e-5, "cylinder.dead_volume_upper": 0.6e-5}
#: (M1 [kg], V0 [m/s], p0 [Pa gauge]) of an example calibration set and of held-back drops
EXAMPLE_DROPS = ((12.0, 1.5, 150e3), (20.0, 2.5, 250e3), (35.0, 1.2, 300e3), (25.0, 3.0, 100e3),
                 (45.0, 2.0, 200e3), (15.0, 2.2, 350e3))
EXAMPLE_HELD_BACK = ((18.0, 1.8, 180e3), (30.0, 2.6, 280e3), (40.0, 1.4, 120e3), (22.0, 2.1, 220e3))


def reference_drop(scenario: Scenario, rig: Rig | str | None = None, *, sample_rate: float = 50e3,
                   duration: float = 0.1, pre_trigger: float = 0.02, noise: float = 0.01,
                   seed: int = 0) -> Recording:
    """One drop test simulated with the reference integrator, recorded as :func:`~impactometer.sensors.record`
    records it (causal anti-alias filter, ``noise`` as a fraction of each channel's RMS after contact).

    Parameters
    ----------
    scenario : Scenario
        M1 [kg], V0 [m/s], p0 [Pa gauge].
    rig : Rig or str, optional
        The stand (a preset name, a TOML file or a Rig).
    sample_rate : float
        DAQ sample rate [Hz].
    duration, pre_trigger : float
        Record length after and before first contact [s].
    noise : float
        Gaussian noise σ as a fraction of each channel's RMS after contact [-].
    seed : int
        Seed of the noise.

    Returns
    -------
    Recording
        With the truth in its metadata (``mass_kg``, ``velocity_m_s``, ``pressure_gauge_Pa``), the stand's name
        and fingerprint.
    """
    stand = get_rig(rig)
    factor, _ = internal_layout("causal", sample_rate)
    rate = factor * sample_rate
    sim = simulate(scenario, stand, duration=duration, sample_rate=rate, integrator="reference",
                   rtol=REFERENCE_RTOL)
    quiet = np.zeros(int(round(pre_trigger * sample_rate)) * factor)
    channels = {"contact_force": np.r_[quiet, sim.contact_force], "piston_acceleration": np.r_[quiet, sim.a2]}
    metadata = {"mass_kg": scenario.mass, "velocity_m_s": scenario.velocity,
                "pressure_gauge_Pa": scenario.pressure_gauge, "rig": stand.name, STAND_KEY: fingerprint(stand),
                "integrator": "reference"}
    return apply_sensors(channels, input_rate=rate, sample_rate=sample_rate, start_time=-quiet.size / rate,
                         noise=noise, seed=seed, anti_alias="causal", metadata=metadata)


def example_set(cases=EXAMPLE_DROPS, *, stand: Rig | str | None = EXAMPLE_STAND, noise: float = 0.01,
                seed: int = 1, duration: float = 0.1, gate: float = 0.005) -> list[Recording]:
    """Drops of ``cases`` ((M1 [kg], V0 [m/s], p0 [Pa gauge]) each) by :func:`reference_drop`, with V0 in the
    metadata as a light gate of relative σ ``gate`` reads it (the true V0 kept as ``true_velocity_m_s``)."""
    rng = np.random.default_rng(seed)
    out = []
    for i, (mass, velocity, pressure) in enumerate(cases):
        rec = reference_drop(Scenario(mass=mass, velocity=velocity, pressure_gauge=pressure), stand, noise=noise,
                             duration=duration, seed=seed * 100 + i)
        rec.metadata.update(velocity_m_s=velocity * (1.0 + gate * rng.standard_normal()), true_velocity_m_s=velocity)
        out.append(rec)
    return out
