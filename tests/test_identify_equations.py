"""The equations of the robust identification against the simulated truth: force extrema where the overlap turns,
gaps that are not flights, stage B, filtered channels refused, answers without information refused, calibration."""

import numpy as np
import pytest

from impactometer.errors import IdentificationError
from impactometer.filters import filter_recording
from impactometer.identify.peak_to_peak import equations, identify, identify_arrays
from impactometer.identify.peak_to_peak.segment import GUARD_SAMPLES, check_channels, segment_bounds, segment_of
from impactometer.identify.peak_to_peak.streaming import StreamingIdentifier
from impactometer.model import simulate
from impactometer.rig import Scenario, get_rig
from impactometer.sensors import apply_sensors, record

FS = 50e3


def prepared(rec):
    f, a, fs = check_channels(rec.contact_force, rec.piston_acceleration, rec.sample_rate)
    start, stop, _, pre = segment_bounds(f, fs)
    return segment_of(f, a, fs, rec.start_time, start, stop, pre, {})


@pytest.mark.parametrize("stand,law", [("drop-stand-pad", "hysteretic"), ("drop-stand-stiff", "hunt-crossley")])
def test_force_extrema_are_where_the_overlap_turns(stand, law):
    """Noise-free: at every turning point of the force found, the relative velocity of mass and rod is zero to
    within what the stated time error and the relative acceleration make of it (a hysteretic contact's peaks
    are cusps; Hunt-Crossley's damping puts the force peak a little ahead of the overlap's)."""
    rig = get_rig(stand, contact=law)
    scenario = Scenario(mass=30.0, velocity=2.0, pressure_gauge=2e5)
    truth = simulate(scenario, rig, duration=0.05, sample_rate=1e6)
    rec = record(scenario, rig, duration=0.05, pre_trigger=0.02)
    seg = prepared(rec)
    eqs, _, _ = equations(seg)
    assert eqs.extrema.size >= 3
    delay = rec.metadata["anti_alias_delay_s"]
    rate = truth.v1 - truth.v2
    accel = np.abs(truth.a1 - truth.a2)
    lag = 0.0 if law == "hysteretic" else 2e-4  # Hunt-Crossley: α·δ of the overlap at the peak, about 0.1 ms
    for index, std in zip(eqs.extrema, eqs.extremum_std, strict=True):
        t = seg.time_of(index) - delay
        allowed = np.interp(t, truth.time, accel) * ((2 * std + 0.5) / FS + lag) + 1e-3
        assert abs(np.interp(t, truth.time, rate)) <= allowed


def test_a_gap_without_flight_gives_no_onset_row():
    """Pad stand, 30 kg at 2 m/s: the pad unloads to zero force but the mass never leaves it (the overlap stays
    above 0.8 mm), so the landing is not at zero overlap: no onset row is used, and the answer from the force
    extrema of stage B is right to 0.5 % / 0.2 %."""
    rig = get_rig("drop-stand-pad")
    scenario = Scenario(mass=30.0, velocity=2.0, pressure_gauge=2e5)
    truth = simulate(scenario, rig, duration=0.05)
    assert (truth.u1 - truth.u2)[truth.time > 0.004].min() > 5e-4
    res = identify(record(scenario, rig, duration=0.05, pre_trigger=0.02))
    used = res.details["equations"]
    assert used["onsets"] == 0 and used["stage_b_extrema"] >= 5 and used["stage_b_samples"] > 1000
    assert abs(res.mass / 30.0 - 1) < 5e-3 and abs(res.velocity / 2.0 - 1) < 2e-3


@pytest.mark.parametrize("law", ["hysteretic", "kelvin-voigt", "hunt-crossley"])
def test_pad_stand_noise_free_round_trip(law):
    """Every contact law on the pad stand, 50 ms after contact: mass within 1 %, velocity within 0.3 %, and the
    answer says which equations it used."""
    res = identify(record(Scenario(mass=20.0, velocity=1.5, pressure_gauge=1e5), get_rig("drop-stand-pad", contact=law),
                          duration=0.05, pre_trigger=0.02))
    assert abs(res.mass / 20.0 - 1) < 0.01 and abs(res.velocity / 1.5 - 1) < 3e-3
    used = res.details["equations"]
    assert set(used) >= {"onsets", "extrema", "stage_b_extrema", "separations", "stage_b_samples"}
    assert res.to_dict()["equations"]["extrema"] == used["extrema"]


