"""Study ``absorption`` (the paper's Fig. 10b over a grid): every absorber strategy judged on the whole event and,
on one common window per impact, on the controller's R_B (:mod:`impactometer.control.event`).

Per impact and noise realisation (one work unit, its own seed; ``--seeds K`` gives each impact K realisations):
``closed``, ``constant``, ``realtime`` and ``predictive`` with M1 and V0
identified from the noisy closed-valve record (:func:`impactometer.control.absorb`), ``predictive`` with the true
M1 and V0 from first contact (the oracle: what the loop's instant and its identification cost together) and from
the loop's own control start (what the identification's error alone costs), and the achievable reference
(:mod:`impactometer.control.reference`: the best opening program found on the same plant with full knowledge, and
the best of each of its families from first contact). One row per strategy, plus one for the reference, every one
carrying the same per-impact columns as ``absorb --json``.
The identification's answer is acted on ``absorption.latency`` after the last sample it used (default 1 ms, a
compiled real-time core; ``--set absorption.latency=3ms``): a stated budget, so the rows are the same for the same
arguments on any machine. ``--set absorption.control_start_ms=T`` makes the answer known T ms after first contact
(with ``absorption.identification=oracle``: what a controller that knew M1 and V0 then would reach).
The force strategies act on what is known as soon as it is known (``absorption.policy=early``, the default;
``absorb(early=True)``: V0 from the first 0.5 ms of contact, M1's prior over the rated masses, refined in stage B and
by the identification's answer); ``--set absorption.policy=wait`` keeps the valve closed until M1 is known.

R_B,wide (``wide_window_ratio``) is the same peak taken from the end of the first contact pulse + 1 ms: a peak
moved before the common window counts there. Medians and percentiles of R_B are taken over the **common set**: the
impacts on which every row has an R_B. The impacts left out are counted and named (case, M1, V0, p0 and why). The
whole-event figures cover every impact.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from ..control import absorb
from ..control.identified import LATENCY
from ..control.strategies import ALL as ALL_STRATEGIES
from ..rig import ABSORPTION_RIG, Scenario
from ..tables import flag, number
from ..validation import finite_or_none
from .base import Row, Setting, Study, StudyFigure, StudyOptions, case_seed, register, scenario_grid
from .identification import seeded_grid

NAME = "absorption"
#: default values per grid axis (8 impacts at the corners of the ranges; ``--grid 5`` gives the paper's 125)
GRID = 2
DEFAULTS = {"noise": 0.02, "identification": "model", "strategies": ["closed", "constant", "realtime",
                                                                       "predictive"],
            "reference_evaluations": 240, "control_start_ms": None, "latency": LATENCY, "policy": "early"}
SETTINGS = {"noise": Setting("number", 0.0, 1.0, "fraction"),
            "identification": Setting("choice", choices=("robust", "paper", "model", "oracle")),
            "strategies": Setting("choices", choices=ALL_STRATEGIES),
            "reference_evaluations": Setting("integer", 0, 10_000),
            "control_start_ms": Setting("number", 0.0, 1e3),
            "latency": Setting("number", 0.0, 0.1, "time"),
            "policy": Setting("choice", choices=("wait", "early"))}
#: the strategy run with the oracle, and the labels of the extra rows
ORACLE_OF = "predictive"
ORACLE = f"{ORACLE_OF} (oracle)"
ORACLE_LATE = f"{ORACLE_OF} (oracle from the control start)"
#: the reference's families, each as its best program from first contact (the ``achievable_<key>_force_ratio``
#: columns)
FAMILIES = {"segments": "segments", "level": "level", "moving target": "moving_target",
            "partial knowledge": "partial_knowledge"}
REFERENCE = "achievable reference"
#: the per-strategy columns of a row (keys of ``AbsorptionResult.to_dict()["strategies"][name]``): the headline
#: first, then the run's own window (supplementary)
METRICS = ("whole_event_peak_ratio", "peak_deceleration_g", "whole_event_efficiency", "stroke_used_m",
           "stroke_utilisation", "stopped", "time_to_stop_s", "bottomed_out", "rebound_m", "stage_b_ratio",
           "stage_b_peak_force_N", "wide_window_ratio", "wide_window_peak_force_N", "wide_window_start_s",
           "common_window_start_s", "floor_force_N", "reference_force_N", "impact_force_N",
           "control_start_s", "whole_event_peak_force_N", "own_window_force_ratio", "own_window_start_s",
           "peak_force_stage_a_N")
#: the absorber's design targets: median and 90th percentile of R_B, improvement over the closed
#: valve, rebound limit [m] and the share of impacts below it, identified vs oracle R_B (deviation, share), median
#: R_B against the achievable reference's, the identification's early answer [s] and its share
TARGETS = {"median": 1.2, "p90": 1.5, "improvement": 2.0, "rebound": 5e-3, "rebound_share": 0.95,
           "oracle_deviation": 0.05, "oracle_share": 0.95, "achievable": 1.10, "early": 0.010, "early_share": 0.90}


def _cases(options: StudyOptions) -> list[Row]:
    """The grid's impacts, each ``options.seeds`` times with its own noise realisation (:func:`.identification.
    seeded_grid`, realisation-major): a case is one impact and one realisation (``impact``: the impact's index in
    the grid, ``seed_index``: the realisation). The first realisation of an impact keeps the impact's index as its
    case, so its seed does not depend on ``seeds``."""
    grid = scenario_grid(options, GRID)
    return [{**s, "impact": i % len(grid)} for i, s in enumerate(seeded_grid(grid, options))]


def case_rows(case: Row, options: StudyOptions, seed: int) -> list[Row]:
    """Rows of one impact: the identified strategies, the oracle and the achievable reference."""
    scenario = Scenario(mass=case["mass"], velocity=case["velocity"], pressure_gauge=case["pressure_gauge"])
    noise = float(options.param(NAME, "noise", DEFAULTS["noise"]))
    strategies = list(options.param(NAME, "strategies", DEFAULTS["strategies"]))
    forced = options.param(NAME, "control_start_ms", DEFAULTS["control_start_ms"])  # what acting earlier would give
    latency = float(options.param(NAME, "latency", DEFAULTS["latency"]))
    found = absorb(scenario, options.rig, strategy=strategies, reference=True, noise=noise, seed=seed,
                   control_start=None if forced is None else float(forced) * 1e-3,
                   sample_rate=options.sample_rate,
                   identification=options.param(NAME, "identification", DEFAULTS["identification"]),
                   reference_evaluations=int(options.param(NAME, "reference_evaluations",
                                                           DEFAULTS["reference_evaluations"])),
                   latency=latency, early=options.param(NAME, "policy", DEFAULTS["policy"]) == "early")
    # the same controller with the true M1 and V0 from first contact (what the loop's instant costs is judged
    # against it), and from the loop's own control start (what the identification's error costs)
    oracle = absorb(scenario, options.rig, strategy=ORACLE_OF, identification="oracle", control_start=0.0,
                    noise=noise, seed=seed, sample_rate=options.sample_rate)
    start = found.control_start if math.isfinite(found.control_start) else None
    late = absorb(scenario, options.rig, strategy=ORACLE_OF, identification="oracle", control_start=start,
                  noise=noise, seed=seed, sample_rate=options.sample_rate)
    summary = found.to_dict()
    ident = summary["identification"]
    base = {"case": case["case"], "impact": case.get("impact", case["case"]), "seed_index": case.get("seed_index", 0),
            "mass_kg": scenario.mass, "velocity_m_s": scenario.velocity,
            "pressure_gauge_Pa": scenario.pressure_gauge, "rig": options.rig.name, "noise": noise, "seed": seed,
            "latency_s": latency,
            "identified_mass_kg": ident["mass_kg"], "identified_mass_std_kg": ident["mass_std_kg"],
            "identified_velocity_m_s": ident["velocity_m_s"], "identified_available_at_s": ident["available_at_s"],
            "identification_error": ident["error"], "common_window_excluded": summary["common_window_excluded"],
            "over_capacity": summary["over_capacity"],
            "achievable_force_ratio": summary.get("achievable_force_ratio"),
            "achievable_from_start_force_ratio": summary.get("achievable_from_start_force_ratio"),
            **{f"achievable_{key}_force_ratio": (summary.get("achievable_by_family") or {}).get(family)
               for family, key in FAMILIES.items()}}
    rows = []
    for result, label in ((summary, None), (oracle.to_dict(), ORACLE), (late.to_dict(), ORACLE_LATE)):
        for name, metrics in result["strategies"].items():
            rows.append({**base, "strategy": label or name, "identification": result["identification"]["method"],
                         **{k: metrics.get(k) for k in METRICS}, "estimated_mass_kg": metrics.get("estimated_mass_kg")})
    reference = found.reference
    if reference is not None:
        shared = {k: summary[k] for k in ("common_window_start_s", "floor_force_N", "reference_force_N",
                                          "control_start_s")}
        rows.append({**base, "strategy": REFERENCE, "identification": "oracle", **dict.fromkeys(METRICS), **shared,
                     "stage_b_ratio": finite_or_none(reference.force_ratio),
                     "whole_event_peak_ratio": finite_or_none(reference.whole_event_peak_ratio),
                     "stroke_used_m": finite_or_none(reference.stroke_used), "reference_family": reference.family,
                     "reference_runs": reference.runs, "estimated_mass_kg": None})
    return rows


def _evaluate(cases: list[Row], options: StudyOptions) -> list[Row]:
    rows = []
    for case in cases:
        seed = int(case_seed(options, NAME, case["case"]).generate_state(1)[0])
        rows += case_rows(case, options, seed)
    return rows


def common_set(rows: Sequence[Row], column: str = "stage_b_ratio", *, key: str = "case",
               group: str = "strategy") -> tuple[list[Any], list[Row]]:
    """The impacts (values of ``key``) on which every ``group`` of the rows has a finite ``column``, and one line
    per impact left out: ``{key, mass_kg, velocity_m_s, pressure_gauge_Pa, reason}``."""
    groups = list(dict.fromkeys(r[group] for r in rows))
    by = {(r[key], r[group]): r for r in rows}
    kept, left = [], []
    for impact in dict.fromkeys(r[key] for r in rows):
        missing = [g for g in groups if not math.isfinite(number((by.get((impact, g)) or {}).get(column)))]
        if not missing:
            kept.append(impact)
            continue
        row = next(r for r in rows if r[key] == impact)
        why = row.get("common_window_excluded") or f"no {column} for {', '.join(map(str, missing))}"
        left.append({key: impact, **{k: row.get(k) for k in ("mass_kg", "velocity_m_s", "pressure_gauge_Pa")},
                     "reason": why})
    return kept, left


def values_on(rows: Sequence[Row], impacts: Sequence[Any], strategy: str, column: str, *, key: str = "case",
              group: str = "strategy") -> np.ndarray:
    """``column`` of ``strategy`` on ``impacts`` (in that order; NaN where missing)."""
    by = {(r[key], r[group]): r for r in rows}
    return np.array([number((by.get((i, strategy)) or {}).get(column)) for i in impacts])


#: the columns the study's figure draws, per strategy, on the common set of impacts
FIGURE_COLUMNS = ("stage_b_ratio", "whole_event_peak_ratio", "mass_kg", "achievable_from_start_force_ratio")


def _figure(rows: list[Row], options: StudyOptions) -> StudyFigure:
    """The figure's values: each strategy's :data:`FIGURE_COLUMNS` on the common set of impacts
    (:func:`common_set`), how many impacts it holds and how many it leaves out, the targets."""
    kept, left = common_set(rows)
    strategies = list(dict.fromkeys(r["strategy"] for r in rows))
    values = {name: {column: values_on(rows, kept, name, column) for column in FIGURE_COLUMNS}
              for name in strategies}
    return StudyFigure("plot_absorption_study", rows, {"values": values, "kept": len(kept), "left": len(left),
                                                       "targets": TARGETS, "reference": REFERENCE})


def _stat(values: np.ndarray, q: float) -> float:
    values = values[np.isfinite(values)]
    return float(np.percentile(values, q)) if values.size else math.nan


def _aggregate(rows: list[Row]) -> list[Row]:
    kept, _ = common_set(rows)
    impacts = list(dict.fromkeys(r["case"] for r in rows))
    out = []
    for strategy in dict.fromkeys(r["strategy"] for r in rows):
        chosen = [r for r in rows if r["strategy"] == strategy]
        ratio = values_on(rows, kept, strategy, "stage_b_ratio")
        wide = values_on(rows, kept, strategy, "wide_window_ratio")
        peak = values_on(rows, impacts, strategy, "whole_event_peak_ratio")
        shared = values_on(rows, kept, strategy, "whole_event_peak_ratio")
        reference = strategy == REFERENCE  # it exists on the common set only
        out.append({"strategy": strategy, "impacts": len(chosen), "common set": len(kept),
                    "median R_B": _stat(ratio, 50), "90th pct R_B": _stat(ratio, 90),
                    "median R_B,wide": _stat(wide, 50), "90th pct R_B,wide": _stat(wide, 90),
                    "median peak / F0, common set": _stat(shared, 50),
                    "90th pct peak / F0, common set": _stat(shared, 90),
                    "median peak / F0": None if reference else _stat(peak, 50),
                    "90th pct peak / F0": None if reference else _stat(peak, 90),
                    "median peak deceleration [g]": _stat(values_on(rows, impacts, strategy, "peak_deceleration_g"),
                                                          50),
                    "median η (whole event)": _stat(values_on(rows, impacts, strategy, "whole_event_efficiency"),
                                                    50),
                    "median stroke used [mm]": _stat(values_on(rows, impacts, strategy, "stroke_used_m") * 1e3, 50),
                    "not stopped": None if reference else sum(not flag(r.get("stopped")) for r in chosen),
                    "bottomed out": None if reference else sum(flag(r.get("bottomed_out")) for r in chosen),
                    "rebound < 5 mm": None if reference else
                    int(np.sum(np.array([number(r.get("rebound_m")) for r in chosen]) < TARGETS["rebound"])),
                    "median R, own window (supplementary)": None if reference else
                    _stat(values_on(rows, impacts, strategy, "own_window_force_ratio"), 50)})
    return out


def acceptance(rows: list[Row], strategy: str = "predictive") -> dict[str, Any]:
    """The absorber's acceptance figures for ``strategy`` over ``rows`` on the common set (see :data:`TARGETS`)."""
    kept, left = common_set(rows)
    mine = values_on(rows, kept, strategy, "stage_b_ratio")
    wide = values_on(rows, kept, strategy, "wide_window_ratio")
    closed = values_on(rows, kept, "closed", "stage_b_ratio")
    oracle = values_on(rows, kept, ORACLE, "stage_b_ratio")
    oracle_late = values_on(rows, kept, ORACLE_LATE, "stage_b_ratio")
    families = {family: values_on(rows, kept, REFERENCE, f"achievable_{key}_force_ratio")
                for family, key in FAMILIES.items()}
    reference = values_on(rows, kept, REFERENCE, "stage_b_ratio")
    late = values_on(rows, kept, REFERENCE, "achievable_from_start_force_ratio")
    chosen = [r for r in rows if r["strategy"] == strategy]
    deviation = np.abs(mine / oracle - 1.0)
    late_deviation = np.abs(mine / oracle_late - 1.0)
    early = np.array([number(r.get("identified_available_at_s")) for r in chosen])
    rebound = np.array([number(r.get("rebound_m")) for r in chosen])
    median = _stat(mine, 50)
    return {"impacts": len(chosen), "common set": len(kept), "left out": left, "median R_B": median,
            "90th pct R_B": _stat(mine, 90), "median R_B,wide": _stat(wide, 50), "90th pct R_B,wide": _stat(wide, 90),
            "closed median R_B": _stat(closed, 50),
            "improvement": _stat(closed, 50) / median, "oracle median R_B": _stat(oracle, 50),
            "oracle 90th pct R_B": _stat(oracle, 90),
            "oracle from the control start median R_B": _stat(oracle_late, 50),
            "oracle from the control start 90th pct R_B": _stat(oracle_late, 90),
            "within 5 % of the oracle from the control start": int(np.sum(late_deviation
                                                                          <= TARGETS["oracle_deviation"])),
            "families": {family: {"median R_B": _stat(v, 50), "90th pct R_B": _stat(v, 90),
                                  "median gap": _stat(mine / v, 50)} for family, v in families.items()},
            "achievable median R_B": _stat(reference, 50),
            "achievable 90th pct R_B": _stat(reference, 90),
            "achievable from the control start median R_B": _stat(late, 50),
            "achievable from the control start 90th pct R_B": _stat(late, 90),
            "median R_B / achievable median": median / _stat(reference, 50),
            "below the achievable by > 5 %": int(np.sum(mine < 0.95 * reference)),
            "oracle below the achievable by > 5 %": int(np.sum(oracle < 0.95 * reference)),
            "within 5 % of the oracle": int(np.sum(deviation <= TARGETS["oracle_deviation"])),
            # the same law, noise-free, on the prior's M1 until the loop's answer and the true M1 from then on: what
            # the instant of the answer alone costs
            "partial knowledge within 5 % of the oracle": int(np.sum(
                np.abs(families["partial knowledge"] / oracle - 1.0) <= TARGETS["oracle_deviation"])),
            "not above the oracle by more than 5 %": int(np.sum(mine <= (1.0 + TARGETS["oracle_deviation"]) * oracle)),
            "largest deviation from the oracle": float(np.nanmax(deviation)) if deviation.size else math.nan,
            "bottomed out": sum(flag(r.get("bottomed_out")) for r in chosen),
            "not stopped": sum(not flag(r.get("stopped")) for r in chosen),
            "rebound below 5 mm": int(np.sum(rebound < TARGETS["rebound"])),
            "largest rebound [mm]": float(np.nanmax(rebound)) * 1e3 if np.isfinite(rebound).any() else math.nan,
            "early answers": int(np.sum(early <= TARGETS["early"])),
            "median answer [ms]": _stat(early, 50) * 1e3,
            "whole-event 90th pct peak / F0": _stat(np.array([number(r.get("whole_event_peak_ratio"))
                                                              for r in chosen]), 90)}


def left_out_text(left: Sequence[Row]) -> str:
    """The impacts left out of a common set, named: ``case 3 (10 kg, 1 m/s, 400 kPa: why)``; the runs of one impact
    left out for the same reason (its noise realisations) on one line: ``cases 3, 128, 253 (...)``."""
    named: dict[str, list[str]] = {}
    for x in left:
        what = (f"{number(x['mass_kg']):g} kg, {number(x['velocity_m_s']):.2g} m/s, "
                f"{number(x['pressure_gauge_Pa']) / 1e3:g} kPa: {x['reason']}")
        named.setdefault(what, []).append(str(x["case"]))
    return "; ".join(f"case{'s' if len(cases) > 1 else ''} {', '.join(cases)} ({what})"
                     for what, cases in named.items()) or "none"


def _summary(rows: list[Row]) -> list[Row]:
    a = acceptance(rows)
    n, c = a["impacts"], a["common set"]
    t = TARGETS
    seeds = len({r.get("seed_index", 0) for r in rows})
    impacts = "impacts" if seeds == 1 else f"runs (impacts × {seeds} noise realisations)"
    return [
        {"quantity": "R_B of the predictive strategy (identified) on the common window: median / 90th percentile",
         "ours": f"{a['median R_B']:.3g} / {a['90th pct R_B']:.3g} over the {c} {impacts} of the common set "
                 f"(oracle from first contact {a['oracle median R_B']:.3g} / {a['oracle 90th pct R_B']:.3g}, from "
                 f"the control start {a['oracle from the control start median R_B']:.3g} / "
                 f"{a['oracle from the control start 90th pct R_B']:.3g}; achievable "
                 f"{a['achievable median R_B']:.3g} / {a['achievable 90th pct R_B']:.3g})",
         "paper": f"targets <= {t['median']} / <= {t['p90']}"},
        {"quantity": "R_B,wide of the predictive strategy (from the first pulse's end + 1 ms): median / 90th "
                     "percentile",
         "ours": f"{a['median R_B,wide']:.3g} / {a['90th pct R_B,wide']:.3g} (a peak moved before the common window "
                 "counts)", "paper": "not below R_B by much: no peak moved out of the window"},
        {"quantity": "achievable reference acting only from the loop's control start: median / 90th percentile R_B",
         "ours": f"{a['achievable from the control start median R_B']:.3g} / "
                 f"{a['achievable from the control start 90th pct R_B']:.3g} (from first contact "
                 f"{a['achievable median R_B']:.3g} / {a['achievable 90th pct R_B']:.3g})",
         "paper": "what the answer's time leaves to any program of the family"},
        {"quantity": "best of each reference family from first contact: median / 90th percentile R_B (median of "
                     "the loop's R_B / it)",
         "ours": "; ".join(f"{family} {v['median R_B']:.3g} / {v['90th pct R_B']:.3g} ({v['median gap']:.3g})"
                           for family, v in a["families"].items()),
         "paper": "the bound of each family for a loop that acts from first contact"},
        {"quantity": "impacts left out of the common set",
         "ours": f"{n - c}{'' if seeds == 1 else ' runs'}: {left_out_text(a['left out'])}",
         "paper": "counted and named"},
        {"quantity": "median R_B of the closed valve / predictive",
         "ours": f"{a['closed median R_B']:.3g} / {a['median R_B']:.3g} ({a['improvement']:.2f}×)",
         "paper": f"target >= {t['improvement']:g}×"},
        {"quantity": "identified R_B within 5 % of the oracle's (the same controller, true M1 and V0 from first "
                     "contact)",
         "ours": f"{a['within 5 % of the oracle']} of {c} (largest deviation "
                 f"{a['largest deviation from the oracle'] * 100:.3g} %; not above it by more than 5 %, the loop "
                 f"below the oracle counted as within: {a['not above the oracle by more than 5 %']} of {c}); of the "
                 "oracle from the control start: "
                 f"{a['within 5 % of the oracle from the control start']} of {c}; the partial-knowledge reference "
                 "(noise-free, the true M1 from the loop's answer on): "
                 f"{a['partial knowledge within 5 % of the oracle']} of {c}", "paper": "target: >= 95 %"},
        {"quantity": "median R_B / the achievable reference's median",
         "ours": f"{a['median R_B / achievable median']:.3g} (predictive below the reference by > 5 % on "
                 f"{a['below the achievable by > 5 %']}, oracle on {a['oracle below the achievable by > 5 %']})",
         "paper": f"target <= {t['achievable']:g}"},
        {"quantity": "bottoming out; not stopped; rebound below 5 mm",
         "ours": f"{a['bottomed out']} of {n}; {a['not stopped']} of {n}; {a['rebound below 5 mm']} of {n} "
                 f"(largest {a['largest rebound [mm]']:.2g} mm)", "paper": "targets: none; none; >= 95 %"},
        {"quantity": "whole event: 90th percentile of the CFC 60 peak / F0 (predictive)",
         "ours": f"{a['whole-event 90th pct peak / F0']:.3g}", "paper": "what a person or payload feels"},
        {"quantity": "identification answered within 10 ms of first contact",
         "ours": f"{a['early answers']} of {n} (median {a['median answer [ms]']:.3g} ms)",
         "paper": f"design target >= {t['early_share'] * 100:g} %"}]


STUDY = register(Study(name=NAME, title="Adaptive absorption: whole event and R_B on a common window, strategies, "
                                        "oracle, achievable reference",
                       figure="Fig. 10b", cases=_cases, evaluate=_evaluate, aggregate=_aggregate, summary=_summary,
                       drawing=_figure, chunk_size=1, defaults=DEFAULTS, settings=SETTINGS,
                       rig=ABSORPTION_RIG))
