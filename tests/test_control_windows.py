"""The controller's stage-B mass: window ends timed at the force's extrema, the estimate between two of them."""

import math

import numpy as np
import pytest

from impactometer.control import ControlSettings, simulate_controlled, windows
from impactometer.control.loop import sensor_noise, sensor_sigma
from impactometer.control.state import Windows
from impactometer.rig import Scenario


def test_noise_spikes_do_not_make_window_ends():
    """A falling force with a single-sample spike pair (−4σ then +4σ) is no extremum: an end needs the force
    beyond the confirmation level for several samples."""
    sigma = 10.0
    w = windows.initial()
    force = np.concatenate([np.linspace(0.0, 1000.0, 50), np.linspace(1000.0, 600.0, 200)])
    force[150], force[151] = force[150] - 4.0 * sigma, force[151] + 4.0 * sigma
    ends = []
    for i, f in enumerate(force):
        windows.push(w, i * 2e-5, f, 10.0, 5.0 * sigma, True, False, sigma, 0.1)
        ends.append(w[Windows.N_ENDS])
    assert ends[-1] == 1.0  # the peak at sample 50, and nothing since
    assert ends[140] == 1.0


@pytest.mark.parametrize("mass, velocity, pressure", [(10.0, 2.0, 20e3), (30.0, 2.5, 400e3), (50.0, 1.5, 115e3)])
def test_the_stage_b_mass_is_calibrated_while_it_forms(mass, velocity, pressure):
    """At 2 % noise the estimate from the windows alone, at each instant it is known over the first 60 ms, is within
    two of its stated standard errors of the truth in most instants and seeds, and within three in nearly all."""
    scenario = Scenario(mass=mass, velocity=velocity, pressure_gauge=pressure)
    closed, _ = simulate_controlled(scenario, "drop-stand", duration=0.1)
    z = []
    for seed in range(4):
        sigma = sensor_sigma(closed, 0.02)
        matrix = sensor_noise(sigma, closed.time.size, seed)
        control = ControlSettings(strategy="closed", force_noise=float(sigma[0]), acceleration_noise=float(sigma[1]))
        result, history = simulate_controlled(scenario, "drop-stand", control=control, duration=0.1,
                                              sensor_noise=matrix)
        estimate, std = history["estimated_mass"], history["estimated_mass_std"]
        for t in np.arange(0.012, 0.06, 0.002):
            i = int(np.searchsorted(result.time, t))
            if math.isfinite(estimate[i]):
                z.append((estimate[i] - mass) / std[i])
    z = np.abs(np.array(z))
    assert z.size >= 40
    assert np.mean(z <= 2.0) >= 0.85
    assert np.mean(z <= 3.0) >= 0.95
