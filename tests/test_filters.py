"""CFC filters (SAE J211-1 / ISO 6487): design equations, corridor, phaselessness, end padding, errors."""

import math

import numpy as np
import pytest

from impactometer.errors import ParameterError, RecordingError
from impactometer.filters import (
    CFC_CLASSES,
    DESIGN_FACTORS,
    cfc_coefficients,
    cfc_corridor,
    cfc_filter,
    cfc_response,
    filter_recording,
)
from impactometer.recording import Recording


@pytest.mark.parametrize("cfc", sorted(CFC_CLASSES))
@pytest.mark.parametrize("standard", sorted(DESIGN_FACTORS))
@pytest.mark.parametrize("rate_over_fn", [6.0, 20.0, 300.0])
def test_magnitude_response_lies_in_the_j211_corridor(cfc, standard, rate_over_fn):
    klass = CFC_CLASSES[cfc]
    fs = rate_over_fn * klass.f_n
    f = np.geomspace(0.1, 0.499 * fs, 3000)
    gain_db = 20 * np.log10(cfc_response(cfc, fs, f, standard=standard))
    lower, upper = cfc_corridor(cfc, f)
    assert np.all(gain_db >= lower), f[gain_db < lower][:3]
    assert np.all(gain_db <= upper), f[gain_db > upper][:3]


@pytest.mark.parametrize("cfc", sorted(CFC_CLASSES))
def test_minus_3db_point_is_near_f_n_when_well_sampled(cfc):
    # the 4-pole phaseless filter of the standard has its -3 dB point at about f_n = 1.65..1.67 x CFC
    klass = CFC_CLASSES[cfc]
    gain_db = 20 * np.log10(cfc_response(cfc, 1000 * klass.f_n, [klass.f_n])[0])
    assert gain_db == pytest.approx(-3.0, abs=0.15)


def test_coefficients_follow_the_standard_difference_equation():
    fs, cfc = 20e3, 1000
    b, a = cfc_coefficients(cfc, fs)
    wd = 2 * math.pi * cfc * 2.0775
    wa = math.tan(wd / fs / 2)
    den = 1 + math.sqrt(2) * wa + wa ** 2
    a0, b1, b2 = wa ** 2 / den, -2 * (wa ** 2 - 1) / den, (-1 + math.sqrt(2) * wa - wa ** 2) / den
    x = np.random.default_rng(0).normal(size=64)
    y = np.zeros_like(x)
    for n in range(x.size):
        xs = [x[n - k] if n - k >= 0 else 0.0 for k in range(3)]
        ys = [y[n - k] if n - k >= 0 else 0.0 for k in range(1, 3)]
        y[n] = a0 * xs[0] + 2 * a0 * xs[1] + a0 * xs[2] + b1 * ys[0] + b2 * ys[1]
    from scipy.signal import lfilter
    np.testing.assert_allclose(lfilter(b, a, x), y, rtol=1e-12, atol=1e-12)
    # not the generic Butterworth at the nominal frequency
    from scipy.signal import butter
    assert not np.allclose(butter(2, cfc, fs=fs)[0], b, rtol=1e-3)


def test_filter_is_phaseless_and_keeps_area_of_a_pulse():
    fs = 50e3
    t = np.arange(5000) / fs
    pulse = np.exp(-0.5 * ((t - 0.05) / 0.002) ** 2)
    y = cfc_filter(pulse, fs, 180)
    assert abs(t[np.argmax(y)] - 0.05) <= 1 / fs
    assert np.trapezoid(y, t) == pytest.approx(np.trapezoid(pulse, t), rel=1e-6)


def test_odd_end_padding_keeps_a_ramp_at_both_ends():
    fs = 10e3
    x = 3.0 + 250.0 * np.arange(800) / fs
    # without padding the ends bend by several % of the span; 10 ms of odd reflection leaves < 1e-4 of it for
    # the slowest class, and a long pad makes the ramp exact
    span = x.max() - x.min()
    assert np.abs(cfc_filter(x, fs, 60, pad_time=0.0) - x).max() > 0.02 * span
    assert np.abs(cfc_filter(x, fs, 60) - x).max() < 1e-4 * span
    np.testing.assert_allclose(cfc_filter(x, fs, 60, pad_time=0.05), x, rtol=0, atol=1e-9 * span)


def test_filter_along_axis_matches_rows():
    rng = np.random.default_rng(1)
    x = rng.normal(size=(3, 400))
    rows = np.array([cfc_filter(r, 10e3, 600) for r in x])
    np.testing.assert_allclose(cfc_filter(x, 10e3, 600, axis=-1), rows, rtol=1e-12)
    np.testing.assert_allclose(cfc_filter(x.T, 10e3, 600, axis=0).T, rows, rtol=1e-12)


def test_filter_recording_filters_named_channels_and_notes_the_class():
    rng = np.random.default_rng(2)
    rec = Recording(sample_rate=20e3, channels={"contact_force": rng.normal(size=500),
                                                "piston_acceleration": rng.normal(size=500)})
    out = filter_recording(rec, 1000, channels=["contact_force"])
    assert out.metadata["cfc"] == {"contact_force": 1000}
    np.testing.assert_array_equal(out.piston_acceleration, rec.piston_acceleration)
    assert np.std(out.contact_force) < 0.5 * np.std(rec.contact_force)
    with pytest.raises(RecordingError, match="channels found"):
        filter_recording(rec, 1000, channels=["pressure_lower"])


@pytest.mark.parametrize("kwargs, match", [
    (dict(cfc=500), r"cfc must be one of \[60, 180, 600, 1000\]"),
    (dict(cfc=True), "cfc must be one of"),
    (dict(sample_rate=5e3), "sample_rate must be >= 9900"),
    (dict(sample_rate=float("nan")), "sample_rate"),
    (dict(standard="DIN"), "standard must be one of"),
    (dict(pad_time=-1.0), "pad_time"),
    (dict(x=[1.0, 2.0]), "at least 3 samples"),
    (dict(x=[1.0, np.nan, 2.0, 3.0]), "finite"),
])
def test_bad_arguments_raise_parameter_error(kwargs, match):
    args = dict(x=np.zeros(100), sample_rate=20e3, cfc=1000) | kwargs
    with pytest.raises(ParameterError, match=match):
        cfc_filter(**args)