def test_streaming_updates_during_stage_b_and_ends_with_the_batch_answer():
    rec = record(Scenario(mass=30.0, velocity=2.0, pressure_gauge=2e5), get_rig("drop-stand-pad"), duration=0.06,
                 noise=0.02, seed=4, pre_trigger=0.02)
    ident = StreamingIdentifier(rec.sample_rate, start_time=rec.start_time)
    got = []
    f, a = rec.contact_force, rec.piston_acceleration
    for k in range(0, f.size, 64):
        got.extend(ident.push(f[k:k + 64], a[k:k + 64]))
    final = ident.finish()
    assert final == identify(rec)
    stage_b = [e for e in got if e.details["equations"]["stage_b_extrema"] > 0]
    assert len(stage_b) >= 2
    times = [e.available_at for e in got]
    assert times == sorted(times)
    assert all(np.isfinite(e.mass_std) and e.mass_std > 0 and np.isfinite(e.velocity_std) for e in got)


@pytest.mark.parametrize("cfc", [60, 180, 600, 1000])
def test_filtered_channels_are_refused_by_the_robust_variant(cfc):
    """A CFC filter spreads the onsets ahead of the contact and colours the noise: the robust variant refuses
    (from the metadata, and from the correlated pre-trigger noise of bare arrays), the paper variant answers."""
    rec = record(Scenario(mass=30.0, velocity=2.0, pressure_gauge=2e5), get_rig(), duration=0.05, noise=0.02,
                 seed=1, pre_trigger=0.02)
    filtered = filter_recording(rec, cfc)
    with pytest.raises(IdentificationError, match="unfiltered"):
        identify(filtered)
    with pytest.raises(IdentificationError, match="low-pass filtered"):
        identify_arrays(filtered.contact_force, filtered.piston_acceleration, FS, filtered.start_time)
    ident = StreamingIdentifier(FS, start_time=filtered.start_time)
    assert ident.push(filtered.contact_force, filtered.piston_acceleration) == []
    with pytest.raises(IdentificationError, match="low-pass filtered"):
        ident.finish()
    try:
        paper = identify(filtered, variant="paper")
    except IdentificationError:
        return  # eq. (4) may have no positive mass on a heavily smoothed record
    assert np.isfinite(paper.mass) and paper.mass > 0


def test_white_noise_through_a_daq_anti_alias_filter_is_accepted():
    """Noise low-passed at 0.4 fs (a DAQ's anti-alias filter) is nearly white: identified, not refused."""
    from scipy import signal

    rec = record(Scenario(mass=30.0, velocity=2.0, pressure_gauge=2e5), get_rig(), duration=0.05, pre_trigger=0.02)
    rng = np.random.default_rng(3)
    sos = signal.butter(8, 0.8, output="sos")
    f = rec.contact_force + signal.sosfilt(sos, rng.normal(0, 50.0, rec.contact_force.size))
    a = rec.piston_acceleration + signal.sosfilt(sos, rng.normal(0, 10.0, f.size))
    res = identify_arrays(f, a, FS, rec.start_time)
    assert abs(res.mass / 30.0 - 1) < 0.05


def _slow_contact(amplitude, acceleration_ratio, *, seed=0, fs=2e6):
    """White noise of unit σ on both channels, then a half-sine contact pulse 4 ms long: at 2 MHz its foot rises
    over hundreds of samples, as a real contact's does."""
    rng = np.random.default_rng(seed)
    start, width = 20000, 8000
    k = np.arange(start + 3 * width)
    pulse = np.where((k >= start) & (k < start + width), np.sin(np.pi * (k - start) / width), 0.0)
    force = amplitude * pulse + rng.normal(0.0, 1.0, k.size)
    acceleration = acceleration_ratio * amplitude * pulse + rng.normal(0.0, 1.0, k.size)
    return force, acceleration, start


