"""Sensor model: sampling, anti-alias designs, noise, ADC, gravity, pre-trigger, batch vs single."""

import numpy as np
import pytest

from impactometer.errors import ParameterError
from impactometer.model import simulate
from impactometer.recording import Recording
from impactometer.rig import Scenario, get_rig
from impactometer.sensors import CAUSAL_PERIODS, anti_alias_delay, apply_sensors, quantise, record, record_batch

SCENARIO = Scenario(mass=30.0, velocity=2.0, pressure_gauge=200e3)
FS = 50e3


@pytest.fixture(scope="module")
def clean():
    return simulate(SCENARIO, duration=0.03, sample_rate=FS)


def test_plain_sampling_equals_the_simulation(clean):
    rec = record(SCENARIO, duration=0.03, anti_alias=False)
    np.testing.assert_allclose(rec.contact_force, clean.contact_force, rtol=1e-9, atol=1e-6)
    np.testing.assert_allclose(rec.piston_acceleration, clean.a2, rtol=1e-9, atol=1e-6)
    assert rec.metadata["mass_kg"] == 30.0 and rec.metadata["velocity_m_s"] == 2.0
    assert rec.metadata["pressure_gauge_Pa"] == 200e3 and rec.metadata["contact_law"] == "hysteretic"


def test_zero_phase_anti_alias_keeps_pulse_timing_and_size(clean):
    rec = record(SCENARIO, duration=0.03, anti_alias="zero-phase")
    assert np.argmax(rec.contact_force) == np.argmax(clean.contact_force)
    # the pulses are a few ms long: the 20 kHz low-pass changes their peak by well under 1 %
    assert rec.contact_force.max() == pytest.approx(clean.contact_force.max(), rel=0.01)
    assert np.trapezoid(rec.contact_force, rec.time) == pytest.approx(
        np.trapezoid(clean.contact_force, clean.time), rel=0.005)


def test_causal_anti_alias_delays_both_channels_by_the_stated_delay(clean):
    rec = record(SCENARIO, duration=0.03, anti_alias="causal")
    delay = anti_alias_delay("causal", FS)
    assert delay == pytest.approx(CAUSAL_PERIODS / 2 / FS)
    lag = round(delay * FS)
    for measured, truth in ((rec.contact_force, clean.contact_force), (rec.piston_acceleration, clean.a2)):
        shifted = truth[:-lag]
        err = np.abs(measured[lag:] - shifted).max() / np.abs(truth).max()
        assert err < 0.03
        assert np.argmax(measured) - np.argmax(truth) == lag
    assert rec.metadata["anti_alias_delay_s"] == pytest.approx(delay)
    assert record(SCENARIO, duration=0.005).metadata["anti_alias"] == "causal"  # the default design


@pytest.mark.parametrize("design", ["zero-phase", "causal"])
def test_anti_alias_rejects_content_above_nyquist_and_passes_the_band(design):
    fs_in, factor = 400e3, 8
    fs_out = fs_in / factor
    t = np.arange(40000) / fs_in
    def amplitude(freq):
        rec = apply_sensors({"contact_force": np.sin(2 * np.pi * freq * t)}, input_rate=fs_in, sample_rate=fs_out,
                            anti_alias=design)
        return np.sqrt(2 * np.mean(rec.contact_force[200:-200] ** 2))
    assert amplitude(0.1 * fs_out) == pytest.approx(1.0, abs=0.01)
    assert amplitude(0.8 * fs_out) < 0.03   # would alias to 0.2·fs_out at full amplitude
    rec = apply_sensors({"contact_force": np.sin(2 * np.pi * 0.8 * fs_out * t)}, input_rate=fs_in,
                        sample_rate=fs_out, anti_alias=False)
    assert np.sqrt(2 * np.mean(rec.contact_force ** 2)) > 0.9


