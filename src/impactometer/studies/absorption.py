"""Study ``absorption`` (the paper's Fig. 10b over a grid): every absorber strategy judged on stage B.

Per impact (one work unit, its own seed): ``closed``, ``constant``, ``realtime`` and ``predictive`` with M1 and V0
identified from the noisy closed-valve record (:func:`impactometer.control.absorb`), ``predictive`` with the true
M1 and V0 started at the same instant (the oracle: the cost of the identification), and the achievable reference
of the valve from that instant (:mod:`impactometer.control.reference`). One row per strategy, plus one for the
reference. Runs without a stage B are kept, flagged ``stage_b = False`` and counted apart. The summary sets the
figures next to the acceptance criteria of the absorber.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..control import absorb
from ..control.strategies import ALL as ALL_STRATEGIES
from ..rig import ABSORPTION_RIG, Scenario
from ..validation import finite_or_none
from .base import Row, Setting, Study, StudyOptions, case_seed, plotted_by, register, scenario_grid
from .tables import finite_values, flag, number

NAME = "absorption"
#: default values per grid axis (8 impacts at the corners of the ranges; ``--grid 5`` gives the paper's 125)
GRID = 2
DEFAULTS = {"noise": 0.02, "identification": "robust", "strategies": ["closed", "constant", "realtime",
                                                                       "predictive"]}
SETTINGS = {"noise": Setting("number", 0.0, 1.0, "fraction"),
            "identification": Setting("choice", choices=("robust", "paper", "oracle")),
            "strategies": Setting("choices", choices=ALL_STRATEGIES)}
#: the strategy run with the oracle, and the labels of the extra rows
ORACLE_OF = "predictive"
ORACLE = f"{ORACLE_OF} (oracle)"
REFERENCE = "achievable reference"
#: the metrics kept per row (keys of ``AbsorptionMetrics.to_dict()``)
METRICS = ("control_start_s", "stage_b", "stage_b_start_s", "reference_force_N", "stage_b_peak_force_N",
           "stage_b_force_ratio", "stage_b_efficiency", "stage_b_force_ratio_first", "bottomed_out", "rebound_m",
           "time_to_stop_s", "peak_force_stage_a_N", "stroke_used_m", "efficiency", "peak_force_controlled_N")
#: acceptance targets of the absorber (the issue's): median and 90th percentile of R, improvement over the closed
#: valve, rebound limit [m] and the share of cases below it, identified vs oracle R
TARGETS = {"median": 1.3, "p90": 1.6, "improvement": 2.0, "rebound": 5e-3, "rebound_share": 0.95,
           "oracle_deviation": 0.10}


def _cases(options: StudyOptions) -> list[Row]:
    return scenario_grid(options, GRID)  # one noise realisation per impact (the summary is per impact)


def case_rows(case: Row, options: StudyOptions, seed: int) -> list[Row]:
    """Rows of one impact: the identified strategies, the oracle and the achievable reference."""
    scenario = Scenario(mass=case["mass"], velocity=case["velocity"], pressure_gauge=case["pressure_gauge"])
    noise = float(options.param(NAME, "noise", DEFAULTS["noise"]))
    strategies = list(options.param(NAME, "strategies", DEFAULTS["strategies"]))
    found = absorb(scenario, options.rig, strategy=strategies, reference=True, noise=noise, seed=seed,
                   sample_rate=options.sample_rate,
                   identification=options.param(NAME, "identification", DEFAULTS["identification"]))
    start = found.control_start if math.isfinite(found.control_start) else None  # the oracle starts with the loop
    oracle = absorb(scenario, options.rig, strategy=ORACLE_OF, identification="oracle", control_start=start,
                    noise=noise, seed=seed, sample_rate=options.sample_rate)
    base = {"case": case["case"], "mass_kg": scenario.mass, "velocity_m_s": scenario.velocity,
            "pressure_gauge_Pa": scenario.pressure_gauge, "rig": options.rig.name, "noise": noise, "seed": seed}
    ident = found.identified.to_dict()
    ident_columns = {"identified_mass_kg": ident["mass_kg"], "identified_mass_std_kg": ident["mass_std_kg"],
                     "identified_velocity_m_s": ident["velocity_m_s"], "identification_error": ident["error"]}
    reference = found.reference
    rows = []
    for result, label in ((found, None), (oracle, ORACLE)):
        summary = result.to_dict()
        for name, metrics in summary["strategies"].items():
            rows.append({**base, "strategy": label or name, "identification": summary["identification"]["method"],
                         **ident_columns, **{k: metrics.get(k) for k in METRICS},
                         "estimated_mass_kg": metrics.get("estimated_mass_kg"),
                         "achievable_force_ratio": None if reference is None else finite_or_none(reference.force_ratio),
                         "over_capacity": summary["over_capacity"]})
    if reference is not None:
        rows.append({**base, "strategy": REFERENCE, "identification": "oracle", **ident_columns,
                     **dict.fromkeys(METRICS), "control_start_s": finite_or_none(found.control_start),
                     "stage_b": math.isfinite(reference.force_ratio),
                     "stage_b_force_ratio": finite_or_none(reference.force_ratio),
                     "stage_b_efficiency": finite_or_none(reference.efficiency),
                     "stroke_used_m": finite_or_none(reference.stroke_used),
                     "reference_level_N": finite_or_none(reference.level), "estimated_mass_kg": None,
                     "achievable_force_ratio": finite_or_none(reference.force_ratio), "over_capacity": None})
    return rows


def _median(rows: list[Row], column: str) -> float:
    values = finite_values([r for r in rows if flag(r.get("stage_b"))], column)
    return float(np.median(values)) if values.size else math.nan



def _evaluate(cases: list[Row], options: StudyOptions) -> list[Row]:
    rows = []
    for case in cases:
        seed = int(case_seed(options, NAME, case["case"]).generate_state(1)[0])
        rows += case_rows(case, options, seed)
    return rows


def _ratios(rows: list[Row], strategy: str) -> np.ndarray:
    return finite_values([r for r in rows if r["strategy"] == strategy and flag(r.get("stage_b"))],
                         "stage_b_force_ratio")


def _aggregate(rows: list[Row]) -> list[Row]:
    out = []
    for strategy in dict.fromkeys(r["strategy"] for r in rows):
        chosen = [r for r in rows if r["strategy"] == strategy]
        ratio = _ratios(rows, strategy)
        efficiency = finite_values([r for r in chosen if flag(r.get("stage_b"))], "stage_b_efficiency")
        rebound = np.array([number(r.get("rebound_m")) for r in chosen])
        out.append({"strategy": strategy, "impacts": len(chosen),
                    "without stage B": sum(1 for r in chosen if not flag(r.get("stage_b"))),
                    "median R": float(np.median(ratio)) if ratio.size else math.nan,
                    "90th pct R": float(np.percentile(ratio, 90)) if ratio.size else math.nan,
                    "median η_B": float(np.median(efficiency)) if efficiency.size else math.nan,
                    "median R, t_B at the first sustained contact": _median(chosen, "stage_b_force_ratio_first"),
                    "bottomed out": sum(flag(r.get("bottomed_out")) for r in chosen),
                    "rebound < 5 mm": int(np.sum(rebound < TARGETS["rebound"])) if strategy != REFERENCE else None})
    return out


def acceptance(rows: list[Row], strategy: str = "predictive") -> dict[str, Any]:
    """The absorber's acceptance figures for ``strategy`` over ``rows`` (see :data:`TARGETS`)."""
    mine, closed = _ratios(rows, strategy), _ratios(rows, "closed")
    chosen = [r for r in rows if r["strategy"] == strategy]
    by_case = {(r["case"], r["strategy"]): r for r in rows}
    deviation, gap = [], []
    for r in chosen:
        oracle = by_case.get((r["case"], ORACLE))
        ratio = number(r.get("stage_b_force_ratio"))
        if oracle and math.isfinite(ratio * number(oracle.get("stage_b_force_ratio"))):
            deviation.append(abs(ratio / number(oracle["stage_b_force_ratio"]) - 1.0))
        if math.isfinite(ratio * number(r.get("achievable_force_ratio"))):
            gap.append(ratio / number(r["achievable_force_ratio"]))
    rebound = [number(r.get("rebound_m")) for r in chosen]
    median = float(np.median(mine)) if mine.size else math.nan
    return {"impacts": len(chosen), "with stage B": int(mine.size), "median R": median,
            "90th pct R": float(np.percentile(mine, 90)) if mine.size else math.nan,
            "closed median R": float(np.median(closed)) if closed.size else math.nan,
            "improvement": float(np.median(closed)) / median if mine.size and closed.size else math.nan,
            "bottomed out": sum(flag(r.get("bottomed_out")) for r in chosen),
            "rebound below 5 mm": sum(1 for x in rebound if x < TARGETS["rebound"]),
            "within 10 % of the oracle": sum(1 for x in deviation if x <= TARGETS["oracle_deviation"]),
            "compared with the oracle": len(deviation),
            "largest deviation from the oracle": max(deviation) if deviation else math.nan,
            "median R / achievable R": float(np.median(gap)) if gap else math.nan}


