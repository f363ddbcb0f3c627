"""Contact pulse detection: noise level, pulse count and sub-sample onsets against the simulated truth."""

import numpy as np
import pytest

from impactometer.identify.peak_to_peak.onsets import onset_index
from impactometer.model import simulate
from impactometer.rig import Scenario, get_rig
from impactometer.sensors import record
from impactometer.signals.noise import robust_noise_std
from impactometer.signals.pulses import PulseDetector, contact_pulses, detect_pulses
from impactometer.signals.stage_b import stage_b_start, sustained_start


@pytest.mark.parametrize("sigma", [0.5, 30.0])
def test_robust_noise_std_of_white_noise_on_a_smooth_signal(sigma):
    t = np.arange(20000) / 50e3
    x = 5000 * np.sin(2 * np.pi * 50 * t) + np.random.default_rng(4).normal(0, sigma, t.size)
    assert robust_noise_std(x) == pytest.approx(sigma, rel=0.05)


@pytest.mark.parametrize("contact", ["kv", "hunt"])
def test_onsets_match_zero_compression(contact):
    """Noise-free onsets are where u1 - u2 crosses zero, to within their stated standard error (+0.5 sample), on
    the stiff stand, whose rate-dependent contacts bounce several times."""
    r = simulate(Scenario(mass=30, velocity=2, pressure_gauge=2e5), get_rig("drop-stand-stiff", contact=contact),
                 duration=0.06)
    d = r.u1 - r.u2
    crossings = np.flatnonzero((d[:-1] <= 0) & (d[1:] > 0))
    truth = crossings + (-d[crossings]) / (d[crossings + 1] - d[crossings])
    spans = detect_pulses(r.contact_force, 0.0)
    assert len(spans) == truth.size  # one zero crossing per pulse (the first at t = 0)
    for span, true in zip(spans[1:], truth[1:], strict=False):
        onset, std = onset_index(r.contact_force, span, 0.0)
        assert abs(onset - true) <= 2 * std + 0.5


def test_noise_gaps_do_not_split_pulses():
    """With 5 % noise the same pulses are found as without noise."""
    r = simulate(Scenario(mass=30, velocity=2, pressure_gauge=2e5), duration=0.06)
    sigma = 0.05 * np.sqrt(np.mean(r.contact_force ** 2))
    noisy = r.contact_force + np.random.default_rng(2).normal(0, sigma, r.time.size)
    clean = detect_pulses(r.contact_force, 0.0)
    found = detect_pulses(noisy, robust_noise_std(noisy))
    assert len(found) == len(clean)
    # detection at 5σ: found after the clean onset, and before the clean force has risen through 8σ
    f = r.contact_force
    for a, b in zip(found, clean, strict=False):
        assert b.first - 1 <= a.first <= b.first + int(np.argmax(f[b.first:] > 8 * sigma))


def test_legacy_contact_pulses_and_stage_b():
    r = simulate(Scenario(mass=30, velocity=2, pressure_gauge=2e5), "drop-stand-stiff", duration=0.05)
    pulses = contact_pulses(r.time, r.contact_force)
    assert len(pulses) >= 4 and pulses[0].start == 0.0
    assert pulses[0].impulse == pytest.approx(np.trapezoid(r.contact_force[r.time <= pulses[0].end],
                                                           r.time[r.time <= pulses[0].end]), rel=1e-3)
    assert stage_b_start(pulses) in (None, pulses[-1].start)


def test_the_built_in_stand_rebounds_then_stays_in_contact():
    """Stage A (a rebound or two) then stage B that lasts to the mass's deepest point, as in the paper's Fig. 2."""
    r = simulate(Scenario(mass=30, velocity=2, pressure_gauge=2e5), "drop-stand-pad", duration=0.08)
    pulses = contact_pulses(r.time, r.contact_force)
    assert 2 <= len(pulses) <= 4 and not pulses[0].sustained and pulses[-1].sustained
    deepest = r.time[np.argmax(r.u1)]
    assert pulses[-1].start < deepest < pulses[-1].end
    assert stage_b_start(pulses) == pulses[-1].start < 0.03


