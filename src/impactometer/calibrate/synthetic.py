"""Calibration sets of known truth: drops simulated with the reference integrator (scipy's DOP853, written apart
from the compiled integrator the fit uses) and passed through the sensor model, for tests, benchmarks and a dry
run of a calibration before the stand is built."""

from __future__ import annotations

import numpy as np

from ..model.simulate import simulate
from ..recording import Recording
from ..rig import STAND_KEY, Rig, Scenario, fingerprint, get_rig
from ..sensors import apply_sensors, internal_layout

#: relative tolerance of the reference integrations (the model error it leaves is far below any sensor noise)
REFERENCE_RTOL = 1e-9


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