def test_noise_has_the_requested_level_and_is_seeded(clean):
    levels = {"contact_force": 0.02, "piston_acceleration": 0.05}
    clean_rec = record(SCENARIO, duration=0.03, anti_alias=False)
    noisy = record(SCENARIO, duration=0.03, anti_alias=False, noise=levels, seed=7)
    for name, level in levels.items():
        x = clean_rec.channel(name)
        rms = np.sqrt(np.mean(x ** 2))
        assert np.std(noisy.channel(name) - x) == pytest.approx(level * rms, rel=0.06)  # 1501 samples: ±2 %/σ
    again = record(SCENARIO, duration=0.03, anti_alias=False, noise=levels, seed=7)
    other = record(SCENARIO, duration=0.03, anti_alias=False, noise=levels, seed=8)
    np.testing.assert_array_equal(noisy.contact_force, again.contact_force)
    assert not np.allclose(noisy.contact_force, other.contact_force)
    assert noisy.metadata["noise"] == levels and noisy.metadata["seed"] == 7


def test_scalar_noise_applies_to_force_and_acceleration_only():
    rec = record(SCENARIO, duration=0.01, noise=0.05, seed=1, extra_channels=["pressure_lower"])
    assert set(rec.metadata["noise"]) == {"contact_force", "piston_acceleration"}
    smooth = record(SCENARIO, duration=0.01, extra_channels=["pressure_lower"])
    np.testing.assert_array_equal(rec.channel("pressure_lower"), smooth.channel("pressure_lower"))


@pytest.mark.parametrize("design", ["none", "causal", "zero-phase"])
def test_pre_trigger_samples_have_zero_force_and_acceleration(design):
    rec = record(SCENARIO, duration=0.01, pre_trigger=0.002, anti_alias=design,
                 extra_channels=["piston_displacement", "pressure_lower"])
    assert rec.start_time == pytest.approx(-0.002)
    assert rec.time[100] == pytest.approx(0.0, abs=1e-12)
    before = rec.time < -3 / FS  # the zero-phase filter rings a few samples ahead of the contact step
    peak = np.abs(rec.contact_force).max()
    tol = 0.0 if design != "zero-phase" else 1e-3 * peak
    assert np.abs(rec.contact_force[before]).max() <= tol
    assert np.abs(rec.piston_acceleration[before]).max() <= (0.0 if design != "zero-phase"
                                                             else 1e-3 * np.abs(rec.piston_acceleration).max())
    for name in ("piston_displacement", "pressure_lower"):   # held at their equilibrium value
        x = rec.channel(name)
        np.testing.assert_allclose(x[before], x[0], rtol=0, atol=1e-3 * np.ptp(x))


def test_adc_quantises_to_levels_and_clips_at_the_range():
    bits, full = 8, 2000.0
    rec = record(SCENARIO, duration=0.02, adc_bits=bits, adc_range={"contact_force": full})
    step = 2 * full / 2 ** bits
    codes = (rec.contact_force + full) / step
    np.testing.assert_allclose(codes, np.round(codes), atol=1e-6)
    assert rec.contact_force.max() == pytest.approx(full - step)   # the stand's pulses exceed 2 kN: clipped
    assert np.unique(rec.contact_force).size <= 2 ** bits
    # auto range on the acceleration: ±1.25·max|a|, no clipping
    ref = record(SCENARIO, duration=0.02)
    a_step = 2.5 * np.abs(ref.piston_acceleration).max() / 2 ** bits
    assert np.abs(rec.piston_acceleration - ref.piston_acceleration).max() <= a_step / 2 + 1e-9


def test_quantise_clip_only_without_bits():
    np.testing.assert_array_equal(quantise(np.array([-5.0, 0.3, 5.0]), -1.0, 2.0, None), [-1.0, 0.3, 2.0])


