"""The absorber-design study: the first collision of a pad against its closed form, the levers it sweeps (piston
mass, pad law, charge per impact class), the Pareto set and recommendation from the rows, and reproducible rows."""

import math

import pytest

from impactometer.errors import ParameterError
from impactometer.studies import StudyOptions, get_study, load_studies
from impactometer.studies.absorber_design import (
    CLASSES,
    EARLY,
    PAD_DEFLECTION,
    designs,
    impact_class,
    pad_parameters,
    recommended,
)
from impactometer.studies.base import options_for

load_studies()


def _case(i, *, stiffness=7e5, piston=4.0, law="hysteretic", pressure=200e3, mass=30.0, velocity=2.0):
    return {"case": i, "impact": 0, "mass": mass, "velocity": velocity, "pressure_gauge": pressure, "law": law,
            "stiffness": stiffness, "effective_area_mm2": 100.0, "response_time_ms": 3.0, "piston_mass": piston}


def _options(**params):
    study = get_study("absorber-design")
    return study, options_for(study, StudyOptions(rig_is_default=True,
                                                  params={f"absorber-design.{k}": v for k, v in params.items()}))


@pytest.fixture(scope="module")
def pads():
    """One impact (30 kg at 2 m/s, 200 kPa) on a soft and on the built-in pad."""
    study, options = _options()
    return study.evaluate([_case(i, stiffness=k) for i, k in enumerate((1e5, 7e5))], options)


def test_the_first_collision_lies_between_the_free_and_the_held_piston(pads):
    """The pad's first collision peaks between V0·sqrt(k·μ) (a free piston, μ = M1·M2/(M1 + M2)) and V0·sqrt(k·M1)
    (a piston held fast); the short pulse of the stiff pad (5 ms) is close to the free one (the gas preload and
    the weight add a few percent), the long one of the soft pad (19 ms) feels the gas spring."""
    reduced = 30.0 * 4.0 / 34.0
    for row in pads:
        free, held = (2.0 * math.sqrt(row["pad_stiffness_N_m"] * m) for m in (reduced, 30.0))
        assert free < row["first_pulse_peak_N"] < held
    assert pads[1]["first_pulse_peak_N"] == pytest.approx(2.0 * math.sqrt(7e5 * reduced), rel=0.15)
    assert pads[0]["pressure_gauge"] == 200e3  # [Pa]


def test_a_softer_pad_lowers_the_whole_event_peak_and_delays_the_identification(pads):
    soft, stiff = pads
    assert soft["whole_event_peak_ratio"] < 0.8 * stiff["whole_event_peak_ratio"]  # 3.0 against 4.2
    late = math.inf if soft["identified_available_at_s"] is None else soft["identified_available_at_s"]
    assert late > stiff["identified_available_at_s"] > 0.0
    assert not soft["bottomed_out"] and not stiff["bottomed_out"]


@pytest.fixture(scope="module")
def pistons():
    """The same impact (30 kg at 2 m/s, 20 kPa, a 2e5 N/m pad) on a 1 kg and a 4 kg piston, M1 and V0 known."""
    study, options = _options(identification="oracle")
    cases = [_case(i, stiffness=2e5, piston=mp, pressure=20e3) for i, mp in enumerate((1.0, 4.0))]
    return study, options, cases, study.evaluate(cases, options)


def test_a_lighter_piston_lowers_the_first_collision(pistons):
    """V0·sqrt(k·μ): μ falls from 3.53 to 0.97 kg, the free-piston peak by sqrt(0.97/3.53) = 0.52; the gas
    preload and the weight add the same few hundred newtons to both, so the measured ratio lies between that and 1,
    and each peak between the free and the held piston."""
    light, heavy = pistons[3]
    assert light["first_pulse_peak_N"] < 0.9 * heavy["first_pulse_peak_N"]
    assert light["whole_event_peak_ratio"] < heavy["whole_event_peak_ratio"]
    for row, piston in ((light, 1.0), (heavy, 4.0)):
        free, held = (2.0 * math.sqrt(2e5 * m) for m in (30.0 * piston / (30.0 + piston), 30.0))
        assert free < row["first_pulse_peak_N"] < held
    assert light["identification"] == "oracle" and light["identified_available_at_s"] <= EARLY


def test_rows_are_reproducible(pistons):
    study, options, cases, rows = pistons
    assert study.evaluate(cases, options) == rows


def test_pads_by_law_share_their_secant_stiffness():
    progressive = pad_parameters("hunt-crossley", 2e5)
    assert progressive["contact.law"] == "hunt-crossley"
    assert progressive["contact.stiffness"] * PAD_DEFLECTION ** 1.5 == pytest.approx(2e5 * PAD_DEFLECTION)
    assert pad_parameters("kelvin-voigt", 2e5) == {"contact.law": "kelvin-voigt", "contact.stiffness": 2e5}
    with pytest.raises(ParameterError, match="pad law must be one of"):
        pad_parameters("crush", 2e5)
    with pytest.raises(ParameterError, match="pad stiffness"):
        pad_parameters("hysteretic", -1.0)