def test_the_pre_trigger_statistics_stop_at_the_foot_of_the_rise_at_high_sample_rates():
    """The trigger fires a fixed time into the rise: at 2 MHz hundreds of samples after first contact, far more than
    the 32 samples of the guard. The foot read as noise made white noise look low-pass filtered (correlation 0.80
    here before); the statistics now stop where the rise starts."""
    force, acceleration, start = _slow_contact(150.0, 3.0)
    first, stop, _, pre = segment_bounds(force, 2e6)
    assert first + pre - start > 3 * GUARD_SAMPLES  # the trigger fired far into the rise
    seg = segment_of(force, acceleration, 2e6, 0.0, first, stop, pre, {})
    assert abs(seg.noise_correlation) < 0.05
    assert first + seg.pre_samples <= start + 16  # no more than the first samples of the (yet flat) foot


def test_the_trigger_fires_on_a_contact_that_rises_over_thousands_of_samples():
    """At 2 MHz a baseline of 256 samples followed a slow rise, its running σ growing with it, and the trigger
    never fired ("no impact found"); the baseline now spans the same time at every rate above 50 kHz."""
    force, _, start = _slow_contact(100.0, 1.0)
    first, _, _, pre = segment_bounds(force, 2e6)
    assert 0 < first + pre - start < 400


def test_a_two_megahertz_record_with_white_noise_is_identified():
    """Refused before as "low-pass filtered (correlation 0.86)" while 0.5 and 1 MHz were answered."""
    scenario = Scenario.from_height(mass=30.0, height=0.2, pressure_gauge=200e3)
    sim = simulate(scenario, duration=0.05, sample_rate=4e6)
    quiet = np.zeros(40000)  # 10 ms before first contact
    rec = apply_sensors({"contact_force": np.r_[quiet, sim.contact_force], "piston_acceleration": np.r_[quiet, sim.a2]},
                        input_rate=4e6, sample_rate=2e6, start_time=-0.01, noise=0.01, seed=0)
    answer = identify(rec)
    assert abs(answer.mass - 30.0) < 3.0 * answer.mass_std and abs(answer.mass / 30.0 - 1) < 0.05
    assert abs(answer.velocity - scenario.velocity) < 3.0 * answer.velocity_std
    assert abs(prepared(rec).noise_correlation) < 0.05


def test_an_answer_without_information_is_refused_not_given():
    """Heavy noise on a short record: whatever comes back states a standard error below half the answer and
    covers the truth within 4 of them; otherwise an IdentificationError."""
    rig = get_rig("drop-stand-pad")
    for seed in range(3):
        rec = record(Scenario(mass=50.0, velocity=1.0, pressure_gauge=2e4), rig, duration=0.03, noise=0.1,
                     seed=seed, pre_trigger=0.01)
        try:
            res = identify(rec)
        except IdentificationError as exc:
            assert "determine" in str(exc) or "pulses" in str(exc)
            continue
        for answer in (res, res.early):
            if answer is None:
                continue
            assert answer.mass_std < 0.5 * answer.mass and abs(answer.mass - 50.0) < 4 * answer.mass_std


def test_standard_errors_are_calibrated():
    """Stiff stand, 30 kg at 2 m/s, 5 % noise, 24 noise draws: the truth lies within ±2σ in most draws (a
    calibrated σ covers it in 95 %), and the errors are neither much smaller nor much larger than σ."""
    rig = get_rig("drop-stand-stiff")
    z = []
    for seed in range(24):
        res = identify(record(Scenario(mass=30.0, velocity=2.0, pressure_gauge=2e5), rig, duration=0.05,
                              noise=0.05, seed=seed, pre_trigger=0.02))
        z.append(((res.mass - 30.0) / res.mass_std, (res.velocity - 2.0) / res.velocity_std))
    z = np.abs(np.array(z))
    assert np.mean(z < 2, axis=0).min() >= 0.8
    assert 0.4 < float(np.median(z)) < 1.2


