"""The achievable reference: the lowest R_B (on the impact's common window, :mod:`.event`) that an opening program of
this valve reaches on the same plant, with full knowledge (true M1 and V0, noise-free sensors).

The family searched, every member judged on the same window and the same feasibility (the mass stops within the
usable stroke + ``STROKE_TOLERANCE``, the piston never touches the bottom stop):

1. **piecewise-constant openings on ``SEGMENTS`` (8) equal segments from first contact** to the horizon T (1.1 × the
   time to the deepest point of the best program of 2-3; the last opening held after it), the valve command
   optimised by ``scipy.optimize.minimize`` (Powell, bounds [0, 1], at most ``EVALUATIONS`` plant simulations at
   ``SEARCH_RATE``) from the per-segment mean command of that program, the best found re-run at the loop's rate;
2. the ideal absorber's programs from first contact and from the loop's control start: open as far as needed,
   then hold the contact force at a level F_c (the ``level`` law with the predictive controller's lag
   compensation, no supervisor), F_c on a grid around F_ref and refined by golden section;
3. the ``predictive`` law's moving target F* = M1·(v²/(2·s_rem) + g) from first contact and from the control
   start, with full knowledge;
4. **partial knowledge** from first contact: the same law from first contact with the true V0 and M1's prior over
   the stand's rated masses (its mean, :meth:`.valve.Absorber.mass_prior`), switched to the true M1 when the loop's
   identification answers (``partial_switch``; never without an answer): what a controller that acts on what is
   known as soon as it is known can reach, without the identification's errors.

The reference is the lowest R_B among them: the best this search finds in a stated family, not a proof that no
program does better (the closed-loop controllers are not in family 1; the study counts the impacts where they beat
it).

**From the control start.** Where the loop's answer comes at a control start t_c > 0, the same three families are
searched again with the valve closed before t_c (family 1 on 8 equal segments of [t_c, T]): the best a program
reaches that knows M1 and V0 exactly but acts only from when the loop can (``from_start_force_ratio``). The gap
between the two references is what the answer's time costs; the gap between the second and the loop is what its
control law costs. The best of each family from first contact is reported too (``by_family``): the bound a loop
that acts from first contact is judged against.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize

from ..model.simulate import sample_times
from ..rig import Rig, Scenario
from ..validation import finite_or_none
from .event import CommonWindow, body_load, impact_force, window_peak
from .plant import simulate_controlled
from .settings import ControlSettings
from .strategies import predictive_tau_control
from .valve import Absorber

#: levels of the first scan, as multiples of the closed-valve run's F_ref
SCAN = (0.8, 1.0, 1.2, 1.5, 2.0, 3.0)
#: golden-section refinements after the scan
REFINEMENTS = 3
#: a program's run ends this long after the mass's deepest point [s] (R_B, the stroke and bottoming are known then)
TAIL = 0.02
#: overshoot of the usable stroke tolerated by the search [m]: the controllers hold the rod to the usable stroke, and
#: the mass runs the contact's compression (a few millimetres) further, within the stroke margin, as theirs do
STROKE_TOLERANCE = 5e-3
#: segments of the piecewise-constant programs, plant simulations of their search, and its sample rate [Hz]
SEGMENTS = 8
EVALUATIONS = 240
SEARCH_RATE = 10e3
#: cost added to R_B per STROKE_TOLERANCE of overshoot beyond the tolerance (and once for touching the bottom)
PENALTY = 10.0


@dataclass(frozen=True, kw_only=True)
class AchievableReference:
    """The best program found: R_B [-], whole-event peak / F0 [-], stroke used [m], which family gave it and from
    when (``segments``, ``level`` or ``moving target``, ``from first contact`` or ``from the control start``), its
    level [N] (NaN unless ``level``), its openings per segment [-] (empty unless ``segments``), the number of
    plant simulations run (R_B NaN when no program is feasible or the impact has no common window), the R_B of
    the best program acting only from the control start [-] (NaN without a control start), and the R_B of the best
    program of each family acting from first contact [-] (``by_family``: ``segments``, ``level``, ``moving
    target``, ``partial knowledge``; inf where none of it is feasible)."""

    force_ratio: float
    whole_event_peak_ratio: float
    stroke_used: float
    family: str
    level: float
    openings: tuple[float, ...]
    runs: int
    from_start_force_ratio: float = math.nan
    by_family: dict[str, float] = dataclasses.field(default_factory=dict)

    def to_dict(self) -> dict:
        """JSON-ready summary with ``achievable_``-prefixed keys (``achievable_by_family``: R_B of the best of each
        family from first contact, None where none is feasible)."""
        finite = [finite_or_none(v) for v in
                  (self.force_ratio, self.whole_event_peak_ratio, self.stroke_used, self.level,
                   self.from_start_force_ratio)]
        return {"achievable_force_ratio": finite[0], "achievable_whole_event_peak_ratio": finite[1],
                "achievable_stroke_used_m": finite[2], "achievable_family": self.family,
                "achievable_level_N": finite[3], "achievable_openings": list(self.openings),
                "achievable_runs": self.runs, "achievable_from_start_force_ratio": finite[4],
                "achievable_by_family": {name: finite_or_none(v) for name, v in self.by_family.items()}}


@dataclass(frozen=True, kw_only=True)
class _Outcome:
    ratio: float  # R_B, inf when infeasible or undefined
    cost: float  # R_B plus the penalties (the search's objective)
    peak_ratio: float
    stroke: float
    deepest_time: float
    commands: np.ndarray
    time: np.ndarray


def _outcome(scenario, rig, absorber, settings, window, duration, sample_rate, program=None) -> _Outcome:
    # the run ends TAIL after the mass turns up in contact once the program has started: from t_w at the latest, so
    # that a bounce of stage A is not taken for the stop
    tail = TAIL if settings.start >= window.start else math.inf
    result, history = simulate_controlled(scenario, rig, control=settings, drive=absorber.drive, duration=duration,
                                          sample_rate=sample_rate, stop_after=tail, program=program)
    usable = absorber.usable_stroke(rig)
    stroke = float(result.u1.max())
    bottomed = bool(np.any(result.bottom_stop_force > 0.0) or "ended_at_bottom" in result.extra)
    over = max(stroke - usable - STROKE_TOLERANCE, 0.0) / STROKE_TOLERANCE
    ratio = window_peak(result, window)[1]
    f0 = impact_force(scenario.mass, scenario.velocity, usable, rig.gravity)
    cost = (ratio if math.isfinite(ratio) else 100.0) + PENALTY * (over + (over > 0.0) + bottomed)
    feasible = over == 0.0 and not bottomed and math.isfinite(ratio)
    return _Outcome(ratio=ratio if feasible else math.inf, cost=cost, peak_ratio=float(body_load(result).max() / f0),
                    stroke=stroke, deepest_time=float(result.time[np.argmax(result.u1)]),
                    commands=history["valve_command"], time=result.time)


def _segment_index(time: np.ndarray, begin: float, horizon: float) -> np.ndarray:
    """Segment of each sample: k on [b + k·(T − b)/n, b + (k+1)·(T − b)/n) with b = ``begin``, T = ``horizon``
    (the last one after T); -1 before ``begin``."""
    index = np.minimum(((time - begin) / (horizon - begin) * SEGMENTS).astype(int), SEGMENTS - 1)
    return np.where(time < begin, -1, index)


def _segment_program(openings, begin: float, horizon: float, time: np.ndarray) -> np.ndarray:
    """Valve command per sample [-]: closed before ``begin``, then ``openings[k]`` on segment k
    (:func:`_segment_index`)."""
    index = _segment_index(time, begin, horizon)
    return np.where(index < 0, 0.0, np.clip(np.asarray(openings, float), 0.0, 1.0)[np.maximum(index, 0)])


def _segment_means(outcome: _Outcome, begin: float, horizon: float) -> np.ndarray:
    """Mean command of a run per segment (the start of the search)."""
    index = _segment_index(outcome.time, begin, horizon)
    commands = np.nan_to_num(outcome.commands, nan=0.0)
    return np.array([commands[index == k].mean() if np.any(index == k) else 0.0 for k in range(SEGMENTS)])


def _golden_levels(cost, levels: list[float]) -> None:
    """Scan ``cost`` over ``levels`` [N], then refine by golden section around the best feasible one (``cost``
    keeps what it tried)."""
    costs = [cost(level) for level in levels]
    best = int(np.argmin(costs))
    if not math.isfinite(costs[best]):
        return
    low, high = levels[max(best - 1, 0)], levels[min(best + 1, len(levels) - 1)]
    golden = (math.sqrt(5.0) - 1.0) / 2.0
    for _ in range(REFINEMENTS):
        a, b = high - golden * (high - low), low + golden * (high - low)
        if cost(a) <= cost(b):
            high = b
        else:
            low = a


def achievable_reference(scenario: Scenario, rig: Rig, absorber: Absorber, control_start: float, *,
                         window: CommonWindow, pressure_lower_start: float, duration: float,
                         sample_rate: float = 50e3, evaluations: int = EVALUATIONS,
                         partial_switch: float = math.inf) -> AchievableReference:
    """Search the program families (module notes) for the impact ``scenario`` on ``rig``; families 2 and 3 start
    at first contact and at ``control_start`` [s] (``inf``: first contact only), ``window`` is the impact's common
    window (F_ref centres the level scan), ``pressure_lower_start`` [Pa absolute] the lower chamber's pressure at
    first contact, ``evaluations`` the budget of plant simulations of the piecewise-constant search (0: family 1 is
    skipped),
    ``partial_switch`` the instant the partial-knowledge program learns the true M1 [s] (family 4)."""
    nothing = AchievableReference(force_ratio=math.nan, whole_event_peak_ratio=math.nan, stroke_used=math.nan,
                                  family="", level=math.nan, openings=(), runs=0)
    if not math.isfinite(window.start):
        return nothing
    base = ControlSettings(strategy="level", start=0.0, mass=scenario.mass, mass_std=0.0,
                           velocity=scenario.velocity, usable_stroke=absorber.usable_stroke(rig),
                           pressure_lower_start=pressure_lower_start, temperature_lower_start=rig.gas.temperature,
                           force_level=window.reference_force, refine_mass=False, supervise=False,
                           tau_control=predictive_tau_control(absorber.drive))
    candidates: dict[tuple[str, str, float], _Outcome] = {}  # (family, from when, level) -> its best run
    runs = 0
    starts = {"first contact": 0.0}
    if math.isfinite(control_start) and control_start > 0.0:
        starts["the control start"] = float(control_start)
    for when, start in starts.items():
        tried: dict[float, _Outcome] = {}
        begun = dataclasses.replace(base, start=start)

        def cost(level: float, begun=begun, tried=tried) -> float:
            if level not in tried:
                tried[level] = _outcome(scenario, rig, absorber, dataclasses.replace(begun, force_level=level),
                                        window, duration, sample_rate)
            return tried[level].ratio

        _golden_levels(cost, [factor * window.reference_force for factor in SCAN])
        level = min(tried, key=lambda x: tried[x].ratio)
        candidates[("level", when, level)] = tried[level]
        tracking = dataclasses.replace(begun, strategy="predictive", force_level=math.nan)  # the moving target
        candidates[("moving target", when, math.nan)] = _outcome(scenario, rig, absorber, tracking, window,
                                                                 duration, sample_rate)
        runs += len(tried) + 1
    prior, prior_std = absorber.mass_prior()
    partial = dataclasses.replace(base, strategy="predictive", force_level=math.nan, start=float(partial_switch),
                                  early_start=0.0, early_mass=prior, early_mass_std=prior_std,
                                  early_velocity=scenario.velocity)
    candidates[("partial knowledge", "first contact", math.nan)] = _outcome(scenario, rig, absorber, partial, window,
                                                                           duration, sample_rate)
    runs += 1
    found_openings: dict[str, tuple[float, ...]] = {}  # by when the segments begin
    if evaluations > 0:
        program_settings = dataclasses.replace(base, strategy="closed", start=window.start)
        for when, start in starts.items():
            seed = min((o for (_, begun, _), o in candidates.items() if begun == when), key=lambda o: o.cost)
            horizon = max(1.1 * seed.deepest_time, start + 10.0 / SEARCH_RATE)
            searched: list[tuple[float, np.ndarray]] = []

            def objective(x: np.ndarray, start=start, horizon=horizon, searched=searched) -> float:
                o = _outcome(scenario, rig, absorber, program_settings, window, duration, SEARCH_RATE,
                             _segment_program(x, start, horizon, sample_times(duration, SEARCH_RATE)))
                searched.append((o.cost, np.clip(x, 0.0, 1.0)))
                return o.cost

            minimize(objective, _segment_means(seed, start, horizon), method="Powell",
                     bounds=[(0.0, 1.0)] * SEGMENTS, options={"maxfev": evaluations, "xtol": 1e-3, "ftol": 1e-4})
            best_x = min(searched, key=lambda item: item[0])[1]
            candidates[("segments", when, math.nan)] = _outcome(
                scenario, rig, absorber, program_settings, window, duration, sample_rate,
                _segment_program(best_x, start, horizon, sample_times(duration, sample_rate)))
            found_openings[when] = tuple(float(v) for v in best_x)
            runs += len(searched) + 1
    late = [o.ratio for (_, begun, _), o in candidates.items() if begun == "the control start"]
    by_family = {name: min(o.ratio for (f, begun, _), o in candidates.items() if f == name and begun == "first contact")
                 for name in dict.fromkeys(f for f, _, _ in candidates)}
    (family, when, level), chosen = min(candidates.items(), key=lambda item: item[1].ratio)
    if not math.isfinite(chosen.ratio):
        return dataclasses.replace(nothing, runs=runs, by_family=by_family)
    return AchievableReference(force_ratio=float(chosen.ratio), whole_event_peak_ratio=chosen.peak_ratio,
                               stroke_used=chosen.stroke, family=f"{family} from {when}", level=float(level),
                               openings=found_openings.get(when, ()) if family == "segments" else (), runs=runs,
                               from_start_force_ratio=float(min(late)) if late else math.nan, by_family=by_family)
