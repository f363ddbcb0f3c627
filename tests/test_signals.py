"""The signal primitives on their own, on synthetic signals with known answers: the compiled impact trigger, the
pulse detector and stage B, the noise estimator, sub-sample onsets and turning points, the segment's trigger events
and pulses, the contact law; and the two turning-point timers (batch and in-loop) against each other.

Tolerances come from the signals (a sample's worth of a known slope, a level's worth of noise) or from the
estimators' own statistics (their stated standard errors, checked by coverage over seeded noise)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.stats import multivariate_normal, norm

from impactometer.errors import IdentificationError
from impactometer.identify.peak_to_peak import contact_law, segment
from impactometer.identify.peak_to_peak.onsets import MIN_STD, onset_index, separation_index
from impactometer.signals import trigger
from impactometer.signals.extrema import (
    EDGE,
    GRID_STEP,
    VERTEX_HALF_MAX,
    VERTEX_HALF_MIN,
    ring_vertex,
    smoothing_margin,
    turning_points,
    vertex,
    wrong_curvature,
)
from impactometer.signals.noise import quiet_noise_std, robust_noise_std, second_difference_noise_std
from impactometer.signals.pulses import (
    HOLD,
    TRIGGER_HOLD,
    PulseSpan,
    contact_pulses,
    detect_pulses,
    detection_levels,
)
from impactometer.signals.stage_b import (
    SUSTAINED_CONTROL_FACTOR,
    SUSTAINED_FACTOR,
    SUSTAINED_WINDOW_FACTOR,
    controller_sustained,
    is_sustained,
    stage_b_start,
    sustained_index,
    sustained_start,
)


def _events(force, *, floor=1e-9, quiet=500, longest=10**6, baseline=256, state=None):
    """Trigger events [(code, sample)] of ``force`` fed in one block (or continuing ``state``)."""
    fstate, istate = trigger.new_state() if state is None else state
    force = np.asarray(force, dtype=float)
    out = np.empty((2 * force.size + 2, 2), dtype=np.int64)
    n = trigger.run_trigger(force, fstate, istate, floor, quiet, longest, baseline, out)
    return [tuple(int(v) for v in row) for row in out[:n]]


def _half_sine(size, start, duration, amplitude):
    """A half-sine pulse of ``amplitude`` from ``start`` to ``start + duration`` [samples], zero elsewhere."""
    s = (np.arange(size) - start) / duration
    return np.where((s > 0.0) & (s < 1.0), amplitude * np.sin(np.pi * np.clip(s, 0.0, 1.0)), 0.0)


# --------------------------------------------------------------------------------------------------------------
# the compiled trigger


def test_baseline_time_constant_follows_the_sample_rate_above_the_baseline_rate():
    assert trigger.baseline_samples(10e3) == trigger.BASELINE_SAMPLES
    assert trigger.baseline_samples(trigger.BASELINE_RATE) == trigger.BASELINE_SAMPLES
    assert trigger.baseline_samples(2e6) == 40 * trigger.BASELINE_SAMPLES  # the same 5.12 ms


@pytest.mark.parametrize("seed", range(12))
def test_the_trigger_fires_where_a_ramp_leaves_the_noise(seed):
    """Quiet noise (σ = 1 N on a 100 N offset), then a ramp of 0.5 N/sample from a known onset: the trigger fires
    where the ramp has risen TRIGGER_SIGMAS σ above the baseline, give or take what the noise (±4 σ) and the running
    σ's own error (±20 %, some six of its standard errors with a 256-sample time constant) move that crossing."""
    size, onset, slope = 6000, 3000, 0.5
    force = 100.0 + slope * np.clip(np.arange(size) - onset, 0, None)
    force += np.random.default_rng(seed).standard_normal(size)
    events = _events(force, quiet=10**9)
    assert [code for code, _ in events] == [trigger.EVENT_TRIGGER]
    level = trigger.TRIGGER_SIGMAS
    early, late = (0.8 * level - 4.0) / slope, (1.2 * level + 4.0) / slope
    assert onset + early <= events[0][1] <= onset + late


def test_noise_alone_never_fires_the_trigger():
    """Four hundred thousand samples of white noise (with an offset, and a slow drift far inside the noise per time
    constant) give no event: the 8 σ level is passed by Gaussian noise once in 10^15 samples."""
    size = 400_000
    rng = np.random.default_rng(11)
    drift = 3.0 * np.sin(2.0 * np.pi * np.arange(size) / 100_000)
    assert _events(-40.0 + drift + rng.standard_normal(size)) == []
    assert _events(np.full(1000, 7.0)) == []  # a constant channel, whatever the floor


def test_a_pulse_is_past_its_peak_then_ends_then_the_impact_closes_at_the_known_samples():
    """Noise-free half-sine from sample 3000.3 lasting 200 samples: it passes half its maximum on the way down at
    3000.3 + 5/6·200, is back at zero from sample 3201, and the impact closes after the quiet run."""
    size, quiet = 6000, 500
    force = 100.0 + _half_sine(size, 3000.3, 200.0, 1000.0)
    events = _events(force, quiet=quiet)
    end = 3201
    assert events == [(trigger.EVENT_TRIGGER, 3001), (trigger.EVENT_PAST_PEAK, int(np.ceil(3000.3 + 200 * 5 / 6))),
                      (trigger.EVENT_PULSE_END, end), (trigger.EVENT_CLOSE, end + quiet - 1)]


@pytest.mark.parametrize("seed", range(6))
def test_with_noise_the_pulse_events_stay_within_a_sample_of_the_noise_free_ones(seed):
    """σ = 1 N on a 1000 N half-sine: the edges fall 13 N per sample where the events are decided, so noise moves
    them by at most a sample; the close comes after the quiet run plus the noise's excursions above the release
    level (2.3 % of samples at 2 σ, so fewer than 4 % of the run)."""
    size, quiet = 6000, 500
    force = 100.0 + _half_sine(size, 3000.3, 200.0, 1000.0) + np.random.default_rng(seed).standard_normal(size)
    (c0, trig), (c1, past), (c2, end), (c3, close) = _events(force, quiet=quiet)
    assert (c0, c1, c2, c3) == (trigger.EVENT_TRIGGER, trigger.EVENT_PAST_PEAK, trigger.EVENT_PULSE_END,
                                trigger.EVENT_CLOSE)
    assert 3001 <= trig <= 3002
    assert abs(past - 3167) <= 1
    assert 3200 <= end <= 3202
    assert end + quiet - 1 <= close <= end + quiet - 1 + 0.04 * quiet