@pytest.mark.parametrize("judged_scatter, inflated", [(0.0, True), (5.0, False)])
def test_readings_the_data_cannot_tell_apart_widen_the_answer(monkeypatch, judged_scatter, inflated):
    """The flights reading keeps an onset the stage-B reading drops; where both fit the turning points as well,
    the flights' estimate is kept and the difference of the two readings joins its covariance (whether that gap
    was a flight, or a pad that kept a set, is not in the data); where the stage-B reading fits worse, nothing."""
    from impactometer.identify.details import Nuisances, RowsUsed
    from impactometer.identify.peak_to_peak import robust

    def solution(theta, std, onsets, scatter):
        return robust.Solution(theta=np.array(theta), cov=np.diag(np.square(std)), chi2=1.0, dof=3,
                               nuisances=Nuisances(), used=RowsUsed(onsets=onsets), gain=np.zeros((2, 0)),
                               tau=np.zeros(0), scatter=scatter)

    flights = solution([1.43, 0.045], [0.011, 0.002], 1, 0.0)
    judged = solution([1.50, 0.050], [0.095, 0.006], 0, judged_scatter)
    monkeypatch.setattr(robust, "_solve_rows", lambda *a, judge_by_stage_b, **k: judged if judge_by_stage_b
                        else flights)
    eqs = robust.Equations(onsets=np.array([500.0]), onset_std=np.array([1.0]), extrema=np.arange(5.0) * 100,
                           extremum_std=np.ones(5), stage_b=np.array([False, False, False, True, True]))
    got = robust.solve_rows(None, eqs, noise_force=1.0, noise_acceleration=1.0, pre_samples=100, lag_max=1e-4)
    np.testing.assert_array_equal(got.theta, flights.theta)
    diff = flights.theta - judged.theta
    expected = flights.cov + np.outer(diff, diff) if inflated else flights.cov
    np.testing.assert_allclose(got.cov, expected)
    if inflated:  # the truth of the stage-B reading now lies within 2 standard errors of the answer
        assert abs(got.theta[0] - judged.theta[0]) <= 2.0 * np.sqrt(got.cov[0, 0])
        # and the answer names both readings (V0, M1): a refusal, or --json, can say what the two gave
        assert got.readings == {"flights": (1.43, pytest.approx(1 / 0.045)), "set": (1.50, pytest.approx(20.0))}
    else:
        assert got.readings is None


def test_normal_inverse_keeps_a_parameter_beside_a_tight_prior():
    """(JᵀJ)⁻¹ where one column is 1e13 times the others (a tight prior row): the equilibrated form keeps the
    small parameters' variances, where the pseudo-inverse of JᵀJ cuts them to zero."""
    from impactometer.identify.peak_to_peak.covariance import normal_inverse

    rng = np.random.default_rng(3)
    scale = np.array([1.0, 2.0, 1e13])
    unit = rng.standard_normal((50, 3))
    jac = unit * scale
    exact = np.linalg.inv(unit.T @ unit) / np.outer(scale, scale)
    assert np.allclose(np.diag(normal_inverse(jac)), np.diag(exact), rtol=1e-8)
    assert np.diag(np.linalg.pinv(jac.T @ jac))[0] < 1e-3 * exact[0, 0]  # what the old form gave


def test_contact_phase_combination_never_extrapolates():
    """Two estimates whose stated cross-covariance their own covariances cannot hold (correlation above 1) or
    one that is not finite are not combined (None): the agnostic answer stands."""
    from impactometer.identify.peak_to_peak.early import combine

    tau = np.array([0.01, 0.02])
    gain = np.array([[1.0, 0.0], [0.0, 1.0]])
    cov = np.diag([1e-6, 1e-6])  # far smaller than the shared acceleration noise below implies
    first, second = (np.array([1.0, 0.05]), cov, (gain, tau)), (np.array([1.01, 0.051]), cov, (gain, tau))
    assert combine(first, second, noise_acceleration=1e4, pre_samples=0, dt=2e-5) is None
    nan = (np.full(2, np.nan), np.full((2, 2), np.inf), (gain, tau))
    assert combine(first, nan, noise_acceleration=1.0, pre_samples=0, dt=2e-5) is None
    theta, _ = combine(first, second, noise_acceleration=1e-3, pre_samples=0, dt=2e-5)
    assert np.all(theta >= np.minimum(first[0], second[0]) - 1e-12)
    assert np.all(theta <= np.maximum(first[0], second[0]) + 1e-12)


