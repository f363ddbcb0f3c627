"""Records of another machine (a guided drop weight, load cell and accelerometer in the striker, 100 kHz, ringing;
:mod:`drop_weight`): refused in one line, the same pulses in ``inspect`` and ``identify``, ringing no pulse, and
an answer that the recorded impulse contradicts refused."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from drop_weight import drop_weight
from impactometer.errors import IdentificationError
from impactometer.identify.inspection import inspect_recording
from impactometer.identify.peak_to_peak import identify
from impactometer.identify.plausibility import check_answer
from impactometer.io import write_recording
from impactometer.signals.noise import robust_noise_std
from impactometer.signals.pulses import detect_pulses
from test_cli_simulate import run


def flipped(rec):
    return replace(rec, channels={**rec.channels, "piston_acceleration": -rec.piston_acceleration})


@pytest.fixture(scope="module")
def striker():
    """20 kg at 3 m/s onto a crushable specimen: one pulse of about 6 ms, the striker flies clear."""
    return drop_weight(mass=20.0, velocity=3.0, stiffness=4e7)


@pytest.fixture(scope="module")
def ringing():
    """5 kg at 2 m/s onto a soft specimen: a 1.2 kN pulse whose ringing swings ±35 N after it."""
    return drop_weight(mass=5.0, velocity=2.0, stiffness=3e5, seed=1)


def test_the_simulated_striker_keeps_its_momentum_balance(striker):
    """The simulator's own check: the force's impulse over the contact is the striker's momentum change, and the
    contact lasts milliseconds."""
    f, a = striker.contact_force, striker.piston_acceleration
    contact = striker.time >= 0.0
    impulse = np.trapezoid(f[contact], dx=1 / striker.sample_rate)
    change = -np.trapezoid(a[contact], dx=1 / striker.sample_rate)
    assert impulse == pytest.approx(20.0 * change, rel=0.02)
    assert 3.0 < change < 2 * 3.0  # it rebounds, but slower than it came


@pytest.mark.parametrize("variant", ["robust", "paper"])
def test_a_drop_weight_record_is_refused_in_one_line(tmp_path, capsys, striker, variant):
    path = write_recording(striker, tmp_path / "striker.h5")
    status, out, err = run(["identify", str(path), "--variant", variant], capsys)
    errors = [line for line in err.splitlines() if line.startswith("error:")]  # after a first-compile notice
    assert status == 2 and len(errors) == 1 and "Traceback" not in err and "error:" not in out
    assert errors[0].startswith("error: this record is not a drop on a gas-spring rod: ") and "20 kg" in errors[0]


def test_a_light_striker_names_the_flip_and_the_other_machine(ringing):
    with pytest.raises(IdentificationError, match=r"other sign.*--flip-acceleration.*not a drop on a gas-spring rod"):
        identify(ringing)


def test_inspect_and_identify_find_the_same_pulses_and_ringing_is_no_pulse(ringing):
    f = ringing.contact_force
    noise = robust_noise_std(f)
    # the ringing after the pulse rises above the detection level of the record's own noise
    assert len(detect_pulses(f - np.median(f[:1000]), noise)) >= 3
    inspected = inspect_recording(ringing)
    assert len(inspected.pulses) == 1 and inspected.pulses[0].peak_force > 1000.0
    with pytest.raises(IdentificationError, match=r"holds 1"):
        identify(flipped(ringing))


def test_an_answer_that_the_recorded_impulse_contradicts_is_refused():
    """The paper variant answered M1 -32 %, V0 -91 % with exit 0 beside its own warning that the pulse carried 8
    times the impulse that answer allows."""
    fs = 100e3
    t = np.arange(2000) / fs
    force = np.where(t < 5e-3, 1000.0 * np.sin(np.pi * t / 5e-3), 0.0)  # 3.18 N·s
    kwargs = {"force": force, "sample_rate": fs, "onset": 0.0, "pulse_ends": [500]}
    assert check_answer(20.0, 1.0, **kwargs) == ()
    assert "too small" in " ".join(check_answer(1.3, 1.0, **kwargs))  # 1.19 times what 1.3 kg allows: a warning
    with pytest.raises(IdentificationError, match=r"3.18 N·s.*times over: the answer is refused"):
        check_answer(0.2, 1.0, **kwargs)
