"""Study ``absorption`` (the paper's Fig. 10b over a grid): every absorber strategy, identified and oracle.

A wrapper of :func:`impactometer.control.study.case_rows`: one work unit per impact, each with its own seed (a
function of the root seed and the case index), so the table does not depend on the number of workers. Summarised
next to the absorber's acceptance criteria (median efficiency vs the physical bound η_max, bottoming out of the
identified real-time strategy where the oracle does not, peak force after the control start vs the oracle).
"""

from __future__ import annotations

import math
from collections import defaultdict

import numpy as np

from .base import Row, Setting, Study, StudyOptions, case_seed, register, scenario_grid

NAME = "absorption"
REQUIRES = ("impactometer.control.study",)
#: default values per grid axis (8 impacts at the corners of the ranges; ``--grid 5`` gives the paper's 125)
GRID = 2
DEFAULTS = {"noise": 0.02, "identification": "robust"}
SETTINGS = {"noise": Setting("number", 0.0, 1.0, "fraction"),
            "identification": Setting("choice", choices=("robust", "paper", "oracle"))}


def _cases(options: StudyOptions) -> list[Row]:
    return scenario_grid(options, GRID)  # one noise realisation per impact (the summary is per impact)


def _evaluate(cases: list[Row], options: StudyOptions) -> list[Row]:
    from ..control.study import case_rows

    rows = []
    for case in cases:
        seed = int(case_seed(options, NAME, case["case"]).generate_state(1)[0])
        scenario = {k: case[k] for k in ("mass", "velocity", "pressure_gauge")}
        rows += [{"case": case["case"], **row} for row in case_rows(
            scenario, options.rig, noise=float(options.param(NAME, "noise", DEFAULTS["noise"])), seed=seed,
            identification=options.param(NAME, "identification", DEFAULTS["identification"]), absorber=None,
            sample_rate=options.sample_rate)]
    return rows


def _finite(values) -> np.ndarray:
    out = np.array([np.nan if v is None else float(v) for v in values], dtype=float)
    return out[np.isfinite(out)]


def _aggregate(rows: list[Row]) -> list[Row]:
    out = []
    for strategy in dict.fromkeys(r["strategy"] for r in rows):
        chosen = [r for r in rows if r["strategy"] == strategy]
        eff = _finite(r.get("efficiency") for r in chosen)
        peak = _finite(r.get("peak_force_controlled_N") for r in chosen)
        out.append({"strategy": strategy, "n": len(chosen),
                    "median efficiency": float(np.median(eff)) if eff.size else math.nan,
                    "median η_max": float(np.median(_finite(r.get("efficiency_max") for r in chosen)))
                    if _finite(r.get("efficiency_max") for r in chosen).size else math.nan,
                    "median peak force after control [kN]": float(np.median(peak)) / 1e3 if peak.size else math.nan,
                    "bottomed out": sum(bool(r.get("bottomed_out")) for r in chosen),
                    "rebounded": sum(bool(r.get("rebounded")) for r in chosen)})
    return out


def _summary(rows: list[Row]) -> list[Row]:
    from ..control.study import ORACLE, acceptance_summary

    s = {k: (math.nan if v is None else v) for k, v in acceptance_summary(rows).items()}
    s = defaultdict(lambda: math.nan, s)
    return [{"quantity": "median absorber efficiency: realtime (identified) / closed valve / bound η_max",
             "ours": f"{s['realtime: median efficiency']:.3g} / {s['closed: median efficiency']:.3g} / "
                     f"{s['efficiency_max_median']:.3g} over {s['cases']} impacts",
             "paper": "real-time control holds a constant deceleration in stage B (Fig. 10b)"},
            {"quantity": "impacts where the identified realtime strategy bottoms out and the oracle does not",
             "ours": f"{s['bottomed_out_identified_not_oracle']} (oracle bottoms out in "
                     f"{s[f'{ORACLE}: bottomed out']})", "paper": "not stated"},
            {"quantity": "peak force after control start, identified vs oracle (median / max deviation)",
             "ours": f"{s['peak_vs_oracle_median'] * 100:.3g} % / {s['peak_vs_oracle_max'] * 100:.3g} %",
             "paper": "not stated"}]


def _plot(rows: list[Row], options: StudyOptions):
    from .plots import plot_strategy_distributions
    return plot_strategy_distributions(rows)


STUDY = register(Study(name=NAME, title="Adaptive absorption: closed, constant, realtime (identified and oracle)",
                       figure="Fig. 10b", cases=_cases, evaluate=_evaluate, aggregate=_aggregate, summary=_summary,
                       plot=_plot, chunk_size=1, requires=REQUIRES, defaults=DEFAULTS,
                       settings=SETTINGS))