def _summary(rows: list[Row]) -> list[Row]:
    a = acceptance(rows)
    n = a["impacts"]
    return [
        {"quantity": "stage-B force ratio R of the predictive strategy (identified): median / 90th percentile",
         "ours": f"{a['median R']:.3g} / {a['90th pct R']:.3g} over {a['with stage B']} impacts with stage B "
                 f"({n - a['with stage B']} without, counted apart)",
         "paper": f"constant deceleration in stage B (Fig. 10b); targets <= {TARGETS['median']} / "
                  f"<= {TARGETS['p90']}"},
        {"quantity": "median R of the closed valve / predictive",
         "ours": f"{a['closed median R']:.3g} / {a['median R']:.3g} ({a['improvement']:.2f}×)",
         "paper": f"target >= {TARGETS['improvement']:g}×"},
        {"quantity": "bottoming out; rebound below 5 mm",
         "ours": f"{a['bottomed out']} of {n}; {a['rebound below 5 mm']} of {n}",
         "paper": "targets: none; >= 95 %"},
        {"quantity": "identified R within 10 % of the oracle's",
         "ours": f"{a['within 10 % of the oracle']} of {a['compared with the oracle']} (largest deviation "
                 f"{a['largest deviation from the oracle'] * 100:.3g} %)", "paper": "target: every impact"},
        {"quantity": "median R / the valve's achievable R (same control start)",
         "ours": f"{a['median R / achievable R']:.3g}", "paper": "1 = all the valve allows"}]


STUDY = register(Study(name=NAME, title="Adaptive absorption judged on stage B: strategies, oracle, achievable R",
                       figure="Fig. 10b", cases=_cases, evaluate=_evaluate, aggregate=_aggregate, summary=_summary,
                       plot=plotted_by("plot_absorption_study"), chunk_size=1, defaults=DEFAULTS, settings=SETTINGS,
                       rig=ABSORPTION_RIG))
