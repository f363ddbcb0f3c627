"""Recording: validation, time base, units, metadata helpers, inspection of pulses and stage B."""

import numpy as np
import pytest

from impactometer.errors import RecordingError
from impactometer.identify.inspection import inspect_recording
from impactometer.io import read_recording, write_recording
from impactometer.recording import Recording
from impactometer.rig import Scenario
from impactometer.sensors import record


def test_time_base_and_properties():
    rec = Recording(sample_rate=1e3, channels={"contact_force": [0.0, 1.0, 2.0, 1.0]}, start_time=-0.002,
                    metadata={"mass_kg": "12.5"})
    np.testing.assert_allclose(rec.time, [-0.002, -0.001, 0.0, 0.001])
    assert rec.duration == pytest.approx(0.004) and len(rec) == 4
    assert rec.truth("mass_kg") == 12.5 and rec.truth("velocity_m_s") is None
    assert rec.unit("contact_force") == "N"
    assert rec.with_metadata(velocity_m_s=2.0).truth("velocity_m_s") == 2.0 and "velocity_m_s" not in rec.metadata
    with pytest.raises(RecordingError, match=r"channel 'piston_acceleration' is missing; channels found: "
                                             r"\['contact_force'\]"):
        _ = rec.piston_acceleration


def test_from_a_regular_time_vector():
    t = -0.001 + np.arange(20) / 4e3
    rec = Recording.from_time(t, {"contact_force": np.ones(20)}, metadata={"mass_kg": 2.0})
    assert rec.sample_rate == pytest.approx(4e3, rel=1e-12) and rec.start_time == pytest.approx(-0.001)
    np.testing.assert_allclose(rec.time, t, atol=1e-15)
    with pytest.raises(RecordingError, match="time must be regularly sampled"):
        Recording.from_time(np.r_[t[:10], t[10:] + 1e-4], {"contact_force": np.ones(20)})
    with pytest.raises(RecordingError, match="time must increase strictly"):
        Recording.from_time(t[::-1], {"contact_force": np.ones(20)})
    with pytest.raises(RecordingError, match="expected equal lengths"):
        Recording.from_time(t, {"contact_force": np.ones(19)})


@pytest.mark.parametrize("kwargs, match", [
    (dict(sample_rate=0.0), r"sample_rate must be a number within \[1, 1e\+08\] Hz, got 0.0"),
    (dict(sample_rate=-5.0), "sample_rate must be a number within"),
    (dict(sample_rate=float("inf")), "sample_rate must be a number within"),
    (dict(sample_rate=True), "sample_rate must be a number within"),
    (dict(sample_rate=1e12), "sample_rate must be a number within"),
    (dict(sample_rate=np.float64(1e-3)), r"within \[1, 1e\+08\] Hz, got 0.001$"),
    (dict(start_time=float("nan")), "start_time must be a number within"),
    (dict(metadata={"mass_kg": "heavy"}), "metadata mass_kg must be a number with an optional mass unit"),
    (dict(metadata={"velocity_m_s": [1, 2]}), r"metadata velocity_m_s must be a number, got \[1, 2\]"),
    (dict(metadata={"pressure_gauge_Pa": -1.0}), r"metadata pressure_gauge_Pa must be within \[0, 1e\+08\] Pa"),
    (dict(channels={}), "non-empty mapping"),
    (dict(channels={"contact_force": [1.0, np.inf, 2.0]}), r"non-finite sample \(inf\) at index 1"),
    (dict(channels={"contact_force": [1.0, 2.0], "piston_acceleration": [1.0]}), "equal lengths"),
    (dict(channels={"contact_force": [[1.0, 2.0]]}), "1-D"),
    (dict(channels={"contact_force": ["a", "b"]}), "must hold numbers"),
    (dict(metadata=[1, 2]), "metadata must be a mapping"),
])
def test_validation(kwargs, match):
    args = dict(sample_rate=1e3, channels={"contact_force": [1.0, 2.0]}) | kwargs
    with pytest.raises(RecordingError, match=match):
        Recording(**args)


