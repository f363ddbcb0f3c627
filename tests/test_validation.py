"""The shared parameter checks: a flag is no quantity, wherever one is expected (True is not 1 Pa, nor 1 kg)."""

from __future__ import annotations

import numpy as np
import pytest

from impactometer.errors import ImpactometerError, ParameterError
from impactometer.identify.model_fit import identify as identify_model
from impactometer.identify.response_map import build_map_simulated
from impactometer.model import simulate_batch
from impactometer.rig import Scenario
from impactometer.sensors import record
from impactometer.validation import check_real, real_array


@pytest.mark.parametrize("flag", [True, False, np.bool_(True), [30.0, True], np.array([True, False]),
                                  np.array([30.0, True], dtype=object)])
def test_real_array_refuses_a_flag_anywhere_in_it(flag):
    with pytest.raises(ParameterError, match=r"^mass must be a number or an array of numbers \[kg\], got "):
        real_array("mass", flag, unit=" [kg]")


def test_real_array_takes_numbers_as_they_are():
    assert real_array("mass", 30).tolist() == 30.0 and real_array("mass", [1, 2.5]).tolist() == [1.0, 2.5]
    assert real_array("mass", np.arange(3, dtype=np.int64)).dtype == float


@pytest.mark.parametrize("call", [
    lambda rec: check_real("pressure", True),
    lambda rec: identify_model(rec, pressure_gauge=True),
    lambda rec: simulate_batch(True, 2.0, 200e3, duration=0.002),
    lambda rec: simulate_batch(30.0, 2.0, [200e3, True], duration=0.002),
    lambda rec: build_map_simulated(None, True, masses=[10.0, 20.0], velocities=[1.0, 2.0]),
    lambda rec: build_map_simulated(None, 200e3, masses=[10.0, True], velocities=[1.0, 2.0]),
])
def test_a_flag_given_for_a_quantity_is_refused_naming_it(call):
    rec = record(Scenario(mass=30.0, velocity=2.0, pressure_gauge=100e3), sample_rate=50e3, duration=0.02,
                 noise=0.02, seed=1, pre_trigger=0.02)
    with pytest.raises(ImpactometerError, match=r"(pressure|pressure_gauge|mass|masses) must be .*got .*True"):
        call(rec)
