"""Study ``absorber-design`` (beyond the paper): which stand absorbs the whole event, not only stage B?

Designs: pre-charge p0 × pad stiffness (the hysteretic pad's loading stiffness, its restitution kept) × valve
(effective area of an ISO 6358 valve with b = 0.3 and the 10-90 % response of its actuator after the built-in
0.5 ms dead time) × piston mass (piston and rod). Per design, the impacts of the M1 × V0 grid over the paper's
ranges at the design's p0 are absorbed by the closed loop with identification (robust, 2 % noise, the same noise
seed per impact for every design): ``closed`` and ``predictive``.

Per design: the whole-event 90th percentile of the CFC 60 peak / F0 (what a person or a payload feels), the 90th
percentile of the controller's R_B (only where every impact of the design has a common window: one stopped in
stage A has none, and a percentile over a subset would flatter the design; the count is shown), the share of
impacts the identification answers within ``EARLY`` of first contact, bottoming. The Pareto set is taken on
(whole-event p90 peak / F0, p90 R_B) among the designs that never bottom out; the recommended design is the one of
the Pareto set that meets every target (:data:`TARGETS`) with the lowest whole-event p90, or, when none does, the
report says so and shows the front.

The trade-off it measures: a softer pad lowers the first collision (its peak ≈ V0·sqrt(k·μ), μ = M1·M2/(M1 + M2))
but lengthens the stage-A pulses the identification reads, so its answer comes later; a stiffer one bounces more
often (an earlier answer) with a higher first peak.
"""

from __future__ import annotations

import math

import numpy as np

from ..control import Absorber, ValveDrive, absorb
from ..control.valve import iso6358_valve
from ..rig import ABSORPTION_RIG, Scenario
from ..tables import flag, number
from ..validation import finite_or_none
from .base import PAPER_RANGES, Row, Setting, Study, StudyFigure, StudyOptions, case_seed, grid_size, register

NAME = "absorber-design"
#: values per axis of the M1 × V0 grid of each design (the report's maps: ``--grid 3``)
GRID = 2
DEFAULTS = {"pressures_kpa": [20, 200], "stiffnesses": [1e5, 7e5], "areas_mm2": [100], "response_times_ms": [3],
            "piston_masses": [4.0], "dead_time_ms": 0.5, "noise": 0.02}
SETTINGS = {"pressures_kpa": Setting("numbers", 0.0, 400.0), "stiffnesses": Setting("numbers", 1e3, 1e8),
            "piston_masses": Setting("numbers", 0.1, 100.0),
            "areas_mm2": Setting("numbers", 0.0, 1e4, low_open=True),
            "response_times_ms": Setting("numbers", 0.0, 1e3, low_open=True),
            "dead_time_ms": Setting("number", 0.0, 50.0), "noise": Setting("number", 0.0, 1.0, "fraction")}
#: the identification answers early when it does within this time of first contact [s]
EARLY = 0.010
#: what a recommended design must reach: whole-event p90 peak / F0, p90 R_B, share of early answers
TARGETS = {"whole_event_p90": 3.0, "stage_b_p90": 1.5, "early_share": 0.9}


def _setting(options: StudyOptions, key: str):
    return options.param(NAME, key, DEFAULTS[key])


def design_label(pressure_gauge: float, stiffness: float, area_mm2: float, response_ms: float,
                 piston_mass: float) -> str:
    """One design as a label: ``"200 kPa, 7e+05 N/m, 100 mm², 3 ms, 4 kg"`` for a charge pressure
    ``pressure_gauge`` [Pa gauge] (shown in kPa), pad stiffness [N/m], effective area [mm²], response time [ms] and
    piston mass [kg]."""
    return (f"{float(pressure_gauge) / 1e3:g} kPa, {float(stiffness):.3g} N/m, {float(area_mm2):g} mm², "
            f"{float(response_ms):g} ms, {float(piston_mass):g} kg")


