"""Study ``valve-design`` (beyond the paper): which valve Z does the stand need?

The predictive absorber (M1 and V0 identified, or with ``--set valve-design.identification=oracle`` known, from
the same instant; 2 % sensor noise) over a subset of the impact grid, for every valve of
a sweep of sizes (effective area of the open valve, an ISO 6358 valve with b = 0.3) and speeds (10-90 % response of
a first-order actuator, after the built-in valve's dead time). The same noise realisation per impact for every
valve, so the maps compare valves, not luck. Maps of the median and 90th-percentile R_B on the common window
(:mod:`impactometer.control.event`), over the impacts every valve has one for (the common set; the others are
counted), and of the bottomed-out runs; the summary names the smallest, slowest valve whose median R_B is 1.1 or
less.
"""

from __future__ import annotations

import math

import numpy as np

from ..control import Absorber, ValveDrive, absorb
from ..control.valve import iso6358_valve
from ..rig import ABSORPTION_RIG, Scenario
from ..tables import flag
from ..validation import finite_or_none
from .absorption import common_set, values_on
from .base import Row, Setting, Study, StudyFigure, StudyOptions, case_seed, register, scenario_grid

NAME = "valve-design"
#: impacts: values per axis of the M1 × V0 × p0 grid (8 impacts; the report's maps: ``--grid 3`` and the five sizes
#: and speeds of :data:`FULL`)
GRID = 2
FULL = {"areas_mm2": [25, 50, 100, 200, 400], "response_times_ms": [1, 2, 3, 5, 10]}
DEFAULTS = {"areas_mm2": [25, 100, 400], "response_times_ms": [1, 3, 10], "dead_time_ms": 0.5,
            "noise": 0.02, "strategy": "predictive", "identification": "model"}
SETTINGS = {"areas_mm2": Setting("numbers", 0.0, 1e4, low_open=True), "response_times_ms": Setting("numbers", 0.0, 1e3,
                                                                                                  low_open=True),
            "dead_time_ms": Setting("number", 0.0, 50.0), "noise": Setting("number", 0.0, 1.0, "fraction"),
            "strategy": Setting("choice", choices=("realtime", "predictive")),
            "identification": Setting("choice", choices=("model", "robust", "paper", "oracle"))}
#: the stage-B force ratio the designer asks for (median over the impacts)
TARGET = 1.1


def _setting(options: StudyOptions, key: str):
    return options.param(NAME, key, DEFAULTS[key])


def _cases(options: StudyOptions) -> list[Row]:
    impacts = scenario_grid(options, GRID)
    return [{"impact": i, **impact, "effective_area_mm2": float(area), "response_time_ms": float(response)}
            for area in _setting(options, "areas_mm2") for response in _setting(options, "response_times_ms")
            for i, impact in enumerate(impacts)]


def _evaluate(cases: list[Row], options: StudyOptions) -> list[Row]:
    rows = []
    dead = float(_setting(options, "dead_time_ms")) * 1e-3
    noise = float(_setting(options, "noise"))
    strategy = str(_setting(options, "strategy"))
    for case in cases:
        rig = iso6358_valve(case["effective_area_mm2"] * 1e-6, rig=options.rig)
        lag = case["response_time_ms"] * 1e-3 / math.log(9.0)  # 10-90 % of a first-order lag: τ·ln 9
        absorber = Absorber(drive=ValveDrive(dead_time=dead, time_constant=lag))
        seed = int(case_seed(options, NAME, case["impact"]).generate_state(1)[0])
        scenario = Scenario(mass=case["mass"], velocity=case["velocity"], pressure_gauge=case["pressure_gauge"])
        result = absorb(scenario, rig, strategy=strategy, noise=noise, seed=seed, absorber=absorber,
                        sample_rate=options.sample_rate, identification=str(_setting(options, "identification")),
                        early=False)  # valves judged, as recorded, with the valve closed until M1 is known
        m = result.metrics[strategy]
        rows.append({"case": case["case"], "impact": case["impact"], "mass_kg": scenario.mass,
                     "velocity_m_s": scenario.velocity, "pressure_gauge_Pa": scenario.pressure_gauge,
                     "effective_area_mm2": case["effective_area_mm2"], "response_time_ms": case["response_time_ms"],
                     "dead_time_ms": dead * 1e3, "sonic_conductance_m3_sPa": rig.valve.sonic_conductance,
                     "valve": valve_label(case["effective_area_mm2"], case["response_time_ms"]),
                     "strategy": strategy, "identification": result.identification,
                     "stage_b_ratio": finite_or_none(m.stage_b_ratio),
                     "whole_event_peak_ratio": finite_or_none(m.whole_event_peak_ratio),
                     "common_window_excluded": result.window.reason or None, "bottomed_out": m.bottomed_out,
                     "rebound_m": finite_or_none(m.rebound), "control_start_s": finite_or_none(m.control_start)})
    return rows



