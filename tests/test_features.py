"""Feature sets of the response map: closed-form signals, noise, batch/single equivalence, bad input."""

from __future__ import annotations

import numpy as np
import pytest

from impactometer.errors import ParameterError, ResponseMapError
from impactometer.identify.response_map.features import FEATURE_SETS, extract_batch, extract_features, get_feature_set

FS = 50e3
TIME = np.arange(0, 0.06 * FS) / FS


def half_sines(pulses, time=TIME):
    """Sum of half-sine pulses (start [s], duration [s], amplitude [N])."""
    force = np.zeros_like(time)
    for start, duration, amplitude in pulses:
        inside = (time >= start) & (time <= start + duration)
        force[inside] += amplitude * np.sin(np.pi * (time[inside] - start) / duration)
    return force


TWO_PULSES = [(0.0, 0.004, 3000.0), (0.015, 0.005, 3600.0)]


def test_max_impulse_of_a_half_sine_matches_closed_form():
    # one 4-ms half sine of 3 kN: max = A, impulse = 2·A·τ/π
    force = half_sines([(0.0, 0.004, 3000.0)])
    values, available = extract_features(TIME, force, "max-impulse", {"window": 0.01})
    assert values[0] == pytest.approx(3000.0, rel=2e-4)
    assert values[1] == pytest.approx(2 * 3000.0 * 0.004 / np.pi, rel=1e-4)
    assert available == pytest.approx(0.01)


def test_max_impulse_window_cuts_the_second_pulse():
    force = half_sines(TWO_PULSES)
    short, _ = extract_features(TIME, force, "max-impulse", {"window": 0.01})
    long, _ = extract_features(TIME, force, "max-impulse", {"window": 0.03})
    assert short[0] == pytest.approx(3000.0, rel=2e-4)
    assert long[0] == pytest.approx(3600.0, rel=2e-4)
    assert long[1] == pytest.approx(2 / np.pi * (3000 * 0.004 + 3600 * 0.005), rel=1e-4)


def test_impulse_profile_of_a_constant_force_is_linear_in_time():
    force = np.full_like(TIME, 1500.0)
    values, available = extract_features(TIME, force, "impulse-profile", {"window": 0.03})
    np.testing.assert_allclose(values, 1500.0 * 0.03 * np.arange(1, 7) / 6, rtol=1e-12)
    assert available == pytest.approx(0.03)


def test_peaks_finds_both_amplitudes_and_the_end_of_the_second_pulse():
    values, available = extract_features(TIME, half_sines(TWO_PULSES), "peaks")
    np.testing.assert_allclose(values, [3000.0, 3600.0], rtol=2e-4)
    # the second peak is known once the force has fallen below it by 5 % of the first peak (150 N):
    # 3600·sin(x) = 3450 past the top of the half sine
    end = 0.015 + 0.005 * (1 - np.arcsin(3450.0 / 3600.0) / np.pi)
    assert available == pytest.approx(end, abs=2 / FS)


def test_peaks_takes_the_first_peak_of_a_second_contact_that_runs_into_stage_b():
    force = half_sines(TWO_PULSES[:1])
    # the rebound's half sine past its peak down to 2400 N, then sustained contact at that level
    settle = 0.015 + 0.005 * (1 - np.arcsin(2400.0 / 3600.0) / np.pi)
    rebound = (TIME >= 0.015) & (settle > TIME)
    force[rebound] = 3600.0 * np.sin(np.pi * (TIME[rebound] - 0.015) / 0.005)
    force[settle <= TIME] = 2400.0
    values, _ = extract_features(TIME, force, "peaks")
    np.testing.assert_allclose(values, [3000.0, 3600.0], rtol=2e-3)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_peaks_are_robust_to_one_percent_noise(seed):
    clean = half_sines(TWO_PULSES)
    rng = np.random.default_rng(seed)
    noisy = clean + rng.normal(0.0, 0.01 * np.sqrt(np.mean(clean ** 2)), clean.size)
    values, _ = extract_features(TIME, noisy, "peaks")
    # smoothing over 0.5 ms leaves a peak error well below the noise level (1 % of the RMS ≈ 0.4 % of a peak)
    np.testing.assert_allclose(values, [3000.0, 3600.0], rtol=4e-3)


def test_one_pulse_is_refused_with_the_reason():
    with pytest.raises(ResponseMapError, match="fewer than two usable peaks"):
        extract_features(TIME, half_sines([(0.0, 0.004, 3000.0)]), "peaks")


@pytest.mark.parametrize("name", sorted(FEATURE_SETS))
def test_batch_equals_single_and_scales_linearly(name):
    rng = np.random.default_rng(4)
    forces = np.array([half_sines([(0.0, 0.004, a), (0.016, 0.005, b)]) for a, b in rng.uniform(1e3, 5e3, (4, 2))])
    values, available = extract_batch(TIME, forces, name)
    for row, force in enumerate(forces):
        single, at = extract_features(TIME, force, name)
        np.testing.assert_allclose(values[row], single, rtol=1e-12)
        assert available[row] == pytest.approx(at)
    doubled, _ = extract_batch(TIME, 2.0 * forces, name)
    np.testing.assert_allclose(doubled, 2.0 * values, rtol=1e-9)  # every feature is linear in the force


def test_unknown_set_and_parameters_are_refused():
    with pytest.raises(ParameterError, match="must be one of"):
        get_feature_set("fft")
    with pytest.raises(ParameterError, match=r"unknown parameter\(s\) \['T'\]"):
        extract_features(TIME, half_sines(TWO_PULSES), "max-impulse", {"T": 0.02})
    with pytest.raises(ParameterError, match="window must be a number within"):
        extract_features(TIME, half_sines(TWO_PULSES), "max-impulse", {"window": -1.0})


def test_record_shorter_than_the_window_is_refused():
    short = TIME[TIME < 0.01]
    with pytest.raises(ResponseMapError, match="needs at least that long"):
        extract_features(short, half_sines(TWO_PULSES, short), "max-impulse", {"window": 0.02})


def test_record_without_first_contact_is_refused():
    with pytest.raises(ResponseMapError, match="must contain first contact"):
        extract_features(TIME + 0.01, half_sines(TWO_PULSES), "max-impulse")


def test_pre_trigger_samples_are_ignored():
    pre = np.arange(-100, 0) / FS
    time = np.concatenate([pre, TIME])
    force = np.concatenate([np.full(pre.size, 500.0), half_sines(TWO_PULSES)])
    np.testing.assert_allclose(extract_features(time, force, "max-impulse")[0],
                               extract_features(TIME, half_sines(TWO_PULSES), "max-impulse")[0], rtol=1e-3)