def test_accelerometer_with_gravity_reads_specific_force():
    kin = record(SCENARIO, duration=0.01, pre_trigger=0.001)
    grav = record(SCENARIO, duration=0.01, pre_trigger=0.001, include_gravity=True)
    np.testing.assert_allclose(grav.piston_acceleration, kin.piston_acceleration - get_rig().gravity, rtol=0, atol=1e-9)
    assert grav.metadata["acceleration_includes_gravity"] is True


def test_batch_equals_single_records_with_the_same_seeds():
    masses = np.array([20.0, 35.0])
    batch = record_batch(masses, 2.0, 200e3, duration=0.01, noise=0.02, seeds=[3, 4], pre_trigger=0.001)
    for m, seed, rec in zip(masses, [3, 4], batch, strict=False):
        single = record(Scenario(mass=m, velocity=2.0, pressure_gauge=200e3), duration=0.01, noise=0.02,
                        seed=seed, pre_trigger=0.001)
        np.testing.assert_allclose(rec.contact_force, single.contact_force, rtol=1e-9, atol=1e-9)
        assert rec.metadata["mass_kg"] == m
    spawned = record_batch(masses, 2.0, 200e3, duration=0.01, noise=0.02, seed=11)
    assert not np.allclose(spawned[0].contact_force[:50], spawned[1].contact_force[:50])


@pytest.mark.parametrize("rate", [5e3, 1e6])
def test_extreme_sample_rates(rate):
    rec = record(SCENARIO, sample_rate=rate, duration=0.005)
    assert rec.sample_rate == rate and len(rec) == int(round(0.005 * rate)) + 1
    assert rec.contact_force.max() > 1000.0


def test_apply_sensors_degrades_a_recording_without_decimation():
    rng = np.random.default_rng(5)
    rec = Recording(sample_rate=10e3, channels={"contact_force": 100 + rng.normal(size=300)}, start_time=-0.001,
                    metadata={"mass_kg": 12.0})
    out = apply_sensors(rec, noise=0.1, seed=1)
    assert out.metadata["mass_kg"] == 12.0 and out.start_time == -0.001 and out.sample_rate == 10e3
    assert "anti_alias" not in out.metadata and out.metadata["noise"] == {"contact_force": 0.1}
    assert np.std(out.contact_force - rec.contact_force) == pytest.approx(0.1 * np.sqrt(np.mean(
        rec.contact_force[10:] ** 2)), rel=0.15)


@pytest.mark.parametrize("call, match", [
    (lambda: record(SCENARIO, sample_rate=1e3), r"sample_rate must be >= 5000 \[Hz\]"),
    (lambda: record(SCENARIO, noise=-0.1), "noise must be >= 0"),
    (lambda: record(SCENARIO, noise={"pressure": 0.1}), "noise names unknown channel"),
    (lambda: record(SCENARIO, anti_alias="sinc"), "anti_alias must be True, False or one of"),
    (lambda: record(SCENARIO, extra_channels=["voltage"]), "extra_channels: unknown channel 'voltage'"),
    (lambda: record(SCENARIO, adc_bits=1), r"adc_bits must be an integer >= 2"),
    (lambda: record(SCENARIO, adc_bits=12, adc_range={"contact_force": (5.0, 1.0)}), "high > low"),
    (lambda: record(SCENARIO, pre_trigger=-1.0), "pre_trigger must be"),
    (lambda: record(SCENARIO, duration=0.0), "duration must be > 0"),
    (lambda: record("30kg"), "scenario must be a Scenario"),
    (lambda: record_batch([1.0, 2.0], 2.0, 2e5, duration=0.005, seeds=[1]), "one entry per scenario"),
    (lambda: apply_sensors({"contact_force": np.zeros(10)}), "input_rate must be given"),
    (lambda: apply_sensors({"contact_force": np.zeros(10)}, input_rate=10e3, sample_rate=3e3),
     "divide the input rate"),
])
def test_bad_options_raise_parameter_error(call, match):
    with pytest.raises(ParameterError, match=match):
        call()
