"""The peak-force study against physics: undamped two-body closed forms, damping lowers the peak."""

from __future__ import annotations

import numpy as np
import pytest

from impactometer.rig import get_rig
from impactometer.studies import StudyOptions, get_study, load_studies
from impactometer.studies.peak_force import closed_form_peak_force

load_studies()


@pytest.mark.parametrize("contact", ["kelvin-voigt", "hunt-crossley", "hysteretic"])
def test_undamped_first_peak_matches_closed_form(contact):
    # the hysteretic law loads along k1·δ whatever its restitution: its first peak is the undamped one (at the
    # Kelvin-Voigt stiffness, so that the gas spring the closed form ignores is as small beside it)
    rig = get_rig("drop-stand-stiff", contact=contact)
    rig = rig.replace(**({"contact.damping": 0.0} if contact != "hysteretic" else {"contact.stiffness": 2e6}))
    rows = get_study("peak-force").run(StudyOptions(rig=rig, grid=3, noise=0.0))
    error = np.array([r["ratio_error"] for r in rows])
    # the closed form ignores only the gas-spring stiffness and the friction smoothing: within 1 %
    assert np.max(np.abs(error)) < 0.01
    # the DAQ (50 kHz, anti-alias filter, no noise) sees the peak within 2 %
    assert np.max(np.abs([r["recorded_error"] for r in rows])) < 0.02


@pytest.mark.parametrize("contact", ["kelvin-voigt", "hunt-crossley"])
def test_contact_damping_lowers_the_first_peak(contact):
    rows = get_study("peak-force").run(StudyOptions(rig=get_rig(contact=contact), grid=2, noise=0.0))
    assert all(-0.15 < r["ratio_error"] < 0.0 for r in rows)


def test_closed_form_limits():
    rig = get_rig("drop-stand-stiff")
    mu = 30.0 * 4.0 / 34.0
    # no preload: V0·sqrt(k·μ); the preload raises the peak
    free = rig.replace(**{"friction.force": 0.0, "gravity": 0.0})
    assert closed_form_peak_force(free, 30.0, 2.0, 0.0) == pytest.approx(2.0 * np.sqrt(2e6 * mu), rel=1e-12)
    assert closed_form_peak_force(rig, 30.0, 2.0, 400e3) > closed_form_peak_force(free, 30.0, 2.0, 0.0)
    hertz = free.with_contact("hunt-crossley")
    expected = 4e8 ** 0.4 * (1.25 * mu * 4.0) ** 0.6
    assert closed_form_peak_force(hertz, 30.0, 2.0, 0.0) == pytest.approx(expected, rel=1e-10)


@pytest.mark.parametrize("args, match", [
    ((0.0, 2.0), "mass must be finite and > 0"),
    ((30.0, -1.0), "velocity must be finite and >= 0"),
    ((30.0, float("nan")), "velocity must be finite"),
    (([1.0, 2.0], [1.0, 2.0, 3.0]), "numbers or arrays of one shape"),
])
def test_closed_form_rejects_bad_input(args, match):
    from impactometer.errors import ParameterError

    with pytest.raises(ParameterError, match=match):
        closed_form_peak_force(get_rig(), *args)


def test_study_run_rejects_other_options():
    from impactometer.errors import ParameterError

    with pytest.raises(ParameterError, match="options must be StudyOptions"):
        get_study("peak-force").run({"grid": 2})