def _cases(options: StudyOptions) -> list[Row]:
    n = grid_size(options, GRID)
    impacts = [(float(m), float(v)) for m in np.linspace(*PAPER_RANGES["mass"], n)
               for v in np.linspace(*PAPER_RANGES["velocity"], n)]
    return [{"impact": i, "mass": m, "velocity": v, "pressure_gauge": float(p) * 1e3, "stiffness": float(k),
             "effective_area_mm2": float(a), "response_time_ms": float(r), "piston_mass": float(mp)}
            for p in _setting(options, "pressures_kpa") for k in _setting(options, "stiffnesses")
            for a in _setting(options, "areas_mm2") for r in _setting(options, "response_times_ms")
            for mp in _setting(options, "piston_masses") for i, (m, v) in enumerate(impacts)]


def _evaluate(cases: list[Row], options: StudyOptions) -> list[Row]:
    rows = []
    dead = float(_setting(options, "dead_time_ms")) * 1e-3
    noise = float(_setting(options, "noise"))
    for case in cases:
        rig = iso6358_valve(case["effective_area_mm2"] * 1e-6,
                            rig=options.rig.replace(**{"contact.stiffness": case["stiffness"],
                                                       "cylinder.piston_mass": case["piston_mass"]}))
        lag = case["response_time_ms"] * 1e-3 / math.log(9.0)  # 10-90 % of a first-order lag: τ·ln 9
        absorber = Absorber(drive=ValveDrive(dead_time=dead, time_constant=lag))
        seed = int(case_seed(options, NAME, case["impact"]).generate_state(1)[0])
        scenario = Scenario(mass=case["mass"], velocity=case["velocity"], pressure_gauge=case["pressure_gauge"])
        result = absorb(scenario, rig, strategy=["closed", "predictive"], noise=noise, seed=seed, absorber=absorber,
                        sample_rate=options.sample_rate)
        m, closed = result.metrics["predictive"], result.metrics["closed"]
        rows.append({"case": case["case"], "impact": case["impact"], "mass_kg": scenario.mass,
                     "velocity_m_s": scenario.velocity, "pressure_gauge_Pa": scenario.pressure_gauge,
                     "pad_stiffness_N_m": case["stiffness"], "effective_area_mm2": case["effective_area_mm2"],
                     "response_time_ms": case["response_time_ms"], "piston_mass_kg": case["piston_mass"],
                     "design": design_label(case["pressure_gauge"], case["stiffness"], case["effective_area_mm2"],
                                            case["response_time_ms"], case["piston_mass"]),
                     "identified_available_at_s": finite_or_none(result.identified.available_at),
                     "identified_mass_kg": finite_or_none(result.identified.mass),
                     "stage_b_ratio": finite_or_none(m.stage_b_ratio),
                     "closed_stage_b_ratio": finite_or_none(closed.stage_b_ratio),
                     "wide_window_ratio": finite_or_none(m.wide_window_ratio),
                     "whole_event_peak_ratio": finite_or_none(m.whole_event_peak_ratio),
                     "closed_whole_event_peak_ratio": finite_or_none(closed.whole_event_peak_ratio),
                     "peak_deceleration_g": finite_or_none(m.peak_deceleration_g),
                     "first_pulse_peak_N": finite_or_none(m.peak_force_stage_a),
                     "common_window_excluded": result.window.reason or None, "stopped": m.stopped,
                     "bottomed_out": m.bottomed_out, "rebound_m": finite_or_none(m.rebound),
                     "stroke_used_m": finite_or_none(m.stroke_used),
                     "control_start_s": finite_or_none(m.control_start)})
    return rows


def _p90(values: np.ndarray) -> float:
    values = values[np.isfinite(values)]
    return float(np.percentile(values, 90)) if values.size else math.nan


def _figure(rows: list[Row], options: StudyOptions) -> StudyFigure:
    return StudyFigure("plot_absorber_design", rows, {"designs": designs(list(rows)), "early": EARLY,
                                                      "targets": TARGETS})


