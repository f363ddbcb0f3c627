"""Study ``absorber-design`` (beyond the paper): which stand absorbs the whole event, not only stage B?

Designs: pre-charge p0 × pad (contact law and its secant stiffness at :data:`PAD_DEFLECTION`, the law's other
parameter at its default: :data:`PAD_LAWS`) × valve (effective area of an ISO 6358 valve with b = 0.3 and the
10-90 % response of its actuator after the built-in 0.5 ms dead time) × piston mass (piston and rod). Per design,
the impacts of the M1 × V0 grid over the paper's ranges at the design's p0 are absorbed by the closed loop (2 %
noise, the same noise seed per impact for every design): ``closed`` and ``predictive``, with M1 and V0 from the
identification in the loop (``identification = model``, the default) or known from first contact plus the stated
latency (``oracle``: the R_B a design allows once the loop acts from first contact; the identification's own
answer time on soft pads is then not part of the design's R_B). The loop's policy is ``absorb``'s (``policy``):
``early`` (the default) drives the valve from first contact on V0 and M1's prior over the rated masses, refined as
M1 becomes known; ``wait`` keeps the valve closed until M1 is known. The oracle knows both from first contact +
the latency, so the policy does not change its rows.

Besides the fixed charges, the charge at contact chosen per impact class (light/heavy: M1 below or above the
middle of the paper's mass range; slow/fast: V0 likewise, :func:`impact_class`) is a design of its own: the stand
is charged to the highest of its class charges and vents to the class's charge before contact. It is composed
from the fixed-charge rows of the same hardware (no more simulations); per hardware the class assignments that no
other assignment of that hardware dominates are kept (:func:`designs`).

Per design: the whole-event 90th percentile of the CFC 60 peak / F0 (what a person or a payload feels), the 90th
percentile of the controller's R_B (only where every impact of the design has a common window: one stopped in
stage A has none, and a percentile over a subset would flatter the design; the count is shown), the 90th
percentile of the first contact pulse's peak / F0 (the first collision, the bound a pad and a piston set), the
share of impacts the identification answers within ``EARLY`` of first contact, bottoming and rebound. The Pareto
set is taken on (whole-event p90 peak / F0, p90 R_B) among the designs that never bottom out; the recommended
design is the one of the Pareto set that meets every target (:data:`TARGETS`) with the lowest whole-event p90, or,
when none does, the report says so and shows the front.

The trade-off it measures: a softer pad lowers the first collision (its peak ≈ V0·sqrt(k·μ), μ = M1·M2/(M1 + M2))
but lengthens the stage-A pulses the identification reads, so its answer comes later, and merges stage A into one
long pulse where the common window of R_B is lost; a stiffer one bounces more often (an earlier answer) with a
higher first peak. A constant-force (crush) pad needs a contact law of its own: once the stand has one, an entry
in :data:`PAD_LAWS` maps the sweep's stiffness to its parameters.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable

import numpy as np

from ..control import Absorber, ValveDrive, absorb
from ..control.identified import LATENCY
from ..control.valve import iso6358_valve
from ..errors import ParameterError
from ..rig import ABSORPTION_RIG, CONTACT_LAWS, Scenario
from ..tables import flag, number
from ..validation import finite_or_none
from .base import PAPER_RANGES, Row, Setting, Study, StudyFigure, StudyOptions, case_seed, grid_size, register

NAME = "absorber-design"
#: values per axis of the M1 × V0 grid of each design (the report's maps: ``--grid 3``)
GRID = 2
#: deflection at which a pad's stiffness is its secant stiffness F(δ)/δ [m] (a progressive pad is as stiff there
#: as a linear one of the same stiffness; softer below, stiffer above)
PAD_DEFLECTION = 0.010
#: rebound above which an impact counts as rebounding in the design table [m]
REBOUND_LIMIT = 0.005


def _linear_pad(law: str) -> Callable[[float], dict[str, object]]:
    return lambda stiffness: {"contact.law": law, "contact.stiffness": stiffness}


def _progressive_pad(stiffness: float) -> dict[str, object]:
    """Hunt-Crossley pad F = k·δ^1.5 with F(δ_ref) = stiffness·δ_ref, δ_ref = :data:`PAD_DEFLECTION`."""
    return {"contact.law": "hunt-crossley", "contact.stiffness": stiffness / math.sqrt(PAD_DEFLECTION)}


#: pads the study sweeps: contact law -> the stand's contact parameters for a secant stiffness [N/m] at
#: :data:`PAD_DEFLECTION` (the law's other parameter at its ``CONTACT_LAWS`` default). A constant-force crush pad
#: is one more entry once the stand has a contact law for it.
PAD_LAWS: dict[str, Callable[[float], dict[str, object]]] = {
    "hysteretic": _linear_pad("hysteretic"), "kelvin-voigt": _linear_pad("kelvin-voigt"),
    "hunt-crossley": _progressive_pad}
DEFAULTS = {"pressures": [20e3, 200e3], "laws": ["hysteretic"], "stiffnesses": [1e5, 7e5], "areas_mm2": [100],
            "response_times_ms": [3], "piston_masses": [4.0], "dead_time_ms": 0.5, "noise": 0.02,
            "identification": "model", "policy": "early"}
SETTINGS = {"pressures": Setting("numbers", 0.0, 400e3, "pressure"),
            "laws": Setting("choices", choices=tuple(PAD_LAWS)),
            "stiffnesses": Setting("numbers", 1e3, 1e8),
            "piston_masses": Setting("numbers", 0.1, 100.0),
            "areas_mm2": Setting("numbers", 0.0, 1e4, low_open=True),
            "response_times_ms": Setting("numbers", 0.0, 1e3, low_open=True),
            "dead_time_ms": Setting("number", 0.0, 50.0), "noise": Setting("number", 0.0, 1.0, "fraction"),
            "identification": Setting("choice", choices=("model", "oracle")),
            "policy": Setting("choice", choices=("early", "wait"))}
#: the identification answers early when it does within this time of first contact [s]
EARLY = 0.010
#: what a recommended design must reach: whole-event p90 peak / F0, p90 R_B, share of early answers
TARGETS = {"whole_event_p90": 3.0, "stage_b_p90": 1.5, "early_share": 0.9}
#: impact classes of the charge chosen per class, in the order of :func:`impact_class`
CLASSES = ("light-slow", "light-fast", "heavy-slow", "heavy-fast")


def _setting(options: StudyOptions, key: str):
    return options.param(NAME, key, DEFAULTS[key])


def pad_parameters(law: str, stiffness: float) -> dict[str, object]:
    """The stand's contact parameters (dotted names) of a pad of ``law`` with secant stiffness ``stiffness``
    [N/m] at :data:`PAD_DEFLECTION`."""
    if law not in PAD_LAWS:
        raise ParameterError(f"pad law must be one of {sorted(PAD_LAWS)} (contact laws of the stand: "
                             f"{sorted(CONTACT_LAWS)}), got {law!r}")
    if not (isinstance(stiffness, (int, float)) and math.isfinite(stiffness) and stiffness > 0.0):
        raise ParameterError(f"pad stiffness must be > 0 [N/m], got {stiffness!r}")
    return PAD_LAWS[law](float(stiffness))


def impact_class(mass: float, velocity: float) -> str:
    """The impact's class (:data:`CLASSES`): light below the middle of the paper's mass range [kg], slow below
    the middle of its velocity range [m/s] (the middle itself counts as light / slow)."""
    light = mass <= 0.5 * sum(PAPER_RANGES["mass"])
    slow = velocity <= 0.5 * sum(PAPER_RANGES["velocity"])
    return CLASSES[2 * (not light) + (not slow)]


def hardware_label(law: str, stiffness: float, area_mm2: float, response_ms: float, piston_mass: float) -> str:
    """The stand without its charge: ``"hysteretic 7e+05 N/m, 100 mm², 3 ms, 4 kg"``."""
    return (f"{law} {float(stiffness):.3g} N/m, {float(area_mm2):g} mm², {float(response_ms):g} ms, "
            f"{float(piston_mass):g} kg")


def design_label(pressure_gauge: float, law: str, stiffness: float, area_mm2: float, response_ms: float,
                 piston_mass: float) -> str:
    """One design as a label: ``"200 kPa, hysteretic 7e+05 N/m, 100 mm², 3 ms, 4 kg"`` (p0 in [Pa])."""
    return f"{float(pressure_gauge) / 1e3:g} kPa, " + hardware_label(law, stiffness, area_mm2, response_ms,
                                                                      piston_mass)


def _cases(options: StudyOptions) -> list[Row]:
    n = grid_size(options, GRID)
    impacts = [(float(m), float(v)) for m in np.linspace(*PAPER_RANGES["mass"], n)
               for v in np.linspace(*PAPER_RANGES["velocity"], n)]
    return [{"impact": i, "mass": m, "velocity": v, "pressure_gauge": float(p), "law": law, "stiffness": float(k),
             "effective_area_mm2": float(a), "response_time_ms": float(r), "piston_mass": float(mp)}
            for p in _setting(options, "pressures") for law in _setting(options, "laws")
            for k in _setting(options, "stiffnesses") for a in _setting(options, "areas_mm2")
            for r in _setting(options, "response_times_ms") for mp in _setting(options, "piston_masses")
            for i, (m, v) in enumerate(impacts)]


def _evaluate(cases: list[Row], options: StudyOptions) -> list[Row]:
    rows = []
    dead = float(_setting(options, "dead_time_ms")) * 1e-3
    noise = float(_setting(options, "noise"))
    oracle = _setting(options, "identification") == "oracle"
    policy = _setting(options, "policy")
    for case in cases:
        law = case.get("law", "hysteretic")
        rig = iso6358_valve(case["effective_area_mm2"] * 1e-6,
                            rig=options.rig.replace(**pad_parameters(law, case["stiffness"]),
                                                    **{"cylinder.piston_mass": case["piston_mass"]}))
        lag = case["response_time_ms"] * 1e-3 / math.log(9.0)  # 10-90 % of a first-order lag: τ·ln 9
        absorber = Absorber(drive=ValveDrive(dead_time=dead, time_constant=lag))
        seed = int(case_seed(options, NAME, case["impact"]).generate_state(1)[0])
        scenario = Scenario(mass=case["mass"], velocity=case["velocity"], pressure_gauge=case["pressure_gauge"])
        result = absorb(scenario, rig, strategy=["closed", "predictive"], noise=noise, seed=seed, absorber=absorber,
                        sample_rate=options.sample_rate, identification="oracle" if oracle else "model",
                        control_start=LATENCY if oracle else None,
                        early=policy == "early")
        m, closed = result.metrics["predictive"], result.metrics["closed"]
        rows.append({"case": case["case"], "impact": case["impact"], "mass_kg": scenario.mass,
                     "velocity_m_s": scenario.velocity, "impact_class": impact_class(scenario.mass, scenario.velocity),
                     "pressure_gauge": scenario.pressure_gauge, "pad_law": law,
                     "pad_stiffness_N_m": case["stiffness"], "effective_area_mm2": case["effective_area_mm2"],
                     "response_time_ms": case["response_time_ms"], "piston_mass_kg": case["piston_mass"],
                     "hardware": hardware_label(law, case["stiffness"], case["effective_area_mm2"],
                                                case["response_time_ms"], case["piston_mass"]),
                     "design": design_label(case["pressure_gauge"], law, case["stiffness"],
                                            case["effective_area_mm2"], case["response_time_ms"],
                                            case["piston_mass"]),
                     "identification": "oracle" if oracle else result.identification,
                     "policy": None if oracle else policy,
                     "identified_available_at_s": finite_or_none(result.identified.available_at),
                     "identified_mass_kg": finite_or_none(result.identified.mass),
                     "control_start_s": finite_or_none(m.control_start),
                     "stage_b_ratio": finite_or_none(m.stage_b_ratio),
                     "closed_stage_b_ratio": finite_or_none(closed.stage_b_ratio),
                     "wide_window_ratio": finite_or_none(m.wide_window_ratio),
                     "impact_force_N": finite_or_none(m.impact_force),
                     "whole_event_peak_ratio": finite_or_none(m.whole_event_peak_ratio),
                     "closed_whole_event_peak_ratio": finite_or_none(closed.whole_event_peak_ratio),
                     "peak_deceleration_g": finite_or_none(m.peak_deceleration_g),
                     "first_pulse_peak_N": finite_or_none(m.peak_force_stage_a),
                     "common_window_excluded": result.window.reason or None, "stopped": m.stopped,
                     "bottomed_out": m.bottomed_out, "rebound_m": finite_or_none(m.rebound),
                     "stroke_used_m": finite_or_none(m.stroke_used)})
    return rows


def _p90(values: np.ndarray) -> float:
    values = values[np.isfinite(values)]
    return float(np.percentile(values, 90)) if values.size else math.nan


def _figure(rows: list[Row], options: StudyOptions) -> StudyFigure:
    return StudyFigure("plot_absorber_design", rows, {"designs": designs(list(rows)), "early": EARLY,
                                                      "targets": TARGETS})


def _metrics(label: str, chosen: list[Row], charge: str, pressure: float) -> Row:
    """One design's row of :func:`designs` from its impacts' rows."""
    first = chosen[0]
    ratio = np.array([number(r.get("stage_b_ratio")) for r in chosen])
    early = np.array([number(r.get("identified_available_at_s")) for r in chosen])
    force = np.array([number(r.get("impact_force_N")) for r in chosen])
    rebound = np.array([number(r.get("rebound_m")) for r in chosen])
    return {"design": label, "charge": charge, "p0 [kPa]": pressure / 1e3, "pad": first.get("pad_law", "hysteretic"),
            "pad [N/m]": number(first["pad_stiffness_N_m"]), "valve [mm²]": number(first["effective_area_mm2"]),
            "response [ms]": number(first["response_time_ms"]),
            "piston [kg]": number(first["piston_mass_kg"]), "impacts": len(chosen),
            "p90 peak / F0": _p90(np.array([number(r.get("whole_event_peak_ratio")) for r in chosen])),
            "p90 R_B": _p90(ratio) if np.isfinite(ratio).all() else math.nan,
            "with R_B": int(np.isfinite(ratio).sum()),
            "p90 first pulse / F0": _p90(np.array([number(r.get("first_pulse_peak_N")) for r in chosen]) / force),
            "early answers": float(np.mean(early <= EARLY)) if early.size else math.nan,
            "median answer [ms]": float(np.nanmedian(early)) * 1e3 if np.isfinite(early).any() else math.nan,
            "bottomed out": sum(flag(r.get("bottomed_out")) for r in chosen),
            "rebound > 5 mm": int(np.sum(rebound > REBOUND_LIMIT)),
            "not stopped": sum(not flag(r.get("stopped")) for r in chosen)}


def _dominates(a: Row, b: Row) -> bool:
    """``a`` is at least as good as ``b`` on both 90th percentiles and better on one."""
    pa, pb = (a["p90 peak / F0"], a["p90 R_B"]), (b["p90 peak / F0"], b["p90 R_B"])
    return pa[0] <= pb[0] and pa[1] <= pb[1] and pa != pb


def _on_front(d: Row, table: list[Row]) -> bool:
    """``d`` never bottoms out, has both percentiles, no design of ``table`` dominates it and none before it in
    ``table`` has the same two (the first of equal designs stands for them)."""
    usable = d["bottomed out"] == 0 and math.isfinite(d["p90 peak / F0"] + d["p90 R_B"])
    same = (d["p90 peak / F0"], d["p90 R_B"])
    for o in table:
        if o is d:
            break
        if o["bottomed out"] == 0 and (o["p90 peak / F0"], o["p90 R_B"]) == same:
            return False
    return usable and not any(o is not d and o["bottomed out"] == 0 and _dominates(o, d) for o in table)


def _per_class(rows: list[Row]) -> list[Row]:
    """Designs with the charge at contact chosen per impact class, composed per hardware from its fixed-charge
    rows: every assignment of the swept charges to :data:`CLASSES` (one charge for all is the fixed design and is
    left out), of which those no other assignment of the same hardware dominates."""
    out = []
    for hardware in dict.fromkeys(r["hardware"] for r in rows if "hardware" in r and "impact_class" in r):
        mine = [r for r in rows if r.get("hardware") == hardware]
        pressures = sorted({float(r["pressure_gauge"]) for r in mine})
        by = {(float(r["pressure_gauge"]), r["impact"]): r for r in mine}
        impacts = sorted({r["impact"] for r in mine})
        if len(pressures) < 2 or any((p, i) not in by for p in pressures for i in impacts):
            continue
        classes = {i: by[(pressures[0], i)]["impact_class"] for i in impacts}
        candidates = []
        for choice in itertools.product(pressures, repeat=len(CLASSES)):
            if len(set(choice)) == 1:
                continue
            charge = dict(zip(CLASSES, choice, strict=True))
            chosen = [by[(charge[classes[i]], i)] for i in impacts]
            text = "/".join(f"{p / 1e3:g}" for p in choice)
            candidates.append(_metrics(f"per class {text} kPa, {hardware}", chosen,
                                       f"per class {text} kPa", max(choice)))
        out += [d for d in candidates if _on_front(d, candidates)]
    return out


def designs(rows: list[Row]) -> list[Row]:
    """One row per design: its parameters, the whole-event, R_B and first-pulse 90th percentiles (R_B: NaN unless
    every impact has a common window; ``with R_B`` counts those that have), early answers, bottoming and rebound,
    and whether it is on the Pareto front and meets every target. The fixed-charge designs first, then those with
    the charge chosen per impact class (``charge`` names the class charges in the order of :data:`CLASSES`;
    ``p0`` is then the highest, the stand's charge before it vents)."""
    out = []
    for label in dict.fromkeys(r["design"] for r in rows):
        chosen = [r for r in rows if r["design"] == label]
        pressure = number(chosen[0].get("pressure_gauge"))
        out.append(_metrics(label, chosen, "fixed", pressure))
    out += _per_class(rows)
    for d in out:
        d["meets targets"] = bool(d["p90 peak / F0"] <= TARGETS["whole_event_p90"]
                                  and d["p90 R_B"] <= TARGETS["stage_b_p90"]
                                  and d["early answers"] >= TARGETS["early_share"] and d["bottomed out"] == 0)
        d["Pareto"] = _on_front(d, out)
    return out


def recommended(rows: list[Row]) -> Row | None:
    """The design of the Pareto set that meets every target with the lowest whole-event p90 (None: none does)."""
    ok = [d for d in designs(rows) if d["Pareto"] and d["meets targets"]]
    return min(ok, key=lambda d: d["p90 peak / F0"]) if ok else None


def _shown(d: Row) -> str:
    return (f"whole-event p90 peak / F0 {d['p90 peak / F0']:.3g}, p90 R_B {d['p90 R_B']:.3g}, p90 first pulse / F0 "
            f"{d['p90 first pulse / F0']:.3g}, {d['early answers'] * 100:.0f} % early, bottomed out "
            f"{d['bottomed out']}, rebound > {REBOUND_LIMIT * 1e3:g} mm {d['rebound > 5 mm']} of {d['impacts']}")


def _summary(rows: list[Row]) -> list[Row]:
    """The verdict, the lowest whole-event p90 with and without the R_B target, one line per design of the front
    (lowest whole-event p90 first), and per pad law × piston mass the design with the lowest whole-event p90 (what
    each lever reaches, and whether R_B is defined there)."""
    table = designs(rows)
    front = sorted((d for d in table if d["Pareto"]), key=lambda d: d["p90 peak / F0"])
    best = recommended(rows)
    impacts = len({r["impact"] for r in rows})
    known = {r.get("identification") for r in rows}
    policies = sorted({str(r["policy"]) for r in rows if r.get("policy")})
    basis = ("M1 and V0 known from first contact + the stated latency (oracle)" if known == {"oracle"}
             else "identification in the loop" + (f", policy {'/'.join(policies)}" if policies else ""))
    target = (f"the design for whole-event p90 peak / F0 <= {TARGETS['whole_event_p90']:g}, p90 R_B <= "
              f"{TARGETS['stage_b_p90']:g} and >= {TARGETS['early_share'] * 100:g} % answers within "
              f"{EARLY * 1e3:g} ms")
    if best is None:
        verdict = f"none of the {len(table)} designs meets all three targets"
    else:
        verdict = f"{best['design']}: {_shown(best)}"
    lines = [{"quantity": target, "ours": f"{verdict}; over {impacts} impacts per design, R_B with {basis}"}]
    within = [d for d in table if d["bottomed out"] == 0 and d["p90 R_B"] <= TARGETS["stage_b_p90"]]
    for text, chosen in ((f"lowest whole-event p90 peak / F0 with p90 R_B <= {TARGETS['stage_b_p90']:g}", within),
                         ("lowest whole-event p90 peak / F0 of any design that never bottoms out",
                          [d for d in table if d["bottomed out"] == 0])):
        low = min(chosen, key=lambda d: d["p90 peak / F0"], default=None)
        lines.append({"quantity": text, "ours": "none" if low is None else f"{low['design']}: {_shown(low)}"})
    lines += [{"quantity": f"front {k + 1} of {len(front)}: {d['design']}", "ours": _shown(d)}
              for k, d in enumerate(front)]
    for law, piston in dict.fromkeys((d["pad"], d["piston [kg]"]) for d in table):
        mine = [d for d in table if (d["pad"], d["piston [kg]"]) == (law, piston) and d["bottomed out"] == 0]
        low = min(mine, key=lambda d: d["p90 peak / F0"], default=None)
        if low is not None:
            lines.append({"quantity": f"lever: {law} pad, {piston:g} kg piston, lowest whole-event p90 peak / F0",
                          "ours": f"{low['design']}: {_shown(low)}; common window in {low['with R_B']} of "
                                  f"{low['impacts']} impacts"})
    return [{**line, "paper": "beyond the paper"} for line in lines]


STUDY = register(Study(name=NAME, title="Absorber design: pre-charge (fixed or per impact class) × pad × valve × "
                                        "piston, whole event and R_B",
                       figure="", cases=_cases, evaluate=_evaluate, aggregate=designs, summary=_summary,
                       drawing=_figure, chunk_size=4, defaults=DEFAULTS, settings=SETTINGS,
                       rig=ABSORPTION_RIG))
