"""The loop's model identification (``control.identified.first_model_answer``): the model stream's first answer
the controller can act on, known a stated latency after its data; round trips on simulated records of known
M1 and V0."""

from __future__ import annotations

import pytest

from impactometer.control.identified import (
    MODEL_LAST,
    MODEL_MASS_TRUST,
    PRE_TRIGGER,
    first_model_answer,
    identify_impact,
)
from impactometer.rig import Scenario, get_rig
from impactometer.sensors import record

RIG = get_rig("drop-stand-pad")
CASES = [(30.0, 2.0, 200e3), (50.0, 1.0, 115e3), (10.0, 3.0, 400e3)]


def _record(mass, velocity, pressure, *, noise=0.02, seed=1, duration=0.03):
    return record(Scenario(mass=mass, velocity=velocity, pressure_gauge=pressure), RIG, sample_rate=50e3,
                  duration=duration, noise=noise, seed=seed, pre_trigger=PRE_TRIGGER)


@pytest.mark.parametrize("case", CASES)
def test_first_answer_is_trusted_early_and_within_its_sigma(case):
    """The answer holds the true M1 and V0 within 4 of its stated σ (the stand known: its σ is the stand's), its
    mass σ is within the trust the loop asks, and its data end within the window the loop gives the stream."""
    mass, velocity, pressure = case
    found = first_model_answer(_record(mass, velocity, pressure), RIG, pressure_gauge=pressure)
    assert found.method == "model/ml" and found.error is None
    assert found.mass_std < MODEL_MASS_TRUST * found.mass
    assert abs(found.mass - mass) < 4.0 * found.mass_std
    assert abs(found.velocity - velocity) < 4.0 * found.velocity_std
    assert 0.0 < found.available_at <= MODEL_LAST


@pytest.mark.parametrize("latency", [0.0, 1e-3, 3e-3])
def test_identify_impact_by_the_model_is_known_the_stated_latency_after_its_data(latency):
    """The answer is acted on exactly the stated latency after the last sample it used (no processor time of this
    machine in it), read before the end of the window the loop gives the stream."""
    found = identify_impact(Scenario(mass=30.0, velocity=2.0, pressure_gauge=200e3), RIG, method="model",
                            noise=0.02, seed=0, sample_rate=50e3, latency=latency)
    assert found.error is None and found.family == "model"
    assert 0.0 < found.details["data_until_s"] <= MODEL_LAST
    assert found.details["latency_s"] == latency
    assert found.available_at == found.details["data_until_s"] + latency


def test_a_longer_latency_leaves_the_stream_fewer_updates_before_its_answer():
    """The core is busy with one update for the latency: the next update reads the record from then on, so with a
    longer latency the answer's data end no earlier (the stream's updates are skipped, not queued)."""
    scenario = Scenario(mass=30.0, velocity=2.0, pressure_gauge=200e3)
    ends = [identify_impact(scenario, RIG, method="model", noise=0.02, seed=0, sample_rate=50e3,
                            latency=latency).details["data_until_s"] for latency in (0.0, 3e-3)]
    assert ends[1] >= ends[0]


@pytest.mark.parametrize("mass", [30.0, 50.0])
def test_the_early_loops_answer_reads_past_the_valves_first_motion_within_its_sigma(mass, monkeypatch):
    """absorb(early=True): the model stream reads the record of the run with the valve the controller drove as an
    input. 30 and 50 kg at 2 m/s and 400 kPa: the valve moves before an answer's data end (read as a closed-valve
    record, those answers were 2.3 and 4.9 of their σ off); with the opening the answer holds M1 and V0 within 4 of
    its stated σ, and the loop acts on it from its data's end + the latency."""
    import math

    import numpy as np

    from impactometer.control import loop as control_loop

    calls = []
    identify = control_loop.identify_impact

    def spy(*args, **kwargs):
        found = identify(*args, **kwargs)
        calls.append((kwargs.get("recording"), found))
        return found

    monkeypatch.setattr(control_loop, "identify_impact", spy)
    run = control_loop.absorb(Scenario(mass=mass, velocity=2.0, pressure_gauge=400e3), strategy="predictive",
                              early=True)
    recording, found = calls[-1]
    assert recording is not None and found.error is None and found.method == "model/ml"
    opening = recording.channels["valve_opening"]
    moved = float(recording.time[np.argmax(opening > 0.0)])
    assert 0.0 < moved < found.details["data_until_s"]  # the valve moved before the answer's data ended
    assert abs(found.mass - mass) < 4.0 * found.mass_std
    assert abs(found.velocity - 2.0) < 4.0 * found.velocity_std
    assert run.runs["predictive"].answer_at == found.available_at == found.details["data_until_s"] + 1e-3
    assert math.isfinite(run.runs["predictive"].metrics.stage_b_ratio)
