"""Response maps: closed-form inversion, refinement, round-trip identification of simulated impacts, bad input."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from impactometer import simulate_batch
from impactometer.errors import ParameterError, ResponseMapError
from impactometer.identify.response_map import (
    Identification,
    ResponseMap,
    build_map_simulated,
    identify_features,
    refine,
)
from impactometer.identify.response_map.features import extract_batch
from impactometer.rig import get_rig, to_dict

#: the grid of the response-map tests: 8 masses × 8 drop heights (5 cm to 50 cm) on the built-in stand
RIG = get_rig()
MASSES = np.linspace(10.0, 50.0, 8)
VELOCITIES = np.sqrt(2 * RIG.gravity * np.linspace(0.05, 0.5, 8))


def polynomial_map(masses=MASSES, velocities=VELOCITIES, pressures=(200e3,), feature_set="max-impulse"):
    """A map whose features are cubic polynomials of (m, v): the not-a-knot spline reproduces them exactly."""
    m, v = np.meshgrid(masses, velocities, indexing="ij")
    layers = [np.stack([1e3 * v * (1 + 0.01 * m) + 50 * v ** 3 + k, 5 * m * v + 0.02 * m ** 2 + k / 100])
              for k in range(len(pressures))]
    return ResponseMap(masses=masses, velocities=velocities, pressures_gauge=np.array(pressures, dtype=float),
                       values=np.stack(layers, axis=1), feature_set=feature_set, feature_params={},
                       sample_rate=50e3, rig=to_dict(RIG))


def polynomial_features(m, v, k=0):
    return np.array([1e3 * v * (1 + 0.01 * m) + 50 * v ** 3 + k, 5 * m * v + 0.02 * m ** 2 + k / 100])


def test_refine_reproduces_cubic_features_exactly():
    fine = refine(polynomial_map(), (31, 17))
    m, v = np.meshgrid(fine.masses, fine.velocities, indexing="ij")
    np.testing.assert_allclose(fine.values[:, 0], polynomial_features(m, v), rtol=1e-10)
    assert fine.provenance["refinements"][-1]["to"] == [31, 17]


def test_fast_search_inverts_a_smooth_map_exactly():
    rmap = polynomial_map()
    rng = np.random.default_rng(0)
    for m, v in zip(rng.uniform(11, 49, 20), rng.uniform(1.1, 3.0, 20), strict=False):
        result = identify_features(polynomial_features(m, v), rmap)
        assert result.mass == pytest.approx(m, rel=1e-8)
        assert result.velocity == pytest.approx(v, rel=1e-8)
        assert result.residual < 1e-20


def test_brute_search_is_the_minimum_of_eq7_over_the_nodes():
    rmap = refine(polynomial_map(), 40)
    y = polynomial_features(23.3, 1.77)
    result = identify_features(y, rmap, search="brute")
    f = (((y[:, None, None] - rmap.values[:, 0]) / y[:, None, None]) ** 2).sum(axis=0)  # eq. (7), naive
    i, j = np.unravel_index(np.argmin(f), f.shape)
    assert (result.mass, result.velocity) == (rmap.masses[i], rmap.velocities[j])
    assert result.residual == pytest.approx(f[i, j], rel=1e-12)
    # and the node found is the one next to the truth
    assert abs(result.mass - 23.3) <= np.diff(rmap.masses)[0]
    assert abs(result.velocity - 1.77) <= np.diff(rmap.velocities)[0]


def test_fast_answer_does_not_depend_on_refinement():
    base = polynomial_map()
    y = polynomial_features(37.1, 2.41)
    answers = [identify_features(y, rmap) for rmap in (base, refine(base, 60), refine(base, 600))]
    for other in answers[1:]:
        assert other.mass == pytest.approx(answers[0].mass, rel=1e-6)
        assert other.velocity == pytest.approx(answers[0].velocity, rel=1e-6)


def test_pressure_axis_interpolates_between_layers():
    pressures = (100e3, 200e3, 300e3, 400e3)
    rmap = polynomial_map(pressures=pressures)  # features grow by k (layer index) along pressure: linear in p
    for p, m, v in [(200e3, 30.0, 2.0), (250e3, 20.0, 1.5), (370e3, 45.0, 2.9)]:
        k = (p - 100e3) / 100e3
        result = identify_features(polynomial_features(m, v, k), rmap, pressure_gauge=p)
        assert result.mass == pytest.approx(m, rel=1e-7)
        assert result.velocity == pytest.approx(v, rel=1e-7)
    with pytest.raises(ResponseMapError, match="give the measured charge pressure"):
        identify_features(polynomial_features(30, 2), rmap)
    with pytest.raises(ResponseMapError, match="map build --pressure 500kPa"):
        identify_features(polynomial_features(30, 2), rmap, pressure_gauge=500e3)


def test_single_pressure_map_refuses_another_pressure():
    with pytest.raises(ResponseMapError, match=r"charge pressure of 200 kPa, the measurement is at 300 kPa"):
        identify_features(polynomial_features(30, 2), polynomial_map(), pressure_gauge=300e3)


def test_outside_the_map_is_refused_or_answered_with_a_warning():
    rmap = polynomial_map()
    y = polynomial_features(60.0, 2.0)  # heavier than the map's 50 kg
    with pytest.raises(ResponseMapError, match=r"outside the map \(mass 10-50 kg.*about 60 kg"):
        identify_features(y, rmap)
    with pytest.warns(UserWarning, match="answering by extrapolation"):
        result = identify_features(y, rmap, allow_extrapolation=True)
    assert result.extrapolated
    assert result.mass == pytest.approx(60.0, rel=1e-6)  # the cubic surfaces extrapolate a cubic exactly


def test_features_that_fit_nowhere_are_refused():
    with pytest.raises(ResponseMapError, match="fit nowhere in or near the map"):
        identify_features([1.0, 1e6], polynomial_map())


@pytest.mark.parametrize("bad", [[1.0], [np.nan, 1.0], [-5.0, 1.0], [0.0, 2.0], ["a", "b"], None])
def test_bad_feature_vectors_are_refused(bad):
    with pytest.raises(ResponseMapError, match="features must be 2 finite numbers > 0"):
        identify_features(bad, polynomial_map())


def test_bad_arguments_are_refused():
    with pytest.raises(ParameterError, match=r"search must be one of \['fast', 'brute'\]"):
        identify_features([1.0, 2.0], polynomial_map(), search="grid")
    with pytest.raises(ParameterError, match="grid size must be an integer >= 2"):
        refine(polynomial_map(), 1)
    with pytest.raises(ParameterError, match="above the limit"):
        refine(polynomial_map(), 100_000)


def test_invalid_maps_are_refused():
    good = polynomial_map()
    kwargs = dict(masses=good.masses, velocities=good.velocities, pressures_gauge=good.pressures_gauge,
                  values=good.values, feature_set="max-impulse", feature_params={}, sample_rate=50e3, rig=good.rig)
    with pytest.raises(ResponseMapError, match="strictly increasing"):
        ResponseMap(**{**kwargs, "masses": good.masses[::-1]})
    with pytest.raises(ResponseMapError, match="must have shape"):
        ResponseMap(**{**kwargs, "values": good.values[:, :, :-1]})
    values = good.values.copy()
    values[1, 0, 2, 3] = -1.0
    with pytest.raises(ResponseMapError, match="'impulse' must be finite and > 0.*at mass"):
        ResponseMap(**{**kwargs, "values": values})
    with pytest.raises(ResponseMapError, match="stand description is invalid"):
        ResponseMap(**{**kwargs, "rig": {"cylinder": {"bore": -1.0}}})


def random_impacts(n, seed):
    """``n`` (masses, velocities) drawn at random inside the grid, away from its edges."""
    rng = np.random.default_rng(seed)
    return rng.uniform(12.0, 48.0, n), np.sqrt(2 * RIG.gravity * rng.uniform(0.07, 0.48, n))


# mean relative error of (mass, velocity) for noise-free impacts with a continuous search on an 8×8 simulated
# map: the two-peak and impulse-profile maps are smooth; max-impulse with T = 20 ms has kinks where the window cuts
# the second pulse, which a cubic surface through 8×8 nodes follows less well.
ROUND_TRIP_TOLERANCE = {"peaks": (0.01, 0.001), "impulse-profile": (0.01, 0.002), "max-impulse": (0.05, 0.02)}


@pytest.mark.parametrize("features", sorted(ROUND_TRIP_TOLERANCE))
def test_round_trip_identification_of_simulated_impacts(features):
    rmap = build_map_simulated(RIG, 200e3, masses=MASSES, velocities=VELOCITIES, features=features)
    masses, velocities = random_impacts(12, seed=5)
    batch = simulate_batch(masses, velocities, 200e3, RIG, duration=0.06, channels=("contact_force",))
    ys, available = extract_batch(batch.time, batch.data["contact_force"], features, rmap.feature_params)
    results = [identify_features(y, rmap, available_at=a) for y, a in zip(ys, available, strict=False)]
    mass_error = np.mean([abs(r.mass / m - 1) for r, m in zip(results, masses, strict=False)])
    velocity_error = np.mean([abs(r.velocity / v - 1) for r, v in zip(results, velocities, strict=False)])
    assert mass_error < ROUND_TRIP_TOLERANCE[features][0]
    assert velocity_error < ROUND_TRIP_TOLERANCE[features][1]
    assert all(0 < r.available_at < 0.06 for r in results)
    # at the map's own nodes both searches return the node
    node = rmap.values[:, 0, 3, 5]
    for search in ("fast", "brute"):
        result = identify_features(node, rmap, search=search)
        assert result.mass == pytest.approx(MASSES[3], rel=1e-6)
        assert result.velocity == pytest.approx(VELOCITIES[5], rel=1e-6)


def test_identification_result_reports_the_shared_keys():
    result = identify_features(polynomial_features(30, 2), polynomial_map())
    assert isinstance(result, Identification)
    data = result.to_dict()
    for key in ("mass_kg", "velocity_m_s", "energy_J", "available_at_s", "method", "search", "residual",
                "features", "mass_std_kg", "velocity_std_m_s"):
        assert key in data
    assert data["method"] == "response-map"
    assert data["energy_J"] == pytest.approx(0.5 * 30 * 2 ** 2, rel=1e-7)
    assert set(data["features"]) == {"max_force", "impulse"}


def test_simulated_map_with_too_short_records_for_peaks_is_refused():
    with pytest.raises(ResponseMapError, match="found no features.*use a longer duration"):
        build_map_simulated(RIG, 200e3, masses=MASSES[:3], velocities=VELOCITIES[:3], features="peaks",
                            duration=0.01)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(allow_nan=True, allow_infinity=True, width=64), min_size=0, max_size=3),
       st.sampled_from(["fast", "brute"]), st.booleans())
def test_any_feature_vector_gives_an_answer_or_a_response_map_error(values, search, allow):
    rmap = _SMALL_MAP
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)
            result = identify_features(values, rmap, search=search, allow_extrapolation=allow)
    except ResponseMapError:
        return
    assert np.isfinite(result.mass) and np.isfinite(result.velocity) and result.residual >= 0
    span_m, span_v = rmap.masses[-1] - rmap.masses[0], rmap.velocities[-1] - rmap.velocities[0]
    assert rmap.masses[0] - 0.26 * span_m <= result.mass <= rmap.masses[-1] + 0.26 * span_m
    assert rmap.velocities[0] - 0.26 * span_v <= result.velocity <= rmap.velocities[-1] + 0.26 * span_v


_SMALL_MAP = refine(polynomial_map(), 20)
