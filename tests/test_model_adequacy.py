"""The model-adequacy test of the model-based identification: its statistics on white and correlated residuals, its
verdict on a record of the model's own family (adequate) and on records of pads outside every family (not silently
adequate; the truth within the stated σ), and the JSON field.

The foreign records come from tests/foreign_stand.py, an independent simulator of the same stand with other pads.
Tolerances are stated in standard errors: ``Z`` = 4 stated σ fails by chance with probability 6e-5 per comparison
for a Gaussian estimate.
"""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from foreign_stand import foreign_case
from impactometer.cli import main
from impactometer.identify.details import Adequacy
from impactometer.identify.model_fit import MAX_REDUCED_CHI2, identify
from impactometer.identify.model_fit.adequacy import (
    VERDICTS,
    Z_ADEQUATE,
    _bandwidth,
    _Residual,
    _robust_inflation,
    _sandwich,
    _statistics,
)
from impactometer.io import write_recording
from impactometer.rig import Scenario
from impactometer.sensors import record

Z = 4.0


def _residual(after: np.ndarray, before: np.ndarray) -> _Residual:
    return _Residual(after=after, before=before, problem=None, vector=np.empty(0), onset=0)  # type: ignore[arg-type]


def test_white_residuals_pass_and_correlated_ones_do_not():
    rng = np.random.default_rng(5)
    white = _statistics(_residual(rng.normal(size=(2, 2500)), rng.normal(size=(2, 1000))))
    assert max(white["misfit_z"]) < Z_ADEQUATE and max(white["autocorrelation_z"]) < Z_ADEQUATE
    # a smooth model error of half the noise's variance: its lag-1 autocorrelation 0.5/1.5, z = 0.33/0.037 = 9 ± 1
    t = np.arange(2500) / 50e3
    smooth = np.sqrt(0.5 * 2) * np.sin(2 * np.pi * 150 * t)
    model_error = _statistics(_residual(rng.normal(size=(2, 2500)) + smooth, rng.normal(size=(2, 1000))))
    assert min(model_error["autocorrelation_z"]) > Z_ADEQUATE + 2
    # coloured noise (the same before and after contact) is the noise, not a model error
    colour = np.array([1.0, 0.8, 0.5])
    coloured = [np.apply_along_axis(np.convolve, 1, rng.normal(size=(2, n)), colour, "same") / np.linalg.norm(colour)
                for n in (2500, 1000)]
    assert max(_statistics(_residual(*coloured))["autocorrelation_z"]) < Z_ADEQUATE


def test_an_in_family_record_is_adequate():
    rec = record(Scenario(mass=30.0, velocity=2.0, pressure_gauge=150e3), seed=21, sample_rate=50e3, duration=0.05,
                 noise=0.05, pre_trigger=0.02)
    answer = identify(rec)
    adequacy = answer.details.adequacy
    assert isinstance(adequacy, Adequacy) and adequacy.verdict == "adequate"
    assert adequacy.chi2_z <= Z_ADEQUATE and adequacy.autocorrelation_z <= Z_ADEQUATE
    assert adequacy.robust_z is not None and adequacy.robust_z <= 3.0
    assert answer.details.path == "ml" and answer.warnings == ()
    assert abs(answer.mass - 30.0) <= Z * answer.mass_std and abs(answer.velocity - 2.0) <= Z * answer.velocity_std
    data = answer.to_dict()["adequacy"]
    assert data["verdict"] == "adequate" and data["chi2_dof"] == pytest.approx(answer.details.reduced_chi2)


def test_a_noise_free_record_keeps_the_models_answer():
    # a record of the sampling study (noise-free, 20 kHz): its σ is the floor NOISE_FLOOR, the residuals after contact
    # are a few % of its variance and smooth (integration-level differences); their correlation is a smooth error far
    # below the noise, not a model error, and the robust answer (its error here 1.2 of its own σ in M1, its σ a
    # thousand times the model's) does not overrule the model's answer, which is exact to its Fisher σ. Whether the
    # whole record or its first span is explained down to the noise depends on remnants at the integrator's tolerance
    # (the whole record here, a first span with the lowest supported numpy and scipy): either is the model's answer
    # with the σ of a fit that passed the test
    rec = record(Scenario(mass=30.0, velocity=2.0, pressure_gauge=210e3), sample_rate=20e3, duration=0.1,
                 pre_trigger=0.05)
    answer = identify(rec)
    adequacy = answer.details.adequacy
    assert answer.details.path == "ml" and adequacy.verdict in ("adequate", "shortened")
    assert max(adequacy.misfit) < 0.5 and adequacy.autocorrelation_z <= Z_ADEQUATE
    assert abs(answer.mass - 30.0) <= Z * answer.mass_std and abs(answer.velocity - 2.0) <= Z * answer.velocity_std


@pytest.mark.parametrize(("kind", "seed"), [("masing", 0), ("masing", 1), ("peak-oriented", 0), ("peak-oriented", 1)])
def test_a_foreign_pad_is_flagged_and_its_answer_covers_the_truth(kind, seed):
    rec, drop, _ = foreign_case(kind, seed)
    answer = identify(rec)
    adequacy = answer.details.adequacy
    assert adequacy.verdict in VERDICTS
    if max(adequacy.misfit or (1.0,)) > 1.5:  # a misfit far beyond the noise is never called adequate
        assert adequacy.verdict != "adequate"
    if adequacy.verdict != "adequate":
        assert adequacy.reason in answer.warnings
    assert abs(answer.mass - drop.mass) <= Z * answer.mass_std
    assert abs(answer.velocity - drop.velocity) <= Z * answer.velocity_std


