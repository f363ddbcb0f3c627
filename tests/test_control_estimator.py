"""What the controller knows: the piston observer, contact detection and the stage-B mass refinement."""

import math

import numpy as np
import pytest

from impactometer.constants import STANDARD_GRAVITY
from impactometer.control import ControlSettings, simulate_controlled, windows
from impactometer.control import estimator as est
from impactometer.control.identified import MODEL_MASS_FLOOR, ROBUST_MASS_FLOOR, mass_floor
from impactometer.control.loop import sensor_noise, sensor_sigma
from impactometer.control.state import N_ESTIMATOR, Estimator, Windows
from impactometer.identify.result import Identification
from impactometer.model import dynamics as d
from impactometer.model.setup import initial_state, pack
from impactometer.rig import Scenario, get_rig


def _watch(scenario, rig="drop-stand-pad", *, noise=0.02, seed=0, **settings):
    """The estimator's histories on a closed-valve impact (the controller watches, the valve stays closed)."""
    closed, _ = simulate_controlled(scenario, rig, duration=0.3)
    sigma = sensor_sigma(closed, noise)
    matrix = sensor_noise(sigma, closed.time.size, seed)
    control = ControlSettings(strategy="closed", force_noise=float(sigma[0]), acceleration_noise=float(sigma[1]),
                              **settings)
    return simulate_controlled(scenario, rig, control=control, duration=0.3, sensor_noise=matrix)


@pytest.mark.parametrize("mass, velocity, pressure", [(10.0, 2.0, 20e3), (30.0, 2.0, 210e3), (50.0, 3.0, 400e3)])
def test_stage_b_refines_the_mass_from_nothing(mass, velocity, pressure):
    """With no prior the estimate is the stage-B regression alone: within 3 % at 2 % noise, and its standard
    error is consistent with its error."""
    result, history = _watch(Scenario(mass=mass, velocity=velocity, pressure_gauge=pressure))
    estimate, std = history["estimated_mass"], history["estimated_mass_std"]
    known = np.isfinite(estimate)
    assert known.any()
    first = result.time[np.argmax(known)]
    assert first < 0.05  # within tens of milliseconds of first contact
    assert estimate[-1] == pytest.approx(mass, rel=0.03)
    assert abs(estimate[-1] - mass) < 4.0 * std[-1] + 0.005 * mass
    # the controller acts on it only once its standard error is below MASS_TRUST of it
    assert np.all(std[known] < est.MASS_TRUST * estimate[known])


def test_windows_between_equal_velocity_instants_remove_the_oscillation_bias():
    """The mass oscillates on the pad in stage B; windows between force extrema keep the estimate close from the
    first windows on, where a window cut anywhere carries the relative velocity at its ends."""
    scenario = Scenario(mass=30.0, velocity=2.0, pressure_gauge=210e3)
    result, history = _watch(scenario, noise=0.0)
    estimate = history["estimated_mass"]
    early = np.isfinite(estimate) & (result.time < 0.04)
    assert early.any()
    assert np.max(np.abs(estimate[early] / 30.0 - 1.0)) < 0.05
    # the same sums cut at arbitrary instants (here every 2 ms of the same contact) scatter far more
    t, fc, a2 = result.time, result.contact_force, result.a2
    stage_b = (t > 0.02) & (t < 0.04)
    cuts = np.arange(0.022, 0.04, 0.002)
    ratios = [fc[stage_b & (t < c)].sum() / (STANDARD_GRAVITY - a2[stage_b & (t < c)]).sum() for c in cuts]
    assert np.max(np.abs(np.array(ratios) / 30.0 - 1.0)) > 0.05


@pytest.mark.parametrize("std, trusted", [(3.0, True), (40.0, False)])
def test_an_own_estimate_is_acted_on_only_once_it_can_be_trusted(std, trusted):
    """Without a prior the stage-B estimate is the mass only while its standard error is below MASS_TRUST of it;
    before, the mass stays unknown (NaN) and the controller keeps the valve closed."""
    e = np.zeros(N_ESTIMATOR)
    e[Estimator.WINDOWS:] = windows.initial()
    e[Estimator.WINDOWS + Windows.MASS] = 30.0
    e[Estimator.WINDOWS + Windows.STD] = std
    ctrl = ControlSettings(strategy="predictive").packed()
    est._combine(e, ctrl, False, False)
    assert (std < 30.0 * est.MASS_TRUST) == trusted
    if trusted:
        assert e[Estimator.MASS] == 30.0 and e[Estimator.MASS_STD] == std
    else:
        assert math.isnan(e[Estimator.MASS]) and math.isinf(e[Estimator.MASS_STD])


def test_the_rated_masses_prior_is_the_mass_until_stage_b_refines_it():
    """Acting on partial knowledge, the mass is the prior (its standard deviation as given, no floor) until a
    stage-B estimate exists, then the inverse-variance combination of the two; the answer replaces the prior once
    known."""
    ctrl = ControlSettings(strategy="predictive", early_start=0.0, early_mass=30.0, early_mass_std=11.5,
                           early_velocity=2.0, mass=12.0, mass_std=0.5, mass_floor=ROBUST_MASS_FLOOR).packed()
    e = np.zeros(N_ESTIMATOR)
    e[Estimator.WINDOWS:] = windows.initial()
    est._combine(e, ctrl, False, True)
    assert e[Estimator.MASS] == 30.0 and e[Estimator.MASS_STD] == 11.5
    e[Estimator.WINDOWS + Windows.MASS], e[Estimator.WINDOWS + Windows.STD] = 20.0, 2.0
    est._combine(e, ctrl, False, True)
    weight = 1.0 / 11.5 ** 2, 1.0 / 2.0 ** 2
    assert e[Estimator.MASS] == pytest.approx((30.0 * weight[0] + 20.0 * weight[1]) / sum(weight))
    est._combine(e, ctrl, True, False)  # the answer (floored at mass_floor of it) and the stage-B estimate
    floor = 1.0 / (ROBUST_MASS_FLOOR * 12.0) ** 2
    assert e[Estimator.MASS] == pytest.approx((12.0 * floor + 20.0 * weight[1]) / (floor + weight[1]))