def test_a_record_that_starts_in_contact_fires_at_sample_zero():
    """No quiet history: the warm-up holds the rise of the first pulse, and the trigger fires at sample 0."""
    size = 3000
    force = _half_sine(size, -0.5, 400.0, 1000.0) + np.random.default_rng(1).standard_normal(size)
    events = _events(force)
    assert events[0] == (trigger.EVENT_TRIGGER, 0)
    assert [code for code, _ in events[1:]] == [trigger.EVENT_PAST_PEAK, trigger.EVENT_PULSE_END, trigger.EVENT_CLOSE]
    assert abs(events[1][1] - 333) <= 1 and 399 <= events[2][1] <= 401


def test_a_contact_that_never_ends_closes_after_the_longest_impact():
    size, step, longest = 3000, 1000, 700
    force = np.where(np.arange(size) >= step, 50.0, 0.0) + 0.1 * np.random.default_rng(2).standard_normal(size)
    assert _events(force, longest=longest) == [(trigger.EVENT_TRIGGER, step), (trigger.EVENT_CLOSE, step + longest)]


def _two_impacts(size=3000, seed=3):
    """Two impacts of σ = 1 N noise: a bounce (500 → 600) and a rebound (700.5 → 760.5), then one more (2000)."""
    force = _half_sine(size, 500.0, 100.0, 300.0) + _half_sine(size, 700.5, 60.0, 200.0)
    force += _half_sine(size, 2000.0, 100.0, 300.0)
    return force + np.random.default_rng(seed).standard_normal(size)


def test_the_trigger_rearms_after_an_impact_and_reports_every_pulse():
    events = _events(_two_impacts(), quiet=400)
    t, past, end, close = trigger.EVENT_TRIGGER, trigger.EVENT_PAST_PEAK, trigger.EVENT_PULSE_END, trigger.EVENT_CLOSE
    assert [code for code, _ in events] == [t, past, end, past, end, close, t, past, end, close]
    known = [501, 584, 600, 751, 761, None, 2001, 2084, 2100, None]  # ceil of the noise-free crossings
    for (_, sample), expected in zip(events, known, strict=True):
        if expected is not None:
            assert abs(sample - expected) <= 1


def test_the_trigger_ends_a_pulse_at_the_first_sample_below_release_the_detector_after_its_hold():
    """TRIGGER_HOLD against HOLD: a one-sample dip to zero inside a 100 N contact is a pulse end for the trigger (its
    streaming answer comes without delay) but not for the detector, which needs HOLD samples; a dip of HOLD samples
    ends both, at the same first sample."""
    assert TRIGGER_HOLD == 1 < HOLD
    for dip, ends in ((1, 1), (HOLD, 2)):
        force = np.zeros(2000)
        force[500:700] = 100.0
        force[600:600 + dip] = 0.0
        events = _events(force, quiet=10**6)
        assert [i for c, i in events if c == trigger.EVENT_PULSE_END] == [600, 700]
        spans = detect_pulses(force, 0.0)
        assert len(spans) == ends and spans[0].end == (600 if ends == 2 else 700)


@pytest.mark.parametrize("chunks", [[1], [7, 1, 64], [1000], [255, 256, 257]])
def test_chunked_feeding_gives_the_events_of_one_block(chunks):
    force = _two_impacts()
    whole = _events(force, quiet=400)
    state, found, start, i = trigger.new_state(), [], 0, 0
    while start < force.size:
        size = chunks[i % len(chunks)]
        found += _events(force[start:start + size], quiet=400, state=state)
        start, i = start + size, i + 1
    assert found == whole and len(whole) == 10


# --------------------------------------------------------------------------------------------------------------
# noise estimator


def _robust_standard_error(size):
    """Asymptotic standard error of :func:`robust_noise_std` on ``size`` samples of unit white noise [-].

    The estimate is the median m of |d| (d the second differences, variance 6, lag correlations −2/3 and 1/6, zero
    beyond) over its Gaussian value: its variance is Var(F̂(m)) / f(m)², where F̂ is the fraction of |d| <= m and
    f the density of |d| there, and F̂'s variance sums the lag covariances of the indicators 1{|d| <= m}."""
    m = norm.ppf(0.75)  # in units of the standard deviation of d

    def both_inside(rho):
        return multivariate_normal(mean=[0.0, 0.0], cov=[[1.0, rho], [rho, 1.0]]).cdf([m, m], lower_limit=[-m, -m])

    long_run = 0.25 + 2.0 * sum(both_inside(rho) - 0.25 for rho in (-2.0 / 3.0, 1.0 / 6.0))
    return float(np.sqrt(long_run / size) / (2.0 * norm.pdf(m) * m))