@pytest.mark.parametrize(("chi2", "dof", "expected"), [(50.0, 5, 10.0 ** 0.5), (3.0, 5, 1.0), (7.0, 0, 1.0),
                                                      (None, None, 1.0)])
def test_the_robust_sigma_is_widened_by_the_scatter_of_its_rows(chi2, dof, expected):
    class _Answer:
        details = type("Details", (), {"chi2": chi2, "dof": dof})()

    assert _robust_inflation(_Answer()) == pytest.approx(expected)


def test_a_fallback_whose_robust_rows_scatter_carries_their_scatter_and_covers_the_truth():
    # a peak-oriented pad whose reload the robust rows read inconsistently (their χ²/dof far above 1) and that no
    # contact law describes (every law's whole-record fit far above the noise): the model falls back, and the robust
    # answer's σ counts the rows' scatter, so the truth lies within its stated σ
    rec, drop, _ = foreign_case("peak-oriented", 4)
    answer = identify(rec)
    adequacy = answer.details.adequacy
    assert answer.method == "model/fallback" and adequacy.verdict == "fell back"
    fallback = answer.details.fallback
    scale = (fallback.chi2 / fallback.dof) ** 0.5
    assert scale > 2.0 and adequacy.robust_inflation == pytest.approx(scale)
    assert adequacy.reason in answer.warnings and "widened by" in adequacy.reason
    assert abs(answer.mass - drop.mass) <= Z * answer.mass_std
    assert abs(answer.velocity - drop.velocity) <= Z * answer.velocity_std
    assert answer.to_dict()["adequacy"]["robust_inflation"] == pytest.approx(scale)


def test_a_law_the_screens_dropped_is_fitted_to_the_whole_record_where_the_laws_kept_do_not_describe_it():
    # a peak-oriented pad: the power law loses the 15 ms screen to the hysteretic law (held to its screening
    # windows' fit), whose whole-record fit then leaves χ²/dof far above the limit of a model answer; the dropped
    # laws are fitted to the whole record too, the power law describes it down to the noise and gives the answer,
    # and the truth lies within its stated σ (where without it the robust answer's σ missed the truth)
    rec, drop, _ = foreign_case("peak-oriented", 8)
    answer = identify(rec)
    selection = answer.details.model_selection
    kept = [fit for fit in selection.values() if "rescued" not in fit and "reduced_chi2" in fit]
    assert kept and all(fit["reduced_chi2"] > MAX_REDUCED_CHI2 for fit in kept)
    chosen = selection[answer.details.contact_law]
    assert "dropped by a screen" in chosen["rescued"]
    assert answer.method == "model/ml" and answer.details.adequacy.verdict == "adequate"
    assert answer.details.reduced_chi2 <= MAX_REDUCED_CHI2
    assert abs(answer.mass - drop.mass) <= Z * answer.mass_std
    assert abs(answer.velocity - drop.velocity) <= Z * answer.velocity_std


def test_the_json_answer_says_which_path_was_taken_and_why(tmp_path, capsys):
    rec, _, _ = foreign_case("peak-oriented", 0, duration=0.05)
    path = tmp_path / "foreign.h5"
    write_recording(replace(rec, source=str(path)), path)
    main(["identify", str(path), "--method", "model", "--json"])
    data = json.loads(capsys.readouterr().out)
    adequacy = data["adequacy"]
    assert adequacy["verdict"] in VERDICTS and adequacy["reason"]
    assert {"chi2_dof", "chi2_z", "autocorrelation", "autocorrelation_z"} <= set(adequacy)


class _Problem:
    """A linear fit of one mean per channel: the Jacobian of the residuals is −1 on that channel's rows."""

    def __init__(self, n: int):
        self.tail = np.zeros((2, n))
        self.jac = np.zeros((2 * n, 2))
        self.jac[:n, 0] = self.jac[n:, 1] = -1.0

    def jacobian(self, x):
        return self.jac


@pytest.mark.parametrize("rho", [0.0, 0.8])
def test_the_sandwich_sigma_of_a_mean_counts_the_residuals_correlation(rho):
    """For the mean of n AR(1) samples of correlation ρ the variance is (1 + ρ)/(1 − ρ) times the white-noise one;
    the sandwich with the bandwidth from the residuals finds it (Bartlett's kernel falls short by its bias, about
    2ρ/((1 − ρ)²·L) of it, and by its scatter, sqrt(4L/3n))."""
    n = 20000
    rng = np.random.default_rng(7)
    e = rng.normal(size=(2, n))
    r = np.empty_like(e)
    r[:, 0] = e[:, 0]
    for i in range(1, n):
        r[:, i] = rho * r[:, i - 1] + np.sqrt(1 - rho ** 2) * e[:, i]
    problem = _Problem(n)
    fit = type("Fit", (), {"x": np.zeros(2), "cov": np.eye(2) / n})()
    res = _Residual(after=r, before=rng.normal(size=(2, 1000)), problem=problem, vector=r.ravel(), onset=0)
    lags = _bandwidth(r)
    ratio = np.diag(_sandwich(res, fit, lags)) / np.diag(fit.cov)  # type: ignore[arg-type]
    expected = (1 + rho) / (1 - rho)
    assert np.all(np.abs(ratio / expected - 1) < 0.35)