def designs(rows: list[Row]) -> list[Row]:
    """One row per design: its parameters, the whole-event and R_B 90th percentiles (R_B: NaN unless every impact
    has a common window; ``with R_B`` counts those that have), early answers, bottoming, and whether it is on the
    Pareto front and meets every target."""
    out = []
    for label in dict.fromkeys(r["design"] for r in rows):
        chosen = [r for r in rows if r["design"] == label]
        first = chosen[0]
        ratio = np.array([number(r.get("stage_b_ratio")) for r in chosen])
        early = np.array([number(r.get("identified_available_at_s")) for r in chosen])
        out.append({"design": label, "p0 [kPa]": number(first["pressure_gauge_Pa"]) / 1e3,
                    "pad [N/m]": number(first["pad_stiffness_N_m"]), "valve [mm²]": number(first["effective_area_mm2"]),
                    "response [ms]": number(first["response_time_ms"]),
                    "piston [kg]": number(first["piston_mass_kg"]), "impacts": len(chosen),
                    "p90 peak / F0": _p90(np.array([number(r.get("whole_event_peak_ratio")) for r in chosen])),
                    "p90 R_B": _p90(ratio) if np.isfinite(ratio).all() else math.nan,
                    "with R_B": int(np.isfinite(ratio).sum()),
                    "early answers": float(np.mean(early <= EARLY)) if early.size else math.nan,
                    "median answer [ms]": float(np.nanmedian(early)) * 1e3 if np.isfinite(early).any() else math.nan,
                    "bottomed out": sum(flag(r.get("bottomed_out")) for r in chosen),
                    "not stopped": sum(not flag(r.get("stopped")) for r in chosen)})
    for d in out:
        d["meets targets"] = bool(d["p90 peak / F0"] <= TARGETS["whole_event_p90"]
                                  and d["p90 R_B"] <= TARGETS["stage_b_p90"]
                                  and d["early answers"] >= TARGETS["early_share"] and d["bottomed out"] == 0)
        d["Pareto"] = d["bottomed out"] == 0 and math.isfinite(d["p90 peak / F0"] + d["p90 R_B"]) and not any(
            o is not d and o["bottomed out"] == 0 and o["p90 peak / F0"] <= d["p90 peak / F0"]
            and o["p90 R_B"] <= d["p90 R_B"] and (o["p90 peak / F0"], o["p90 R_B"]) != (d["p90 peak / F0"],
                                                                                       d["p90 R_B"]) for o in out)
    return out


def recommended(rows: list[Row]) -> Row | None:
    """The design of the Pareto set that meets every target with the lowest whole-event p90 (None: none does)."""
    ok = [d for d in designs(rows) if d["Pareto"] and d["meets targets"]]
    return min(ok, key=lambda d: d["p90 peak / F0"]) if ok else None


def _summary(rows: list[Row]) -> list[Row]:
    table = designs(rows)
    front = sorted((d for d in table if d["Pareto"]), key=lambda d: d["p90 peak / F0"])
    best = recommended(rows)
    shown = "; ".join(f"{d['design']}: {d['p90 peak / F0']:.3g} / {d['p90 R_B']:.3g} / "
                      f"{d['early answers'] * 100:.0f} % early" for d in front)
    if best is None:
        verdict = (f"none of the {len(table)} designs meets all three targets; the Pareto front (whole-event p90 "
                   f"peak / F0 / p90 R_B / early answers): {shown}")
    else:
        verdict = (f"{best['design']}: whole-event p90 peak / F0 {best['p90 peak / F0']:.3g}, p90 R_B "
                   f"{best['p90 R_B']:.3g}, {best['early answers'] * 100:.0f} % early answers; front: {shown}")
    impacts = len({r["impact"] for r in rows})
    return [{"quantity": f"the design for whole-event p90 peak / F0 <= {TARGETS['whole_event_p90']:g}, p90 R_B <= "
                         f"{TARGETS['stage_b_p90']:g} and >= {TARGETS['early_share'] * 100:g} % answers within "
                         f"{EARLY * 1e3:g} ms", "ours": f"{verdict}; over {impacts} impacts per design",
             "paper": "beyond the paper"}]


STUDY = register(Study(name=NAME, title="Absorber design: pre-charge × pad × valve, whole event and R_B",
                       figure="", cases=_cases, evaluate=_evaluate, aggregate=designs, summary=_summary,
                       drawing=_figure, chunk_size=4, defaults=DEFAULTS, settings=SETTINGS,
                       rig=ABSORPTION_RIG))
