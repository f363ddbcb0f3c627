"""The typed details of an identification: read by attribute, by the names of the dict they replace, as JSON."""

import json
import math

import pytest

from impactometer.identify.details import (
    EquationsUsed,
    GapReadings,
    ModelError,
    Nuisances,
    PeakToPeakDetails,
    ResponseMapDetails,
    RowsUsed,
    SlowErrors,
)
from impactometer.identify.result import Identification


def _robust() -> PeakToPeakDetails:
    used = EquationsUsed(rows=RowsUsed(onsets=2, extrema=6, stage_b_extrema=4, separations=0, stage_b_samples=900),
                         nuisances=Nuisances(lag_e=1e-4, offset=0.01,
                                             slow_errors=SlowErrors(offset=0.01, drift=2.0, shift_velocity=1e-4,
                                                                    shift_inverse_mass=1e-6),
                                             model_error=ModelError(extrema=0.002, separations=0.0)),
                         gap_readings=GapReadings(flights=(2.0, 30.0), kept_set=(2.1, 31.0)))
    return PeakToPeakDetails(t00=0.001, t01=0.003, t11=math.nan, onsets=(0.001, 0.02), stage="final", equations=used,
                             chi2=12.0, dof=10, noise_force=5.0, noise_acceleration=0.5, pre_trigger_samples=1000)


def test_details_read_by_the_names_of_the_dict_they_replace():
    details = _robust()
    assert details.equations is not None and details.equations.rows.extrema == 6 and details.agnostic
    assert details["equations"] == {
        "onsets": 2, "extrema": 6, "stage_b_extrema": 4, "separations": 0, "stage_b_samples": 900, "lag_e": 1e-4,
        "offset_m_s2": 0.01, "slow_errors": {"offset_m_s2": 0.01, "drift_m_s3": 2.0, "shift_v0_m_s": 1e-4,
                                             "shift_w_1_kg": 1e-6},
        "model_error": {"extrema_m_s": 0.002, "separations_m": 0.0},
        "gap_readings": {"flights": (2.0, 30.0), "set": (2.1, 31.0)}}
    assert isinstance(details["equations"], dict) and details.equations.turning_scatter == 0.002
    assert list(details) == ["t00", "t01", "t11", "onsets", "stage", "equations", "chi2", "dof", "noise_force_N",
                             "noise_acceleration_m_s2", "pre_trigger_samples"]
    assert details.get("caution") is None and "caution" not in details
    assert {**details}["noise_force_N"] == 5.0


def test_identification_reports_the_typed_details_as_json():
    answer = Identification(mass=30.0, velocity=2.0, available_at=0.05, method="peak-to-peak/robust",
                            details=_robust())
    data = json.loads(json.dumps(answer.to_dict()))
    assert data["t00_s"] == 0.001 and data["t11_s"] is None and data["onsets_s"] == [0.001, 0.02]
    assert data["equations"]["slow_errors"]["drift_m_s3"] == 2.0 and data["equations"]["gap_readings"]["set"] == [
        2.1, 31.0]
    assert "chi2" not in data and answer.t00 == 0.001 and answer.onsets == (0.001, 0.02)
    assert _robust().to_dict()["t11"] is None


def test_a_details_dict_is_typed_with_the_same_names():
    paper = {"t00": 0.001, "t01": 0.003, "t11": 0.02, "onsets": (), "noise_force_N": 5.0,
             "noise_acceleration_m_s2": 0.5, "caution": "noisy"}
    typed = PeakToPeakDetails.from_mapping(paper)
    assert dict(typed) == paper and typed.caution == "noisy" and not typed.agnostic


@pytest.mark.parametrize("extrapolated", [False, True])
def test_response_map_details(extrapolated):
    details = ResponseMapDetails(residual=0.01, features={"a": 1.0}, feature_set="paper", pressure_gauge=2e5,
                                 extrapolated=extrapolated)
    answer = Identification(mass=30.0, velocity=2.0, available_at=0.05, method="response-map/fast", details=details)
    assert answer.residual == 0.01 and answer.extrapolated is extrapolated
    assert answer.to_dict()["pressure_gauge_Pa"] == 2e5 and answer.to_dict()["features"] == {"a": 1.0}


def test_details_equal_the_mapping_of_their_names():
    assert GapReadings(flights=(2.0, 30.0), kept_set=(2.1, 31.0)) == {"flights": (2.0, 30.0), "set": (2.1, 31.0)}
    assert _robust() == _robust() and _robust() != {**_robust(), "caution": "noisy"}