def valve_label(area_mm2: float, response_ms: float) -> str:
    """The valve of a row as one label: ``"100 mm², 3 ms"``."""
    return f"{float(area_mm2):g} mm², {float(response_ms):g} ms"


def _figure(rows: list[Row], options: StudyOptions) -> StudyFigure:
    """The figure's maps over valve size × response time: median and 90th-percentile R_B on the common set of
    impacts (every valve has R_B on them) and the number of runs that bottomed out."""
    areas = sorted({r["effective_area_mm2"] for r in rows})
    times = sorted({r["response_time_ms"] for r in rows})
    kept, _ = common_set(rows, key="impact", group="valve")
    grids = {key: np.full((len(times), len(areas)), np.nan) for key in ("median", "p90", "bottomed")}
    for i, t in enumerate(times):
        for j, a in enumerate(areas):
            chosen = [r for r in rows if r["effective_area_mm2"] == a and r["response_time_ms"] == t]
            values = values_on(rows, kept, valve_label(a, t), "stage_b_ratio", key="impact", group="valve")
            values = values[np.isfinite(values)]
            if values.size:
                grids["median"][i, j] = np.median(values)
                grids["p90"][i, j] = np.percentile(values, 90)
            grids["bottomed"][i, j] = sum(flag(r.get("bottomed_out")) for r in chosen)
    return StudyFigure("plot_valve_design", rows, {"areas": areas, "times": times, "grids": grids,
                                                   "kept": len(kept)})


def _valves(rows: list[Row]) -> list[Row]:
    out = []
    kept, _ = common_set(rows, key="impact", group="valve")
    for key in dict.fromkeys((r["effective_area_mm2"], r["response_time_ms"]) for r in rows):
        chosen = [r for r in rows if (r["effective_area_mm2"], r["response_time_ms"]) == key]
        ratio = values_on(rows, kept, valve_label(*key), "stage_b_ratio", key="impact", group="valve")
        ratio = ratio[np.isfinite(ratio)]
        out.append({"effective area [mm²]": key[0], "response 10-90 % [ms]": key[1], "impacts": len(chosen),
                    "common set": len(kept),
                    "median R_B": float(np.median(ratio)) if ratio.size else math.nan,
                    "90th pct R_B": float(np.percentile(ratio, 90)) if ratio.size else math.nan,
                    "bottomed out": sum(flag(r.get("bottomed_out")) for r in chosen)})
    return out


def needed_valve(rows: list[Row], target: float = TARGET) -> Row | None:
    """The valve of the sweep with median R_B <= ``target`` and no bottoming that is smallest, then slowest; None
    when no valve of the sweep reaches it."""
    ok = [v for v in _valves(rows) if v["median R_B"] <= target and v["bottomed out"] == 0]
    if not ok:
        return None
    return min(ok, key=lambda v: (v["effective area [mm²]"], -v["response 10-90 % [ms]"]))


def _summary(rows: list[Row]) -> list[Row]:
    valves = _valves(rows)
    best = min(valves, key=lambda v: v["median R_B"] if math.isfinite(v["median R_B"]) else math.inf)
    need = needed_valve(rows)
    if need is None:
        verdict = (f"none of the sweep: the lowest median R_B is {best['median R_B']:.3g} "
                   f"({best['effective area [mm²]']:g} mm², {best['response 10-90 % [ms]']:g} ms)")
    else:
        verdict = (f"{need['effective area [mm²]']:g} mm² with a 10-90 % response of {need['response 10-90 % [ms]']:g}"
                   f" ms or faster (median R_B {need['median R_B']:.3g}, 90th percentile {need['90th pct R_B']:.3g})")
    impacts = len({r["impact"] for r in rows})
    return [{"quantity": "the valve the stand needs for a median R_B <= 1.1 (no bottoming)",
             "ours": f"{verdict}; over {impacts} impacts", "paper": "beyond the paper"}]


STUDY = register(Study(name=NAME, title="Valve design: R_B on the common window over valve size and response time",
                       figure="", cases=_cases, evaluate=_evaluate, aggregate=_valves, summary=_summary,
                       drawing=_figure, chunk_size=5, defaults=DEFAULTS, settings=SETTINGS,
                       rig=ABSORPTION_RIG))
