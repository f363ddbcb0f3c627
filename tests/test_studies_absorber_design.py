"""The absorber-design study: the first collision of a pad against its closed form, the trade-off it measures, and
the Pareto set and recommendation from the rows."""

import math

import pytest

from impactometer.studies import StudyOptions, get_study, load_studies
from impactometer.studies.absorber_design import EARLY, designs, recommended
from impactometer.studies.base import options_for

load_studies()


@pytest.fixture(scope="module")
def pads():
    """One impact (30 kg at 2 m/s, 200 kPa) on a soft and on the built-in pad."""
    study = get_study("absorber-design")
    options = options_for(study, StudyOptions(rig_is_default=True))
    cases = [{"case": i, "impact": 0, "mass": 30.0, "velocity": 2.0, "pressure_gauge": 200e3, "stiffness": k,
              "effective_area_mm2": 100.0, "response_time_ms": 3.0, "piston_mass": 4.0}
             for i, k in enumerate((1e5, 7e5))]
    return study.evaluate(cases, options)


def test_the_first_collision_lies_between_the_free_and_the_held_piston(pads):
    """The pad's first collision peaks between V0·sqrt(k·μ) (a free piston, μ = M1·M2/(M1 + M2)) and V0·sqrt(k·M1)
    (a piston held fast); the short pulse of the stiff pad (5 ms) is close to the free one (the gas preload and
    the weight add a few percent), the long one of the soft pad (19 ms) feels the gas spring."""
    reduced = 30.0 * 4.0 / 34.0
    for row in pads:
        free, held = (2.0 * math.sqrt(row["pad_stiffness_N_m"] * m) for m in (reduced, 30.0))
        assert free < row["first_pulse_peak_N"] < held
    assert pads[1]["first_pulse_peak_N"] == pytest.approx(2.0 * math.sqrt(7e5 * reduced), rel=0.15)


def test_a_softer_pad_lowers_the_whole_event_peak_and_delays_the_identification(pads):
    soft, stiff = pads
    assert soft["whole_event_peak_ratio"] < 0.8 * stiff["whole_event_peak_ratio"]  # 3.0 against 4.2
    late = math.inf if soft["identified_available_at_s"] is None else soft["identified_available_at_s"]
    assert late > stiff["identified_available_at_s"] > 0.0
    assert not soft["bottomed_out"] and not stiff["bottomed_out"]


def _rows(design, peaks, ratios, answers, bottomed=False):
    return [{"impact": i, "design": design, "pressure_gauge_Pa": 2e5, "pad_stiffness_N_m": 7e5,
             "effective_area_mm2": 100.0, "response_time_ms": 3.0, "piston_mass_kg": 4.0,
             "whole_event_peak_ratio": p, "stage_b_ratio": r, "identified_available_at_s": a,
             "bottomed_out": bottomed and i == 0, "stopped": True}
            for i, (p, r, a) in enumerate(zip(peaks, ratios, answers, strict=True))]


def test_pareto_set_and_recommendation():
    early, late = [EARLY / 2] * 10, [3 * EARLY] * 10
    rows = (_rows("a", [2.0] * 10, [1.4] * 10, early) + _rows("b", [4.0] * 10, [1.1] * 10, early)
            + _rows("c", [5.0] * 10, [1.5] * 10, early) + _rows("d", [1.0] * 10, [1.0] * 10, early, bottomed=True)
            + _rows("e", [1.5] * 10, [1.2] * 10, late))
    table = {d["design"]: d for d in designs(rows)}
    assert {name for name, d in table.items() if d["Pareto"]} == {"b", "e"}  # d bottoms out; a, c dominated
    assert table["a"]["meets targets"] and not table["e"]["meets targets"]  # e answers late
    assert recommended(rows) is None  # the front's designs miss a target each
    rows = [r for r in rows if r["design"] != "e"]
    assert recommended(rows)["design"] == "a"