def test_read_and_write_round_trip(tmp_path):
    rec = Recording(sample_rate=2e3, channels={"contact_force": [0.0, 3.0, 1.0]}, metadata={"mass_kg": 4.0})
    path = write_recording(rec, tmp_path / "r.h5")
    back = read_recording(path)
    np.testing.assert_array_equal(back.contact_force, rec.contact_force)
    assert back.truth("mass_kg") == 4.0


@pytest.fixture(scope="module")
def noisy():
    """The stiff stand: about 9 separated pulses in 100 ms."""
    return record(Scenario(mass=30.0, velocity=2.0), "drop-stand-stiff", duration=0.1, noise=0.02, seed=2,
                  pre_trigger=0.005, anti_alias="none")


def test_inspection_finds_the_separated_pulses_of_the_simulation(noisy):
    clean = record(Scenario(mass=30.0, velocity=2.0), "drop-stand-stiff", duration=0.1, pre_trigger=0.005,
                   anti_alias="none")
    result = inspect_recording(noisy)
    reference = inspect_recording(clean)
    # noise must not split or merge any pulse
    assert len(reference.pulses) >= 8 and len(result.pulses) == len(reference.pulses)
    period = 1 / noisy.sample_rate
    for p, q in zip(result.pulses, reference.pulses, strict=False):
        assert abs(p.peak_time - q.peak_time) < 0.5e-3              # noisy peaks sit on a flat top
        assert abs(p.start - q.start) <= 0.3e-3 + period             # 5 σ detection starts a little later
        assert p.impulse == pytest.approx(q.impulse, rel=0.03)
    # first contact is at t = 0; the stiff stand's Kelvin-Voigt force jumps there, and the sample at t = 0 holds half
    # the jump (model.fast.share_jump), so the pulse starts at the last quiet sample, one period before
    assert reference.pulses[0].start == pytest.approx(-period, abs=1e-12)
    assert reference.stage_b_start is None and not any(p.sustained for p in reference.pulses)
    # the white-noise estimate recovers the requested 2 % of the force RMS
    rms = np.sqrt(np.mean(clean.contact_force[clean.time >= 0] ** 2))
    assert result.channels["contact_force"].noise == pytest.approx(0.02 * rms, rel=0.1)
    assert result.truth == {"mass_kg": 30.0, "velocity_m_s": 2.0, "pressure_gauge_Pa": 200e3}


def test_inspection_removes_a_pre_trigger_offset(noisy):
    shifted = Recording(sample_rate=noisy.sample_rate, start_time=noisy.start_time,
                        channels={"contact_force": noisy.contact_force + 250.0})
    result = inspect_recording(shifted)
    assert result.force_offset == pytest.approx(250.0, abs=10.0)
    assert len(result.pulses) == len(inspect_recording(noisy).pulses)


def test_inspection_reports_sustained_contact():
    t = np.arange(4000) / 20e3
    force = np.where(t < 0.01, np.sin(np.pi * t / 0.01), 0.0) * 1e3
    force = force + np.where(t > 0.05, 500.0 * (1 - np.exp(-(t - 0.05) / 0.005)), 0.0)
    result = inspect_recording(Recording(sample_rate=20e3, channels={"contact_force": force}))
    assert [p.sustained for p in result.pulses] == [False, True]
    assert result.stage_b_start == pytest.approx(0.05, abs=2e-4)
    assert result.to_dict()["stage_b_start_s"] == result.stage_b_start


def test_inspection_without_a_force_channel():
    rec = Recording(sample_rate=1e3, channels={"pressure_lower": np.linspace(3e5, 4e5, 50)})
    result = inspect_recording(rec)
    assert result.pulses == [] and result.peak_force is None and result.channels["pressure_lower"].unit == "Pa"
    with pytest.raises(RecordingError, match="recording must be a Recording"):
        inspect_recording({"contact_force": [1.0]})


def test_plot_marks_the_pulses(noisy):
    fig = inspect_recording(noisy).plot(noisy)
    force_axis = fig.axes[0]
    assert len(force_axis.patches) == len(inspect_recording(noisy).pulses)
    assert force_axis.get_ylabel() == "contact force [kN]"  # as every figure of the package labels it
    assert fig.axes[1].get_ylabel() == "piston acceleration [m/s²]"