def test_prior_and_stage_b_are_weighted_by_their_errors():
    scenario = Scenario(mass=30.0, velocity=2.0, pressure_gauge=210e3)
    # a prior with a tiny error, floored at the peak-to-peak answer's 25 %
    _, confident = _watch(scenario, mass=45.0, mass_std=1e-3, mass_floor=ROBUST_MASS_FLOOR, start=0.0)
    _, ignored = _watch(scenario, mass=45.0, mass_std=math.inf, start=0.0)  # no weight once stage B speaks
    _, frozen = _watch(scenario, mass=45.0, mass_std=1.0, refine_mass=False, start=0.0)
    assert frozen["estimated_mass"][-1] == 45.0
    assert ignored["estimated_mass"][-1] == pytest.approx(30.0, rel=0.03)
    # stage B dominates the prior floored at 25 %, which still pulls a little
    assert ignored["estimated_mass"][-1] < confident["estimated_mass"][-1] < 31.5


def _answer_and_stage_b(floor, stage_b, stage_b_std, *, mass=30.0, mass_std=0.15):
    """(mass, standard error) [kg] the estimator acts on once the answer ``mass`` ± ``mass_std`` [kg], floored at
    ``floor`` of it, meets a stage-B estimate ``stage_b`` ± ``stage_b_std`` [kg]."""
    ctrl = ControlSettings(strategy="predictive", start=0.0, mass=mass, mass_std=mass_std, velocity=2.0,
                           mass_floor=floor).packed()
    e = np.zeros(N_ESTIMATOR)
    e[Estimator.WINDOWS:] = windows.initial()
    e[Estimator.WINDOWS + Windows.MASS], e[Estimator.WINDOWS + Windows.STD] = stage_b, stage_b_std
    est._combine(e, ctrl, True, False)
    return e[Estimator.MASS], e[Estimator.MASS_STD]


def test_a_precise_answer_is_not_pulled_away_by_the_floor():
    """The model's answer (σ 0.5 % of M1, floored at its validated 1 %) barely moves for a stage-B estimate 10 % off
    within its own errors; the same answer floored at the peak-to-peak answer's 25 % is pulled most of the way to it.
    A stage-B estimate that contradicts the answer (beyond 3 combined standard errors) still replaces it, and a mass
    known exactly is kept."""
    assert 0.0 < MODEL_MASS_FLOOR < ROBUST_MASS_FLOOR
    precise, std = _answer_and_stage_b(MODEL_MASS_FLOOR, 33.0, 2.0)
    assert std == pytest.approx(1.0 / math.sqrt(1.0 / (MODEL_MASS_FLOOR * 30.0) ** 2 + 1.0 / 2.0 ** 2))
    assert abs(precise - 30.0) < 0.01 * 30.0
    pulled, _ = _answer_and_stage_b(ROBUST_MASS_FLOOR, 33.0, 2.0)
    assert pulled > 32.0
    contradicted, std = _answer_and_stage_b(MODEL_MASS_FLOOR, 40.0, 2.0)
    assert (contradicted, std) == (40.0, 2.0)
    assert _answer_and_stage_b(0.0, 33.0, 2.0, mass_std=0.0) == (30.0, 0.0)


def test_each_identification_has_its_floor():
    """The loop floors the model fit's own answer at its validated error, the others (a model answer that fell back
    to the peak-to-peak one included) at the peak-to-peak answer's."""
    def found(method):
        return Identification(method=method, mass=30.0, velocity=2.0, mass_std=0.15, available_at=0.006)

    assert mass_floor(found("model/ml")) == MODEL_MASS_FLOOR
    assert mass_floor(found("peak-to-peak/robust")) == mass_floor(found("response-map/fast")) \
        == mass_floor(found("model/fallback")) == ROBUST_MASS_FLOOR
    assert mass_floor(found("oracle")) == 0.0


def test_observer_tracks_the_piston_without_drift():
    scenario = Scenario(mass=30.0, velocity=2.0, pressure_gauge=210e3)
    result, history = _watch(scenario, rig="drop-stand-pad")
    error = history["estimated_piston_displacement"] - result.u2
    assert np.max(np.abs(error[result.time > 0.05])) < 2e-3  # mm: the rod transducer anchors it
    # the estimated mass velocity in sustained contact is the piston's mean velocity
    together = history["sustained_contact"] > 0
    assert together.any()
    late = together & (result.time > 0.03)
    assert np.median(np.abs(history["estimated_velocity"][late] - result.v1[late])) < 0.05


def test_estimator_starts_from_the_measured_state():
    p = pack(get_rig("drop-stand-pad"), Scenario(mass=30.0, velocity=2.0))
    y0 = initial_state(p)
    e = est.initial(y0, ControlSettings(mass=20.0, velocity=1.5, start=0.01).packed())
    assert e[Estimator.P_LOWER_F] == y0[d.P_LOWER] and e[Estimator.X_HAT] == y0[d.U2]
    # the identification's answer is not known before the control start
    assert math.isnan(e[Estimator.MASS]) and math.isnan(e[Estimator.VELOCITY]) and e[Estimator.IN_CONTACT] == 0.0
