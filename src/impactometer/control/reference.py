"""The achievable reference: the best stage-B force ratio R an opening program of this valve reaches from a given
control start.

The programs are those of the ideal absorber, run with full knowledge (true M1 and V0, noise-free sensors, the
controller's lag and dead-time compensation, no supervisor): from the control start the valve opens as far as it
must (fully, while the contact force is above the level) and then holds the contact force at a constant level F_c
(the ``level`` strategy), the levels searched on a grid around the F_ref of the closed-valve state at the control
start and refined by golden section around the best one; and the ``predictive`` law's moving target
F* = M1·(v²/(2·s_rem) + g). Among the programs that stop the mass within the usable stroke without touching the
bottom stop, the one with the lowest R is the reference: the best this search finds, not a proven bound.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from ..rig import Rig, Scenario
from .metrics import stage_b
from .settings import ControlSettings
from .simulate import simulate_controlled
from .strategies import predictive_tau_control
from .valve import Absorber

#: levels of the first scan, as multiples of the closed-valve run's F_ref
SCAN = (0.8, 1.0, 1.2, 1.5, 2.0, 3.0)
#: golden-section refinements after the scan
REFINEMENTS = 3
#: a program's run ends this long after the mass's deepest point [s] (R, the stroke and bottoming are known then)
TAIL = 0.02
#: overshoot of the usable stroke tolerated by the search [m]: the controllers hold the rod to the usable stroke, and
#: the mass runs the contact's compression (a few millimetres) further, within the stroke margin, as theirs do
STROKE_TOLERANCE = 5e-3


@dataclass(frozen=True, kw_only=True)
class AchievableReference:
    """The best program of the valve found: its force level [N] (NaN for the moving target), R [-], η_B [-], stroke
    used [m] and the number of programs tried (R NaN when none stops the mass within the usable stroke, or the run
    has no stage B)."""

    level: float
    force_ratio: float
    efficiency: float
    stroke_used: float
    runs: int


def _outcome(scenario, rig, absorber, settings, duration, sample_rate):
    result, _ = simulate_controlled(scenario, rig, control=settings, drive=absorber.drive, duration=duration,
                                    sample_rate=sample_rate, stop_after=TAIL)
    usable = absorber.usable_stroke(rig)
    feasible = (float(result.u1.max()) <= usable + STROKE_TOLERANCE and not np.any(result.bottom_stop_force > 0.0)
                and "ended_at_bottom" not in result.extra)
    return stage_b(result, settings.start, usable), feasible, float(result.u1.max())


def achievable_reference(scenario: Scenario, rig: Rig, absorber: Absorber, control_start: float, *,
                         reference_force: float, charge_pressure: float, duration: float,
                         sample_rate: float = 50e3) -> AchievableReference:
    """Search the programs (see the module notes) from ``control_start`` [s]; ``reference_force`` [N] (F_ref
    of the closed-valve state at the control start, or any force of its scale) centres the scan,
    ``charge_pressure`` [Pa] is the lower chamber's pressure at first contact."""
    nothing = AchievableReference(level=math.nan, force_ratio=math.nan, efficiency=math.nan, stroke_used=math.nan,
                                  runs=0)
    if not (math.isfinite(control_start) and math.isfinite(reference_force) and reference_force > 0.0):
        return nothing
    base = ControlSettings(strategy="level", start=control_start, mass=scenario.mass, mass_std=0.0,
                           velocity=scenario.velocity, usable_stroke=absorber.usable_stroke(rig),
                           charge_pressure=charge_pressure, charge_temperature=rig.gas.temperature,
                           force_level=reference_force, refine_mass=False, supervise=False,
                           tau_control=predictive_tau_control(absorber.drive))
    tried: dict[float, tuple[float, float, float]] = {}

    def cost(level: float) -> float:
        if level not in tried:
            settings = dataclasses.replace(base, force_level=level)
            b, feasible, stroke = _outcome(scenario, rig, absorber, settings, duration, sample_rate)
            ratio = b.force_ratio if feasible and math.isfinite(b.force_ratio) else math.inf
            tried[level] = (ratio, b.efficiency, stroke)
        return tried[level][0]

    levels = [factor * reference_force for factor in SCAN]
    costs = [cost(level) for level in levels]
    best = int(np.argmin(costs))
    if math.isfinite(costs[best]):
        low, high = levels[max(best - 1, 0)], levels[min(best + 1, len(levels) - 1)]
        golden = (math.sqrt(5.0) - 1.0) / 2.0
        for _ in range(REFINEMENTS):
            a, b = high - golden * (high - low), low + golden * (high - low)
            if cost(a) <= cost(b):
                high = b
            else:
                low = a
    level = min(tried, key=lambda x: tried[x][0])
    ratio, efficiency, stroke = tried[level]
    if not math.isfinite(ratio):
        level, efficiency, stroke = math.nan, math.nan, math.nan
    tracking = dataclasses.replace(base, strategy="predictive", force_level=math.nan)  # the moving target
    b, feasible, tracked_stroke = _outcome(scenario, rig, absorber, tracking, duration, sample_rate)
    if feasible and b.force_ratio < ratio:
        level, ratio, efficiency, stroke = math.nan, b.force_ratio, b.efficiency, tracked_stroke
    if not math.isfinite(ratio):
        ratio = math.nan
    return AchievableReference(level=float(level), force_ratio=float(ratio), efficiency=float(efficiency),
                               stroke_used=stroke, runs=len(tried) + 1)