def test_sustained_start_with_noise():
    """A long run of bounces ends in sustained contact: found with and without noise, at the same place."""
    r = simulate(Scenario(mass=50, velocity=3, pressure_gauge=4e5), get_rig(None, contact="hunt"), duration=0.1)
    clean = detect_pulses(r.contact_force, 0.0)
    b_clean = sustained_start(clean, size=r.time.size)
    assert b_clean is not None and r.time[b_clean] > 0.01  # after a few bounces
    sigma = 0.02 * np.sqrt(np.mean(r.contact_force ** 2))
    noisy = r.contact_force + np.random.default_rng(5).normal(0, sigma, r.time.size)
    b_noisy = sustained_start(detect_pulses(noisy, robust_noise_std(noisy)), size=r.time.size)
    assert abs(b_noisy - b_clean) <= 20
    assert sustained_start(clean[:1], size=r.time.size) is None


def _boundaries(spans):
    return [(p.zero, p.first, p.peak, p.end) for p in spans]


@pytest.mark.parametrize("chunk", [1, 2, 3, 7, 64, 1000])
def test_incremental_detector_agrees_with_the_batch_one_sample_for_sample(chunk):
    """The incremental form, pushed the noisy record in chunks of any size, finds the pulses of the batch form
    (zero, first, peak and end samples), and after every chunk those of the batch form on the samples so far."""
    rec = record(Scenario.from_height(mass=30, height=0.2, pressure_gauge=200e3), sample_rate=50e3, duration=0.1,
                 noise=0.02, seed=0, pre_trigger=0.02)
    f = rec.contact_force
    sigma, scale = robust_noise_std(f), float(np.max(np.abs(f)))
    batch = detect_pulses(f, sigma, start=100)
    assert len(batch) >= 2 and batch[0].first > 1000  # the pre-trigger is quiet; separated bounces follow
    detector = PulseDetector(sigma, scale, start=100)
    checks = range(chunk, f.size, max(chunk, 997))  # prefixes where the incremental answer is compared
    for k in range(0, f.size, chunk):
        found = detector.push(f[k:k + chunk])
        if k + chunk in checks:
            assert _boundaries(found) == _boundaries(detect_pulses(f[:k + chunk], sigma, force_scale=scale,
                                                                   start=100))
    assert detector.seen == f.size
    assert _boundaries(detector.pulses) == _boundaries(batch)


def test_incremental_detector_merges_a_gap_that_is_not_a_separation():
    """A dip below the release level whose force stays clearly positive is one pulse, however it is chunked."""
    t = np.arange(400)
    f = 100 * np.exp(-0.5 * ((t - 100) / 30) ** 2) + 100 * np.exp(-0.5 * ((t - 220) / 30) ** 2)
    f = np.where((t > 150) & (t < 170), 1.0, f) + np.random.default_rng(1).normal(0, 0.05, t.size)
    batch = detect_pulses(f, 0.2)
    assert len(batch) == 1
    for chunk in (1, 5, 160):
        detector = PulseDetector(0.2, float(np.max(np.abs(f))))
        for k in range(0, f.size, chunk):
            detector.push(f[k:k + chunk])
        assert _boundaries(detector.pulses) == _boundaries(batch)


def test_a_force_free_flight_is_not_merged_by_a_noise_excursion():
    """Two bounces with a force-free gap between them, 3000 noise draws: the gap is a separation in every draw (the
    gap test's one-sided false-alarm rate is 3e-5 per gap; at 3 standard errors it merges 3 of these flights),
    while a gap whose force stays at one noise σ (about 10 standard errors of its median) is one pulse."""
    t = np.arange(700)
    pulses = 100 * np.exp(-0.5 * ((t - 100) / 30) ** 2) + 100 * np.exp(-0.5 * ((t - 600) / 30) ** 2)
    pulses[(t > 180) & (t < 520)] = 0.0
    rng = np.random.default_rng(11)
    merged = sum(len(detect_pulses(pulses + rng.normal(0.0, 1.0, t.size), 1.0)) != 2 for _ in range(3000))
    assert merged == 0
    held = np.where((t > 180) & (t < 520), 1.0, pulses) + rng.normal(0.0, 1.0, t.size)
    assert len(detect_pulses(held, 1.0)) == 1