def test_impact_classes_split_the_paper_ranges_at_their_middle():
    assert [impact_class(m, v) for m, v in ((10, 1), (30, 3), (30.1, 2), (50, 2.01))] == list(CLASSES)


def _rows(design, peaks, ratios, answers, bottomed=False, pressure=2e5, classes=None):
    return [{"impact": i, "design": design, "hardware": "pad", "pressure_gauge": pressure,
             "impact_class": classes[i] if classes else CLASSES[0], "pad_stiffness_N_m": 7e5,
             "effective_area_mm2": 100.0, "response_time_ms": 3.0, "piston_mass_kg": 4.0,
             "whole_event_peak_ratio": p, "stage_b_ratio": r, "identified_available_at_s": a, "impact_force_N": 100.0,
             "first_pulse_peak_N": 100.0 * p, "rebound_m": 0.0, "bottomed_out": bottomed and i == 0, "stopped": True}
            for i, (p, r, a) in enumerate(zip(peaks, ratios, answers, strict=True))]


def test_pareto_set_and_recommendation():
    early, late = [EARLY / 2] * 10, [3 * EARLY] * 10
    rows = (_rows("a", [2.0] * 10, [1.4] * 10, early) + _rows("b", [4.0] * 10, [1.1] * 10, early)
            + _rows("c", [5.0] * 10, [1.5] * 10, early) + _rows("d", [1.0] * 10, [1.0] * 10, early, bottomed=True)
            + _rows("e", [1.5] * 10, [1.2] * 10, late))
    for r in rows:
        r["hardware"] = r["design"]  # one charge per hardware: no design per class
    table = {d["design"]: d for d in designs(rows)}
    assert {name for name, d in table.items() if d["Pareto"]} == {"b", "e"}  # d bottoms out; a, c dominated
    assert table["a"]["meets targets"] and not table["e"]["meets targets"]  # e answers late
    assert recommended(rows) is None  # the front's designs miss a target each
    rows = [r for r in rows if r["design"] != "e"]
    assert recommended(rows)["design"] == "a"


def test_the_charge_per_class_takes_each_class_at_its_best_charge_and_the_front_is_non_dominated():
    """Light impacts are better at the low charge, heavy ones at the high: the design per class beats both."""
    classes = list(CLASSES) * 2  # light-slow, light-fast, heavy-slow, heavy-fast, twice
    low = _rows("low", [2.0, 2.0, 4.0, 4.0] * 2, [1.2, 1.2, 1.8, 1.8] * 2, [EARLY / 2] * 8, pressure=2e4,
                classes=classes)
    high = _rows("high", [4.0, 4.0, 2.5, 2.5] * 2, [1.8, 1.8, 1.3, 1.3] * 2, [EARLY / 2] * 8, pressure=2e5,
                 classes=classes)
    table = designs(low + high)
    fixed = [d for d in table if d["charge"] == "fixed"]
    assert {d["design"] for d in fixed} == {"low", "high"}
    best = [d for d in table if d["charge"] == "per class 20/20/200/200 kPa"]
    assert len(best) == 1 and best[0]["Pareto"] and best[0]["meets targets"]
    assert best[0]["p90 peak / F0"] == pytest.approx(2.5) and best[0]["p90 R_B"] == pytest.approx(1.3)
    assert best[0]["p0 [kPa]"] == 200.0  # charged to the highest, vented to 20 kPa for the light impacts
    front = [d for d in table if d["Pareto"]]
    assert front and not any(o["bottomed out"] == 0 and o is not d and o["p90 peak / F0"] <= d["p90 peak / F0"]
                             and o["p90 R_B"] <= d["p90 R_B"]
                             and (o["p90 peak / F0"], o["p90 R_B"]) != (d["p90 peak / F0"], d["p90 R_B"])
                             for d in front for o in table)
    assert len({(d["p90 peak / F0"], d["p90 R_B"]) for d in front}) == len(front)  # equal designs shown once


def test_the_policy_setting_is_checked_and_passed_to_absorb(pads, monkeypatch):
    """``policy`` is absorb's: ``early`` (the default) drives the valve from first contact, ``wait`` keeps it
    closed until M1 is known, the call the study made before it had the setting (``absorb(early=False)``)."""
    import impactometer.studies.absorber_design as module

    assert module.DEFAULTS["policy"] == "early" == _options(policy="early")[1].params["absorber-design.policy"]
    with pytest.raises(ParameterError, match="policy"):
        _options(policy="later")
    seen = []

    def spy(*args, **kwargs):
        seen.append(kwargs["early"])
        return absorb(*args, **kwargs)

    absorb = module.absorb
    monkeypatch.setattr(module, "absorb", spy)
    study, options = _options(policy="wait")
    (wait,) = study.evaluate([_case(1)], options)
    assert seen == [False] and wait["policy"] == "wait" and pads[1]["policy"] == "early"
    keys = ("stage_b_ratio", "whole_event_peak_ratio", "control_start_s")
    assert [wait[k] for k in keys] != [pads[1][k] for k in keys]  # the early policy acts before M1 is known