@pytest.mark.parametrize("law", ["kelvin-voigt", "hysteretic"])
def test_contact_phase_option_answers_and_covers_on_noisy_pad_records(law):
    """``contact_phase=True`` on noisy pad records: every record answered (a hysteretic pad, whose contact phase
    gives no answer, keeps the agnostic one and says so), and the truth within 4 standard errors: no standard
    error collapsed to nothing, no combination thrown far from both of its parts."""
    for mass, velocity, pressure, seed in [(20.0, 1.0, 115e3, 1), (10.0, 1.0, 210e3, 3), (10.0, 1.0, 400e3, 3)]:
        rec = record(Scenario(mass=mass, velocity=velocity, pressure_gauge=pressure),
                     get_rig("drop-stand-pad", contact=law), duration=0.05, noise=0.05, seed=seed, pre_trigger=0.02)
        res = identify(rec, contact_phase=True)
        info = res.details["equations"]["contact_phase"]
        assert info["combined"] is (info["branches"] != "none")
        assert abs(res.mass - mass) < 4 * res.mass_std and abs(res.velocity - velocity) < 4 * res.velocity_std


def _pad_impact(seed=0):
    """30 kg from 0.2 m on the pad stand, 1 % noise, 20 ms pre-trigger (the reference truth record)."""
    return record(Scenario.from_height(mass=30.0, height=0.2, pressure_gauge=200e3), sample_rate=FS, duration=0.1,
                  noise=0.01, seed=seed, pre_trigger=0.02)


@pytest.mark.parametrize("seed", [0, 1])
def test_a_drifting_acceleration_lies_within_the_standard_errors(seed):
    """A drift of 1 m/s² across the record (120 ms): M1 = 30.34 ± 0.043 kg before (7.8 standard errors off, no
    warning); the answer that estimates an offset and a drift moves away from it, and the difference joins σ."""
    rec = _pad_impact(seed)
    a = rec.piston_acceleration + np.linspace(0.0, 1.0, rec.piston_acceleration.size)
    res = identify_arrays(rec.contact_force, a, FS, rec.start_time)
    assert abs(res.mass - 30.0) < 3.0 * res.mass_std
    assert abs(res.velocity - rec.truth("velocity_m_s")) < 3.0 * res.velocity_std
    assert res.details["equations"]["slow_errors"]["drift_m_s3"] > 2.0  # 8.3 m/s³ put in
    intact = identify(rec)  # the same impact without drift keeps its calibrated standard error
    assert intact.mass_std < res.mass_std / 2.0 and abs(intact.mass - 30.0) < 3.0 * intact.mass_std


@pytest.mark.parametrize("seed", [0, 1])
def test_an_offset_without_pre_trigger_lies_within_the_standard_errors(seed):
    """No pre-trigger to measure it: a 0.5 m/s² offset gave M1 1.1 % high at 12 standard errors; the offset is now
    estimated beside the answer, and what it may do is in σ."""
    rec = _pad_impact(seed)
    first = int(np.flatnonzero(rec.time >= 0.0)[0])
    res = identify_arrays(rec.contact_force[first:], rec.piston_acceleration[first:] + 0.5, FS)
    assert abs(res.mass - 30.0) < 3.0 * res.mass_std
    assert abs(res.velocity - rec.truth("velocity_m_s")) < 3.0 * res.velocity_std
    assert res.details["pre_trigger_samples"] == 0


@pytest.mark.parametrize("frequency, level", [(50.0, 0.002), (50.0, 0.003), (50.0, 0.01), (60.0, 0.01)])
def test_mains_hum_that_the_pre_trigger_shows_is_removed(frequency, level):
    """Hum of 0.2 % of the peak put M1 three standard errors off, 0.3 % and more was refused; the hum the
    pre-trigger shows is removed and the truth lies within 3 standard errors."""
    rec = _pad_impact()
    t, a = rec.time, rec.piston_acceleration
    hum = level * np.max(np.abs(a)) * np.sin(2 * np.pi * frequency * t + 0.3)
    res = identify_arrays(rec.contact_force, a + hum, FS, rec.start_time)
    assert abs(res.mass - 30.0) < 3.0 * res.mass_std
    assert abs(res.velocity - rec.truth("velocity_m_s")) < 3.0 * res.velocity_std


def test_a_pre_trigger_that_is_not_at_rest_is_named():
    rec = _pad_impact()
    t, a = rec.time, rec.piston_acceleration
    ramp = np.where(t < 0.0, 40.0 * (t - t[0]) / -t[0], 40.0)  # 40 m/s² over the pre-trigger, then level
    with pytest.raises(IdentificationError, match="the pre-trigger is not at rest: piston_acceleration moves by"):
        identify_arrays(rec.contact_force, a + ramp, FS, rec.start_time)