@pytest.mark.parametrize("sigma, size", [(0.5, 20_000), (30.0, 4000), (1e-3, 100_000)])
def test_robust_noise_std_of_white_noise_is_within_its_sampling_error(sigma, size):
    """Within 4 asymptotic standard errors, on a large smooth signal (second differences 1e-4 σ) and with three jumps
    of 500 σ: each spoils two second differences, so together they move the median by at most 6/(2n) of a quantile,
    which the tolerance adds."""
    k = np.arange(size)
    smooth = 1000.0 * sigma * np.sin(2.0 * np.pi * k / 20_000)
    jumps = 500.0 * sigma * (k >= size // 3) - 500.0 * sigma * (k >= size // 2) + 500.0 * sigma * (k >= 3 * size // 4)
    noisy = smooth + jumps + np.random.default_rng(int(size + 1000 * sigma)).normal(0.0, sigma, size)
    outliers = 3 * 2 / (2.0 * size) / (2.0 * norm.pdf(norm.ppf(0.75)) * norm.ppf(0.75))
    assert abs(robust_noise_std(noisy) / sigma - 1.0) <= 4.0 * _robust_standard_error(size) + outliers


def test_robust_noise_std_is_unbiased_and_its_spread_is_its_standard_error():
    """Over 400 records: the mean within 4 standard errors of the mean, the records' spread within 15 % of the
    asymptotic standard error (the spread's own sampling error is 3.5 %)."""
    size = 4000
    estimates = np.array([robust_noise_std(np.random.default_rng(seed).standard_normal(size))
                          for seed in range(400)])
    se = _robust_standard_error(size)
    assert abs(estimates.mean() - 1.0) <= 4.0 * se / np.sqrt(estimates.size)
    assert estimates.std(ddof=1) == pytest.approx(se, rel=0.15)


def test_robust_noise_std_edge_cases():
    assert robust_noise_std(np.zeros(2)) == 0.0
    assert robust_noise_std(np.linspace(0.0, 5.0, 100)) == pytest.approx(0.0, abs=1e-12)  # a line is no noise
    with pytest.raises(IdentificationError, match="1-D"):
        robust_noise_std(np.zeros((3, 3)))
    with pytest.raises(IdentificationError, match="numbers"):
        robust_noise_std(["a", "b", "c"])


def test_the_quiet_span_estimator_is_the_sample_standard_deviation_and_scatters_less_than_the_robust_one():
    """On a quiet span (offset plus white noise) the sample standard deviation, ``ddof`` and ``axis`` as numpy's,
    is the efficient σ: over 200 spans of 1000 samples its spread is below half the robust estimator's (the
    robust one's asymptotic standard error is about 2.4 times the sample standard deviation's, 1/√(2n))."""
    rng = np.random.default_rng(5)
    spans = 3.0 + 2.0 * rng.standard_normal((200, 1000))
    assert np.array_equal(quiet_noise_std(spans, axis=1, ddof=1), np.std(spans, axis=1, ddof=1))
    assert quiet_noise_std(spans[0]) == np.std(spans[0])
    quiet = quiet_noise_std(spans, axis=1, ddof=1) / 2.0
    robust = np.array([robust_noise_std(x) for x in spans]) / 2.0
    assert abs(quiet.mean() - 1.0) <= 4.0 / np.sqrt(2.0 * 1000 * 200)
    assert quiet.std() < 0.5 * robust.std()


def _second_difference_std(x):
    """The compiled estimator fed as the trigger feeds it: the sum of the squared second differences of ``x``."""
    d2 = x[2:] - 2.0 * x[1:-1] + x[:-2]
    return second_difference_noise_std(float(np.sum(d2 * d2)), d2.size)


def test_the_second_difference_estimator_ignores_a_smooth_rise_but_not_a_jump():
    """σ = 1 on a half-sine rise of 1000 (second differences 1e-2 σ): within 4 of its standard errors (the RMS of
    n correlated second differences: about 1.2/√n relative). A jump J of 200 σ adds two second differences ±J, so
    the estimate grows to √(1 + 2J²/(6n)) ≈ 2.1 σ (the robust median moves by no more than its own error): the
    trigger's warm-up holds a smooth rise, never a jump."""
    n = 4000
    rng = np.random.default_rng(8)
    x = 1000.0 * np.sin(np.pi * np.arange(n) / (2 * n)) + rng.standard_normal(n)
    assert abs(_second_difference_std(x) - 1.0) <= 4.0 * 1.2 / np.sqrt(n)
    jumped = x + 200.0 * (np.arange(n) >= n // 2)
    assert _second_difference_std(jumped) == pytest.approx(np.sqrt(1.0 + 2.0 * 200.0 ** 2 / (6.0 * n)), rel=0.05)
    assert abs(robust_noise_std(jumped) - 1.0) <= 4.0 * _robust_standard_error(n) + 2.0 / n


# --------------------------------------------------------------------------------------------------------------
# pulses of noise-free forces at a threshold, and the one rule of stage B


def test_is_sustained_is_never_the_first_pulse_and_a_strict_inequality():
    assert not is_sustained(0, 100.0, 1.0)
    assert is_sustained(1, 2.01, 1.0) and not is_sustained(1, 2.0, 1.0)
    assert is_sustained(3, 1.6, 1.0, factor=1.5) and not is_sustained(3, 1.4, 1.0, factor=1.5)


def test_the_controller_judges_a_running_contact_against_the_first_pulse_from_the_sample_it_reaches_the_factor():
    """The compiled preset: sustained from ``held`` = SUSTAINED_CONTROL_FACTOR × the first pulse on (inclusive,
    the instant), never while the first pulse runs (NaN); the presets order the callers from the loop's early
    instant to the finished run's contact for good."""
    first = 2e-3
    assert not controller_sustained(SUSTAINED_CONTROL_FACTOR * first * (1.0 - 1e-9), first)
    assert controller_sustained(SUSTAINED_CONTROL_FACTOR * first, first)
    assert not controller_sustained(1.0, math.nan)
    assert SUSTAINED_CONTROL_FACTOR < SUSTAINED_FACTOR < SUSTAINED_WINDOW_FACTOR


def test_the_window_preset_marks_stage_b_against_the_first_pulse():
    """The absorber's window reads every pulse unmarked and asks SUSTAINED_WINDOW_FACTOR × the first: a pulse of
    4 × the first (zero to end, 10 samples against 40) is not yet stage B, one sample more is."""
    time = np.arange(1000, dtype=float)  # 1 s samples: the lengths compare exactly
    pulses = contact_pulses(time, _boxes(1000, [(100, 109), (300, 339), (500, 540)]), sustained_factor=math.inf)
    first = pulses[0].end - pulses[0].start
    marked = [is_sustained(k, p.end - p.start, first, SUSTAINED_WINDOW_FACTOR) for k, p in enumerate(pulses)]
    assert marked == [False, False, True]
    assert not any(p.sustained for p in pulses) and stage_b_start(pulses) is None


def _boxes(size, spans, height=10.0):
    force = np.zeros(size)
    for i0, i1 in spans:
        force[i0:i1] = height
    return force


def test_contact_pulses_of_rectangles_have_their_known_starts_ends_peaks_and_impulses():
    """Rectangles of height 10 N on samples [i0, i1): a pulse starts at the sample before its first positive one
    and ends at its first zero one, so it lasts i1 − i0 + 1 samples; bounces of 10 and 8 samples, then 22 (more than
    2 × 10 + 1): stage B at the third, and nothing reported after it."""
    dt = 1e-4
    spans = [(100, 109), (200, 207), (300, 321), (400, 500)]
    time = np.arange(1000) * dt
    force = _boxes(1000, spans)
    force[305] = 12.0  # the peak of the third
    pulses = contact_pulses(time, force)
    assert len(pulses) == 3
    for pulse, (i0, i1) in zip(pulses, spans, strict=False):
        assert pulse.start == pytest.approx((i0 - 1) * dt) and pulse.end == pytest.approx(i1 * dt)
    assert [p.sustained for p in pulses] == [False, False, True]
    assert pulses[2].peak_time == pytest.approx(305 * dt) and pulses[2].peak_force == 12.0
    assert pulses[0].impulse == pytest.approx(10.0 * (109 - 100) * dt)  # the trapezoid: ramps of half a sample each
    assert stage_b_start(pulses) == pytest.approx(299 * dt)


def test_a_pulse_just_short_of_the_factor_is_a_bounce_and_a_cut_one_counts_by_its_length_so_far():
    time = np.arange(1000) * 1e-4
    short = contact_pulses(time, _boxes(1000, [(100, 109), (300, 318)]))  # 19 samples against 10
    assert [p.sustained for p in short] == [False, False] and stage_b_start(short) is None
    cut = contact_pulses(time[:315], _boxes(315, [(100, 109), (300, 400)]))  # runs off the end after 16 samples
    assert [p.sustained for p in cut] == [False, False]
    long_cut = contact_pulses(time[:330], _boxes(330, [(100, 109), (300, 400)]))
    assert [p.sustained for p in long_cut] == [False, True]
    assert contact_pulses(time, _boxes(1000, [(0, 5)]))[0].start == 0.0  # a record that starts in contact
    with pytest.raises(IdentificationError, match="equal length"):
        contact_pulses(time, np.zeros(999))


# --------------------------------------------------------------------------------------------------------------
# the noise-aware pulse detector and stage B of its pulses


def _triangles(size, pulses, amplitude=200.0):
    """Triangles (start, rise, fall) [samples] of ``amplitude`` [N]."""
    k = np.arange(size, dtype=float)
    force = np.zeros(size)
    for start, rise, fall in pulses:
        force += np.interp(k, [start, start + rise, start + rise + fall], [0.0, amplitude, 0.0], left=0.0, right=0.0)
    return force


#: two 20-sample bounces, then a pulse that rises in 10 samples and falls in 200 (stage B at 800)
BOUNCES = [(500, 10, 10), (600, 10, 10), (800, 10, 200)]


@pytest.mark.parametrize("seed", [None, *range(5)])
def test_detected_pulses_start_peak_and_end_at_their_known_samples(seed):
    """σ = 1 N on 200 N triangles (levels 5 and 2 σ): each edge sample is 20 σ from the next, so the first sample
    above the detection level is the one after the start, the peak the apex (or, on the slow side at 1 N per
    sample, a sample whose clean force is within the spread of two noise samples of it, 6 σ); the zero sample is the
    start itself or, where noise lifts it above the release level, one of the few before it; an edge that falls 20 N
    per sample ends
    at its last sample or within the hold after it, the slow one (1 N per sample) where it is within 4 σ of the
    release level."""
    size, sigma = 3000, 1.0
    force = clean = _triangles(size, BOUNCES)
    if seed is not None:
        force = clean + np.random.default_rng(seed).normal(0.0, sigma, size)
    assert detection_levels(sigma, 200.0) == (5.0, 2.0)
    spans = detect_pulses(force, sigma)
    assert len(spans) == 3
    for span, (start, rise, _) in zip(spans, BOUNCES, strict=True):
        assert span.first == start + 1
        apex = start + rise
        assert span.peak == apex if seed is None else clean[span.peak] >= clean[apex] - 6.0 * sigma
        assert apex <= span.peak <= apex + 6  # never on the steep side (20 N per sample)
        assert start - 3 <= span.zero <= start
        assert span.complete
    for span, (start, _, _) in zip(spans[:2], BOUNCES[:2], strict=True):
        assert start + 20 <= span.end <= start + 20 + HOLD
    assert 1004 <= spans[2].end <= 1010 + HOLD  # the clean fall reaches 2 ± 4 N at 1004 ... 1012
    assert sustained_index(spans, size=size) == 2
    assert sustained_start(spans, size=size) == spans[2].zero


def test_stage_b_of_detected_pulses_is_the_first_longer_than_the_factor_times_the_longest_before():
    """Stage B needs a pulse longer than SUSTAINED_FACTOR × the longest before it (zero to end), counts a pulse
    still running by its length so far, and is never the first pulse."""
    size = 3000
    bounce = 20  # zero to end of a (start, 10, 10) triangle
    level = int(SUSTAINED_FACTOR * bounce)
    for fall, expected in ((level - 10, None), (level - 9, 1)):  # zero → end: exactly the factor's length, one more
        spans = detect_pulses(_triangles(size, [(500, 10, 10), (600, 10, fall)]), 1.0)
        assert spans[1].end - spans[1].zero == fall + 10
        assert sustained_index(spans, size=size) == expected
        assert sustained_start(spans, size=size) == (None if expected is None else 600)
    running = detect_pulses(_triangles(size, BOUNCES)[:900], 1.0)  # the long pulse cut 100 samples after its start
    assert running[2].end == -1 and sustained_start(running, size=900) == 800
    early = detect_pulses(_triangles(size, BOUNCES)[:830], 1.0)  # ... 30 samples after: not yet
    assert sustained_index(early, size=830) is None
    assert sustained_index(running, size=900, factor=10.0) is None  # 100 samples is not 10 × 20
    first_running = [PulseSpan(zero=0, first=1, peak=5, end=-1), PulseSpan(zero=100, first=101, peak=105, end=900)]
    assert sustained_index(first_running, size=1000) is None


# --------------------------------------------------------------------------------------------------------------
# sub-sample onsets and separations


def _power_foot(size, onset, exponent, rise, peak=1000.0, fall=60.0):
    """F = peak·((t − onset)/rise)^exponent for onset < t <= onset + rise, then a straight fall to zero in ``fall``
    samples; zero before the onset."""
    s = np.arange(size, dtype=float) - onset
    up = peak * (np.clip(s, 0.0, None) / rise) ** exponent
    down = peak * np.clip(1.0 - (s - rise) / fall, 0.0, None)
    return np.where(s <= 0.0, 0.0, np.where(s <= rise, up, down))


@pytest.mark.parametrize("exponent", [0.5, 1.0, 1.5, 2.0])
def test_a_noise_free_power_law_foot_is_timed_to_the_scan_step(exponent):
    """The foot model holds exactly (every exponent on the grid): the onset within one fine scan step of the truth,
    a separation (the same pulse reversed in time) likewise, and both with the least standard error."""
    onset = 200.37
    force = _power_foot(600, onset, exponent, 60.0)
    (span,) = detect_pulses(force, 0.0)
    time, std = onset_index(force, span, 0.0)
    assert abs(time - onset) <= GRID_STEP and std == MIN_STD
    mirrored = force[::-1].copy()
    (span,) = detect_pulses(mirrored, 0.0)
    time, std = separation_index(mirrored, span, 0.0)
    assert abs(time - (599 - onset)) <= GRID_STEP and std == MIN_STD


def _edge_errors(exponent, rise, sigma, *, separation=False, seeds=150):
    """(errors, stated standard errors) [samples] of the onsets (or separations) of a power-law foot in σ =
    ``sigma`` white noise on a 1000 N peak, its onset uniform within a sample, over ``seeds`` seeds."""
    errors, stds = [], []
    for seed in range(seeds):
        rng = np.random.default_rng(seed)
        onset = 200.0 + rng.uniform(0.0, 1.0)
        force = _power_foot(600, onset, exponent, rise) + rng.normal(0.0, sigma, 600)
        if separation:
            force, onset = force[::-1].copy(), 599.0 - onset
        (span,) = detect_pulses(force, sigma)
        time, std = (separation_index if separation else onset_index)(force, span, sigma)
        errors.append(time - onset)
        stds.append(std)
    return np.array(errors), np.array(stds)


@pytest.mark.parametrize("exponent, rise, sigma, separation", [
    (1.0, 60.0, 1.0, False),  # a linear foot at 0.1 % noise
    (1.5, 60.0, 1.0, False),  # a Hertzian foot at 0.1 % noise
    (0.5, 60.0, 5.0, False),  # a steep foot at 0.5 % noise
    (1.5, 30.0, 10.0, False),  # a short Hertzian foot at 1 % noise
    (1.5, 60.0, 1.0, True),  # the end of a Hertzian unloading at 0.1 % noise
])
def test_onsets_and_separations_lie_within_two_stated_standard_errors_in_most_seeds(exponent, rise, sigma,
                                                                                     separation):
    """Coverage: at least 85 % of 150 seeds within 2 σ (95 % for a Gaussian error; the binomial spread of the
    fraction is 2 %); and the stated errors not inflated to get there: their median at most twice the errors' RMS,
    or the least error MIN_STD where the errors are smaller still."""
    errors, stds = _edge_errors(exponent, rise, sigma, separation=separation)
    assert np.mean(np.abs(errors) <= 2.0 * stds) >= 0.85
    assert np.median(stds) <= max(MIN_STD, 2.0 * np.sqrt(np.mean(errors ** 2)))


@pytest.mark.parametrize("separation", [False, True])
def test_the_onset_of_a_gentle_foot_in_noise_is_covered_by_its_stated_standard_error(separation):
    """A Hertzian foot rising over 120 samples at 2 % noise: 2 stated standard errors cover the truth in at least
    85 % of seeds, as on the steep feet above (a flat foot's set of trial times reaches beyond the fine grid, which
    spans two samples either side of the coarse minimum: both grids are searched)."""
    errors, stds = _edge_errors(1.5, 120.0, 20.0, separation=separation)
    assert np.mean(np.abs(errors) <= 2.0 * stds) >= 0.85


# --------------------------------------------------------------------------------------------------------------
# turning points: the batch vertex and the controller's ring-buffer vertex


def _cusp(size, apex, left, right, peak=1000.0):
    """A peak of ``peak`` [N] at the fractional sample ``apex`` with curvature ``left`` before and ``right`` after
    it [N/sample²] (a contact that unloads along another line than it loads), floored at zero."""
    x = np.arange(size, dtype=float) - apex
    return np.maximum(peak - np.where(x < 0.0, left, right) * x * x, 0.0)


def _ring(force, size=256):
    """A ring buffer of ``size`` samples holding ``force`` as sample counts 1..n (the controller's layout)."""
    ring = np.zeros(size)
    for count, value in enumerate(force, start=1):
        ring[count % size] = value
    return ring


def _ring_vertex(force, sigma, drop):
    """The controller's timing of the maximum of ``force`` [samples from 0] and its standard error: fed up to the
    sample that confirms it (HOLD samples more than ``drop`` below the maximum), as ``control.windows.push`` does."""
    top = int(np.argmax(force))
    below = (np.arange(force.size) > top) & (force < force[top] - drop)
    confirm = int(np.argmax(np.convolve(below, np.ones(HOLD))[:force.size] >= HOLD)) + 1  # a sample count
    at, timing = ring_vertex(_ring(force[:confirm]), float(top + 1), float(confirm), sigma, 1.0, drop)
    return at - 1.0, timing


def _batch_vertex(force, sigma, peak=1000.0):
    return vertex(force, int(np.argmax(force)), 1, peak, sigma)


@pytest.mark.parametrize("apex, left, right", [(150.37, 0.1, 0.5), (150.81, 2.0, 0.1), (149.5, 0.3, 0.3)])
def test_a_noise_free_cusp_is_timed_within_the_stated_error_by_both_timers(apex, left, right):
    """F = F_E − a±·(t − E)² holds exactly for both fits: the batch vertex within its scan step (its least stated
    error), the ring vertex (whole samples) within its half sample, and the two within their errors of each other."""
    force = _cusp(300, apex, left, right)
    time, std, value = _batch_vertex(force, 0.0)
    assert abs(time - apex) <= std == GRID_STEP and value == pytest.approx(1000.0, abs=1e-3)
    at, timing = _ring_vertex(force, 1e-6, 5.0)
    assert abs(at - apex) <= timing == 0.5
    assert abs(at - time) <= std + timing


def test_a_ring_vertex_confirmed_within_its_edge_states_the_whole_window_as_its_error():
    """A steep unloading side (2 N/sample²) passes the 5 N confirmation level two samples after the apex: the fit
    cannot bracket the apex by EDGE samples, and says so with the window's length as the error."""
    force = _cusp(300, 150.37, 0.1, 2.0)
    at, timing = _ring_vertex(force, 1e-6, 5.0)
    assert timing >= 2 * EDGE + 3 and abs(at - 150.37) <= timing


def test_the_batch_vertex_refuses_a_turning_point_of_the_other_sign_and_too_few_samples_before_it():
    """The fit keeps at least VERTEX_HALF_MIN samples on each side; a window that would reach beyond the data is cut
    at its edge (the apex is still found)."""
    force = _cusp(300, 150.37, 0.1, 2.0)
    assert vertex(force, 150, -1, 1000.0, 0.0) is None  # a maximum asked for as a minimum
    assert vertex(-force, 150, -1, 1000.0, 0.0)[0] == pytest.approx(150.37, abs=GRID_STEP)
    assert vertex(force[150 - VERTEX_HALF_MIN + 1:], VERTEX_HALF_MIN - 1, 1, 1000.0, 0.0) is None
    cut = vertex(force[140:], 10, 1, 1000.0, 0.0)  # the fit would reach 50 samples back
    assert cut is not None and abs(cut[0] + 140 - 150.37) <= cut[1]


@pytest.mark.parametrize("sigma, left, right", [(1.0, 0.1, 0.3), (3.0, 0.1, 1.0), (3.0, 1.0, 0.1), (3.0, 0.3, 0.3)])
def test_both_timers_time_noisy_cusps_within_their_stated_errors_of_the_truth_and_of_each_other(sigma, left, right):
    """On 150 seeded cusps (apex uniform within a sample, 1000 N peak, σ = 1 or 3 N; the ring's confirmation level
    DETECT_SIGMAS·σ, as the controller's): each timer within 2 of its stated standard errors of the truth, and the
    two within 2 of their combined errors of each other, in at least 85 % of seeds (95 % for Gaussian errors;
    binomial spread 2 %); the batch vertex answers for nearly every peak, and the ring vertex brackets nearly every
    apex (its whole-window fallback error would make any agreement vacuous)."""
    seeds, refused = 150, 0
    batch = ring = both = fallback = 0
    z_batch, z_ring = [], []
    for seed in range(seeds):
        rng = np.random.default_rng(seed)
        apex = 150.0 + rng.uniform(0.0, 1.0)
        force = _cusp(300, apex, left, right) + rng.normal(0.0, sigma, 300)
        found = _batch_vertex(force, sigma)
        if found is None:
            refused += 1
            continue
        time, std, _ = found
        at, timing = _ring_vertex(force, sigma, 5.0 * sigma)
        batch += abs(time - apex) <= 2.0 * std
        ring += abs(at - apex) <= 2.0 * timing
        both += abs(at - time) <= 2.0 * np.hypot(std, timing)
        fallback += timing >= 2 * EDGE + 3
        z_batch.append(abs(time - apex) / std)
        z_ring.append(abs(at - apex) / timing)
    answered = seeds - refused
    assert refused <= 0.02 * seeds and fallback <= 0.05 * answered
    # nor inflated to get there: the median |error| / stated error is 0.67 for Gaussian errors
    assert min(np.median(z_batch), np.median(z_ring)) >= 0.3
    assert min(batch, ring, both) >= 0.85 * answered


def test_one_sign_convention_for_both_timers():
    """+1 times a maximum: a side that bends up rules it out, a flat one does not; −1 the reverse (NaN rules out
    nothing: the fit's own guards refuse a degenerate side)."""
    assert wrong_curvature(0.5, 1) and not wrong_curvature(-0.5, 1) and not wrong_curvature(0.0, 1)
    assert wrong_curvature(-0.5, -1.0) and not wrong_curvature(0.5, -1.0)
    assert not wrong_curvature(math.nan, 1)
    force = _cusp(300, 150.37, 0.3, 0.3)
    assert _batch_vertex(force, 0.0)[0] == pytest.approx(150.37, abs=GRID_STEP)
    assert vertex(force, 150, -1, 1000.0, 0.0) is None
    at, _ = ring_vertex(_ring(force[:170]), 151.0, 170.0, 1e-6, 1.0, 5.0)
    minimum, _ = ring_vertex(_ring(1000.0 - force[:170]), 151.0, 170.0, 1e-6, -1.0, 5.0)
    assert at == minimum and abs(at - 1.0 - 150.37) <= 0.5


def test_the_ring_vertex_reads_the_ring_modulo_its_size():
    """The same cusp late in a record (sample counts past several turns of the ring) is timed at the same place
    relative to its apex, and a ring smaller than the fit's reach only shortens the fit."""
    force = _cusp(300, 150.37, 0.1, 0.5)
    early = ring_vertex(_ring(force[:170]), 151.0, 170.0, 1e-6, 1.0, 5.0)
    shift = 1000
    late_force = np.r_[np.zeros(shift), force[:170]]
    late = ring_vertex(_ring(late_force), 151.0 + shift, 170.0 + shift, 1e-6, 1.0, 5.0)
    assert late[0] - shift == early[0] and late[1] == early[1]
    short = ring_vertex(_ring(force[:170], size=32), 151.0, 170.0, 1e-6, 1.0, 5.0)
    assert abs(short[0] - 1.0 - 150.37) <= short[1]


def test_a_cusp_is_timed_where_one_parabola_leans_to_its_flatter_side():
    """A contact unloads along a stiffer line than it loads: the force peak has a curvature of its own on each side.
    The two-sided ring vertex finds it to the sample; one least-squares parabola over the same samples does not."""
    k = np.arange(1, 141, dtype=float)
    force = 1000.0 - np.where(k < 100.0, 0.1, 2.0) * (k - 100.0) ** 2  # apex at sample count 100
    at, timing = ring_vertex(_ring(force), 100.0, 110.0, 1.0, 1.0, 20.0)
    assert at == 100.0 and timing <= 1.0
    window = np.arange(90, 111, dtype=float)  # the same stretch after the apex, and as far before it
    c2, c1, _ = np.polyfit(window, force[window.astype(int) - 1], 2)
    assert abs(-c1 / (2.0 * c2) - 100.0) > 3.0


def test_the_ring_timing_error_of_a_noisy_flat_extremum_is_stated_honestly():
    """A shallow minimum in noise: the ring vertex lands within two stated standard errors of the truth in most runs,
    and the standard error of a flat extremum is several samples (not the half sample of a sharp one)."""
    rng = np.random.default_rng(3)
    hits, timings = 0, []
    runs = 60
    counts = np.arange(1, 201, dtype=float)
    for _ in range(runs):
        apex = 150.0 + rng.uniform(-0.5, 0.5)
        force = -400.0 + 0.02 * (counts - apex) ** 2 + 10.0 * rng.standard_normal(200)
        extreme = float(np.argmin(force) + 1)
        beyond = (counts > extreme) & (force > force[int(extreme) - 1] + 50.0)
        confirm = float(np.argmax(np.convolve(beyond, np.ones(HOLD))[:200] >= HOLD) + 1)
        at, timing = ring_vertex(_ring(force[:int(confirm)]), extreme, confirm, 10.0, -1.0, 50.0)
        hits += abs(at - apex) <= 2.0 * timing + 0.5
        timings.append(timing)
    assert hits >= 0.85 * runs
    assert np.median(timings) > 2.0


def test_the_batch_vertex_reads_no_sample_beyond_its_reach():
    """The reach that keys the segment's cache of a vertex (VERTEX_HALF_MAX + smoothing_margin) bounds the samples
    the vertex reads: changing every sample beyond it leaves the answer bit for bit."""
    rng = np.random.default_rng(4)
    force = _cusp(600, 150.37, 0.01, 0.02) + rng.normal(0.0, 1.0, 600)
    width = 4
    reach = 150 + VERTEX_HALF_MAX + smoothing_margin(width)
    changed = force.copy()
    changed[reach:] = rng.normal(0.0, 100.0, force.size - reach)
    assert vertex(force, 150, 1, 1000.0, 1.0, width) == vertex(changed, 150, 1, 1000.0, 1.0, width)


def test_turning_points_of_a_noisy_oscillation_alternate_at_the_known_samples():
    """A damped cosine of period 100 samples (extrema at 25 + 50·m, a maximum for even m, moved earlier by the
    decay) in σ = 1 noise, four seeds: the turning points alternate, start with a maximum, and each lies within a
    quarter period of the truth (the smoothed force is flat there); the batch vertex then times at least 85 % of
    them within 2 of its stated errors (95 % for Gaussian errors; 48 turning points)."""
    n, period, decay = 600, 100.0, 800.0
    k = np.arange(n, dtype=float)
    clean = 500.0 + 400.0 * np.exp(-k / decay) * np.cos(2.0 * np.pi * (k - 25.0) / period)
    omega = 2.0 * np.pi / period
    hits = timed_count = 0
    for seed in range(4):
        force = clean + np.random.default_rng(seed).standard_normal(n)
        found = turning_points(force, 0, n, 1.0, 5)
        signs = [sign for _, sign, _ in found]
        assert signs[0] == 1 and all(a == -b for a, b in zip(signs, signs[1:], strict=False)) and len(found) >= 11
        for centre, sign, swing in found:
            m = round((centre - 25.0) / (period / 2.0))  # the m-th extremum of the cosine
            truth = 25.0 + m * period / 2.0 + np.arctan(-1.0 / (omega * decay)) / omega
            assert abs(centre - truth) < period / 4.0 and (sign == 1) == (m % 2 == 0)
            timed = vertex(force, centre, sign, swing, 1.0, 5)
            if timed is not None:
                timed_count += 1
                hits += abs(timed[0] - truth) <= 2.0 * timed[1]
    assert timed_count >= 44 and hits >= 0.85 * timed_count


# --------------------------------------------------------------------------------------------------------------
# the segment: trigger events, bounds, offsets and noise, pulses and their turning points

RATE = 50e3


def _impact(size, starts, rng, *, offset=100.0, sigma=1.0):
    """Force [N] and acceleration [m/s²] of an impact: a 1000 N half-sine of 200 samples from ``starts[0]``, a 500 N
    bounce of 100 samples from ``starts[1]`` (and more 1000 N pulses from any later starts), on offsets of 100 N and
    3 m/s² with white noise of ``sigma`` and 0.1 m/s²."""
    force = _half_sine(size, starts[0], 200.0, 1000.0) + _half_sine(size, starts[1], 100.0, 500.0)
    for start in starts[2:]:
        force += _half_sine(size, start, 200.0, 1000.0)
    acceleration = 3.0 - force / 30.0 + rng.normal(0.0, 0.1, size)
    return offset + force + rng.normal(0.0, sigma, size), acceleration


def test_trigger_events_cross_the_batch_blocks_as_one_block_would():
    """An impact astride the first TRIGGER_BLOCK boundary: the events up to its close are those of one block (and
    those reported after it too), at the known samples of its two pulses."""
    size = 100_000
    assert 65_000 < segment.TRIGGER_BLOCK < 66_000
    force, _ = _impact(size, [65000.3, 65400.6, 90000.0], np.random.default_rng(0))
    events = [tuple(int(v) for v in row) for row in segment.trigger_events(force, RATE, floor=segment.TRIGGER_FLOOR)]
    whole = _events(force, floor=segment.TRIGGER_FLOOR, quiet=int(segment.QUIET_TIME * RATE),
                    longest=int(segment.MAX_DURATION * RATE), baseline=trigger.baseline_samples(RATE))
    assert events == whole[:len(events)]
    close = [code for code, _ in events].index(trigger.EVENT_CLOSE)
    known = [65001, 65167, 65201, 65484, 65501]  # ceil of the noise-free trigger, past-peak and end crossings
    assert [code for code, _ in events[:close]] == [1, 4, 2, 4, 2]
    assert all(abs(sample - k) <= 1 for (_, sample), k in zip(events[:close], known, strict=True))
    assert events[close][1] >= 65501 + segment.QUIET_TIME * RATE - 1


def test_segment_bounds_keep_the_pre_trigger_samples_and_end_after_the_close():
    size = 100_000
    force, _ = _impact(size, [65000.3, 65400.6, 90000.0], np.random.default_rng(0))
    start, stop, ends, pre = segment.segment_bounds(force, RATE)
    events = segment.trigger_events(force, RATE, floor=segment.TRIGGER_FLOOR)
    trig, close = events[0, 1], events[events[:, 0] == trigger.EVENT_CLOSE][0, 1]
    assert (start, stop, pre) == (trig - segment.PRE_SAMPLES, close + 1, segment.PRE_SAMPLES)
    assert ends == [int(i) for c, i in events[1:5]]  # the pulse ends and past-peak events of the first impact
    in_contact, _ = _impact(4000, [-0.5, 400.0], np.random.default_rng(1), offset=0.0)
    start, stop, _, pre = segment.segment_bounds(in_contact, RATE)
    assert (start, stop, pre) == (0, 4000, 0)  # fired at sample 0, no quiet spell within the record


def test_a_prepared_segment_removes_the_offsets_and_finds_the_known_pulses():
    """Offsets of 100 N and 3 m/s² are removed (the pre-trigger samples average to zero), the noise is the white
    noise's σ to within 4 of the standard errors of a standard deviation of the pre-trigger samples, σ/√(2n); the
    two pulses start at their known samples: the first detected sample after the onset and no later than where the
    clean half-sine passes the detection level (25 N: FLOOR_FRACTION of the peak, times DETECT_SIGMAS) by 4 σ; their
    zero samples (at or below the release level, 10 N) no later than where it passes that level by 4 σ."""
    size = 9000
    starts = [6000.3, 6400.6]
    force, acceleration = _impact(size, starts, np.random.default_rng(2))
    start, stop, _, pre = segment.segment_bounds(force, RATE)
    seg = segment.segment_of(force, acceleration, RATE, 1.0, start, stop, pre)
    n = seg.pre_samples
    assert segment.PRE_SAMPLES - segment.GUARD_SAMPLES - 40 <= n <= segment.PRE_SAMPLES - segment.GUARD_SAMPLES
    assert abs(seg.force[:n].mean()) < 1e-9 and abs(seg.acceleration[:n].mean()) < 1e-9
    assert abs(seg.noise_force - 1.0) <= 4.0 / np.sqrt(2 * n)
    assert abs(seg.noise_acceleration - 0.1) <= 4.0 * 0.1 / np.sqrt(2 * n)
    assert seg.start_time == pytest.approx(1.0 + start / RATE)
    assert len(seg.pulses) == 2 and all(p.complete for p in seg.pulses)
    detect, release = detection_levels(seg.noise_force, float(np.max(seg.force)))
    assert (detect, release) == pytest.approx((25.0, 10.0), rel=0.01)
    for pulse, (known, duration, peak) in zip(seg.pulses, [(starts[0], 200.0, 1e3), (starts[1], 100.0, 500.0)],
                                              strict=True):
        onset = known - start

        def rise(level, duration=duration, peak=peak):  # samples the clean pulse takes to pass level + 4 σ
            return duration / np.pi * np.arcsin((level + 4.0) / peak)

        assert onset < pulse.first <= onset + rise(detect) + 1
        assert onset - 3 <= pulse.zero <= onset + rise(release)
        assert abs(pulse.end - (onset + duration)) <= 2


def test_the_turning_points_of_known_pulses_lie_within_their_stated_errors():
    """The apexes of the two half-sines (start + half their duration) timed by the segment's extrema: 2 stated
    standard errors cover them in at least 85 % of 200 peaks (50 seeds, apexes uniform within a sample)."""
    size, hits, peaks = 9000, 0, 0
    for seed in range(50):
        rng = np.random.default_rng(seed)
        starts = [6000.0 + rng.uniform(0.0, 1.0), 6400.0 + rng.uniform(0.0, 1.0)]
        force, acceleration = _impact(size, starts, rng)
        start, stop, _, pre = segment.segment_bounds(force, RATE)
        times, stds, stage_b, _ = segment.extrema(segment.segment_of(force, acceleration, RATE, 0.0, start, stop, pre))
        assert times.size == 2 and not stage_b.any()
        truth = np.array([starts[0] + 100.0, starts[1] + 50.0]) - start
        hits += int(np.sum(np.abs(times - truth) <= 2.0 * stds))
        peaks += 2
    assert hits >= 0.85 * peaks


def test_quantum_lag_correlation_and_the_inverted_channel_hint():
    rng = np.random.default_rng(4)
    noise = rng.standard_normal(20_000)
    assert segment.quantum(0.37 + 0.01 * np.round(50.0 * noise)) == pytest.approx(0.01)
    assert segment.quantum(noise) == 0.0
    n = noise.size
    assert abs(segment.lag_correlation(noise)) <= 4.0 / np.sqrt(n)
    filtered = np.zeros(n)
    for i in range(1, n):  # AR(1) with coefficient 0.8: lag-1 correlation 0.8, standard error √((1 − 0.64)/n)
        filtered[i] = 0.8 * filtered[i - 1] + noise[i]
    assert abs(segment.lag_correlation(filtered) - 0.8) <= 4.0 * np.sqrt(0.36 / n)
    assert segment.lag_correlation(np.full(10, 3.0)) == 0.0
    inverted = -_half_sine(4000, 2000.0, 200.0, 1000.0) + rng.standard_normal(4000)
    assert "flip-force" in str(segment.no_impact(inverted))
    assert "expected at least one contact pulse" in str(segment.no_impact(rng.standard_normal(4000)))


# --------------------------------------------------------------------------------------------------------------
# the contact law of the early answer


def test_the_contact_law_family_gives_hertz_and_kelvin_voigt_and_no_force_apart():
    delta = np.array([-1e-4, 0.0, 1e-4, 4e-4, 9e-4])
    rate = np.array([0.5, 0.5, 0.5, -0.2, 0.1])
    scale = 1e-4
    hertz = contact_law.law(delta, rate, 2e3, 0.0, 1.5, 0.0, scale)
    assert hertz == pytest.approx([0.0, 0.0, 2e3, 2e3 * 8.0, 2e3 * 27.0])
    voigt = contact_law.law(delta, rate, 2e3, 50.0, 1.0, 0.0, scale)
    assert voigt == pytest.approx([0.0, 0.0, 2e3 + 25.0, 8e3 - 10.0, 18e3 + 5.0])
    tiny = contact_law.law(np.array([1e-30]), np.array([1.0]), 0.0, 1.0, 1.0, -0.5, scale)
    assert tiny[0] == pytest.approx(contact_law.X_FLOOR ** -0.5)  # x^m with m < 0 stays finite at the edge


def _fit_case():
    """Samples of the family generated at known unknowns x = (V0, w, d0, k, c, n, m)."""
    rng = np.random.default_rng(5)
    x = np.array([2.0, 0.3, 1e-5, 4e3, 30.0, 1.4, 0.6])
    tau = np.linspace(0.0, 4e-3, 40)
    i_f, jf = rng.uniform(0.0, 1e-3, 40) * tau, rng.uniform(0.0, 0.1, 40) * tau
    da, va = 0.1 * tau ** 2, 0.2 * tau
    return x, tau, i_f, jf, da, va


def test_overlaps_and_residuals_of_the_family_at_its_own_unknowns():
    """δ = V0·τ + g·τ²/2 − w·IF − D2 + d0 and δ' = V0 + g·τ − w·JF − V2; forces generated by the law at the true
    unknowns leave zero residuals but the onset's and the prior's rows, which are δ and d0 over their errors."""
    x, tau, i_f, jf, da, va = _fit_case()
    g, scale, sigma = 9.81, 1e-3, 2.0
    delta, rate = contact_law.overlaps(x, tau, i_f, jf, da, va, g)
    assert delta == pytest.approx(x[0] * tau + g * tau ** 2 / 2 - x[1] * i_f - da + x[2])
    assert rate == pytest.approx(x[0] + g * tau - x[1] * jf - va)
    force = contact_law.law(delta, rate, x[3], x[4], x[5], x[6], scale)
    onset, s1, shift = np.array([1e-3, 2e-4, 3e-7]), 1e-6, 1e-5
    out = contact_law.residuals(x, tau, i_f, jf, da, va, force + sigma, g, scale, sigma, onset, s1, shift)
    assert out[:-2] == pytest.approx(np.ones(tau.size))  # one σ above the law everywhere
    assert out[-2] == pytest.approx((x[0] * 1e-3 + g * 1e-6 / 2 - x[1] * 2e-4 - 3e-7 + x[2]) / s1)
    assert out[-1] == pytest.approx(x[2] / (x[0] * shift))


def test_the_jacobian_of_the_residuals_is_their_derivative():
    """Central differences of the residuals, step 1e-6 of each unknown: truncation O(h²) and rounding far below
    1e-5 of the largest column entry."""
    x, tau, i_f, jf, da, va = _fit_case()
    args = (tau, i_f, jf, da, va, np.full(tau.size, 500.0), 9.81, 1e-3, 2.0, np.array([1e-3, 2e-4, 3e-7]), 1e-6,
            1e-5)
    jac = contact_law.jacobian(x, *args)
    for j in range(x.size):
        h = 1e-6 * max(abs(x[j]), 1e-6)
        up, down = x.copy(), x.copy()
        up[j] += h
        down[j] -= h
        numeric = (contact_law.residuals(up, *args) - contact_law.residuals(down, *args)) / (2.0 * h)
        assert numeric == pytest.approx(jac[:, j], rel=1e-5, abs=1e-5 * np.max(np.abs(jac[:, j])))


@pytest.mark.parametrize("periods, amplitude", [(1.5, 1.4), (0.9, 5.0)])
def test_a_mains_hum_in_the_pre_trigger_is_found_and_extrapolated_and_white_noise_shows_none(periods, amplitude):
    """A 50 Hz hum over 1.5 periods at 10 σ, or 0.9 of one at 37 σ (σ: its amplitude's standard error): it comes
    back within 30 % over 5000 samples in at least 40 of 50 draws and is left alone in the others (60 Hz fits
    about as well); white noise shows none."""
    from impactometer.signals.noise import mains_hum

    fs = 50e3
    n = int(periods * fs / 50.0)
    t = np.arange(5000) / fs
    errors, found_in_noise = [], 0
    for seed in range(50):
        rng = np.random.default_rng(seed)
        hum = amplitude * np.sin(2 * np.pi * 50.0 * t + rng.uniform(0.0, 2.0 * np.pi))
        found = mains_hum(2.0 + hum[:n] + rng.normal(0.0, 3.0, n), fs, t.size)
        errors.append(np.nan if found is None else np.max(np.abs(found - hum)) / amplitude)
        found_in_noise += mains_hum(2.0 + rng.normal(0.0, 3.0, n), fs, t.size) is not None
    errors = np.array(errors)
    assert np.isnan(errors).sum() <= 10 and np.nanmax(errors) < 0.3
    assert found_in_noise == 0
