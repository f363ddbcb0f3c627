"""Per-run metrics of an absorber: the stage-B force ratio (the headline), stage-A peaks, bottoming, rebound, and
the earlier efficiency columns (supplementary).

Stage B and the force ratio (from the truth channels of the simulation):

- the deepest point of the mass is the largest u1 of the record; stage B is the contact pulse that holds it, when
  that pulse is not the first one and has lasted, from its start to the deepest point, longer than 4 × the first
  pulse (the stage-B rule ``identify.pulses.is_sustained``, with this module's ``SUSTAINED_FACTOR`` and the first
  pulse as the bounce it is measured against); ``stage_b_start`` t_B is its start. A run whose deepest point lies
  in a collision (for example a light mass stopped by the gas spring during stage A) has no stage B: it is counted
  apart, never dropped;
- t_s = max(t_B, control start); the remaining usable stroke s_rem = usable stroke − u1(t_s), and the reference
  force F_ref = M1·(v1(t_s)²/(2·s_rem) + g): the lowest constant force on the mass that stops it within s_rem;
- the stage-B force ratio R = peak of the CFC 60 filtered contact force over [t_s, deepest point] / F_ref (ideal 1;
  CFC 60 is the SAE J211 class for whole-body loads), and the stage-B efficiency η_B = W_B / (that peak × s_rem),
  W_B = M1·(v1(t_s)² − v1(deepest)²)/2 + M1·g·(u1(deepest) − u1(t_s)) the energy absorbed meanwhile;
- when the bodies part after the control start and meet again, stage B starts at the new contact and R leaves out
  the force before it; ``stage_b_force_ratio_first`` is R with t_B at the first sustained contact instead
  (supplementary: how much of R such a parting hides).

Supplementary (the earlier headline): the control starts at ``control_start``; the absorption ends at the mass's
deepest point after it (stopped when its velocity there is below 1 % of V0); η = W / (F_peak · Δu1) with W the work
of the contact force on the mass, F_peak the peak contact force after the control start and Δu1 the stroke used
meanwhile. ``*_cfc60`` values use the CFC 60 filtered force. ``bounce_energy`` is the kinetic energy of the
relative motion of mass and piston at the control start, μ·(v1 − v2)²/2 with μ = M1·M2/(M1 + M2).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from ..filters import cfc_filter
from ..identify.pulses import contact_pulses, is_sustained
from ..validation import finite_or_none

#: upward travel of the mass after it stopped that counts as a rebound [m]
REBOUND_THRESHOLD = 1e-3
#: the mass counts as stopped at its deepest point when its velocity there is below this fraction of V0
STOPPED_FRACTION = 0.01
#: channel frequency class of the filtered (body-load) contact force
BODY_CFC = 60
#: stage B of the metric: the pulse holding the deepest point has lasted longer than this multiple of the first
#: pulse (the rule ``pulses.is_sustained``, measured against the first pulse). It differs from
#: ``pulses.SUSTAINED_FACTOR`` (2 × the longest pulse before) because it answers another question: which pulse of a
#: finished, noise-free controlled run opens the window of R, not when the identification may take a detected pulse
#: for stage B. The absorption figures (README, docs/absorption.md) were computed with it.
SUSTAINED_FACTOR = 4.0


@dataclass(frozen=True, kw_only=True)
class AbsorptionMetrics:
    """Outcome of one absorbed impact (SI units; NaN where undefined, e.g. no stop within the record)."""

    control_start: float
    stage_b: bool
    stage_b_start: float
    reference_force: float
    stage_b_peak_force: float
    stage_b_force_ratio: float
    stage_b_efficiency: float
    stage_b_force_ratio_first: float
    peak_force_stage_a: float
    peak_force_controlled: float
    peak_force_controlled_cfc60: float
    max_deceleration: float
    energy_absorbed: float
    bounce_energy: float
    stroke_controlled: float
    stroke_used: float
    efficiency: float
    efficiency_cfc60: float
    bottomed_out: bool
    time_to_stop: float
    rebound: float
    rebounded: bool

    def to_dict(self) -> dict[str, float | bool | None]:
        """JSON-ready mapping with unit-suffixed keys (``peak_force_controlled_N``, ...); NaN -> None."""
        units = {"control_start": "s", "stage_b_start": "s", "reference_force": "N", "stage_b_peak_force": "N",
                 "peak_force_stage_a": "N", "peak_force_controlled": "N",
                 "peak_force_controlled_cfc60": "N", "max_deceleration": "m_s2", "energy_absorbed": "J",
                 "bounce_energy": "J", "stroke_controlled": "m", "stroke_used": "m", "time_to_stop": "s",
                 "rebound": "m"}
        out = {}
        for key, value in asdict(self).items():
            if isinstance(value, float):
                value = finite_or_none(value)
            out[f"{key}_{units[key]}" if key in units else key] = value
        return out


@dataclass(frozen=True, kw_only=True)
class StageB:
    """Stage B of one run as the metric sees it (NaN where there is none).

    ``first_force_ratio`` is R with t_B at the first sustained contact instead (the paper's onset of stage B): the
    two differ when the bodies part after the control start and meet again (the force before the new contact is
    then left out of R).
    """

    start: float
    reference_force: float
    peak_force: float
    force_ratio: float
    efficiency: float
    first_force_ratio: float = math.nan


def stage_b(result, control_start: float, usable_stroke: float, *, filtered: np.ndarray | None = None) -> StageB:
    """Stage-B start t_B [s], F_ref [N], CFC 60 peak over [t_s, deepest point] [N], R and η_B of a simulated run
    (see the module notes); NaN where the run has no stage B or the control starts after the deepest point."""
    none = StageB(start=math.nan, reference_force=math.nan, peak_force=math.nan, force_ratio=math.nan,
                  efficiency=math.nan)
    t, force, u1, v1 = result.time, result.contact_force, result.u1, result.v1
    mass, g = result.scenario.mass, result.rig.gravity
    pulses = contact_pulses(t, force, sustained_factor=math.inf)  # every contact pulse, none marked
    deepest = int(np.argmax(u1))
    held = [i for i, p in enumerate(pulses) if p.start <= t[deepest] <= p.end]
    if not held:
        return none
    first = pulses[0].end - pulses[0].start
    pulse = pulses[held[0]]
    if not is_sustained(held[0], t[deepest] - pulse.start, first, SUSTAINED_FACTOR):
        return none  # the first pulse or a bounce holds the deepest point
    body = cfc_filter(force, 1.0 / (t[1] - t[0]), BODY_CFC) if filtered is None else filtered

    def judged(onset: float) -> tuple[float, float, float, float]:
        """F_ref, peak, R and η_B from t_s = max(onset, control start) to the deepest point (NaN if none); a
        control that never started leaves t_s = onset."""
        i0 = int(np.searchsorted(t, max(onset, control_start if math.isfinite(control_start) else onset) - 1e-12))
        remaining = usable_stroke - u1[i0] if i0 < deepest else 0.0
        if remaining <= 0.0:
            return math.nan, math.nan, math.nan, math.nan
        reference = mass * (max(v1[i0], 0.0) ** 2 / (2.0 * remaining) + g)
        peak = float(body[i0:deepest + 1].max())
        work = 0.5 * mass * (v1[i0] ** 2 - v1[deepest] ** 2) + mass * g * (u1[deepest] - u1[i0])
        return float(reference), peak, float(peak / reference), float(work / (peak * remaining))

    reference, peak, ratio, efficiency = judged(pulse.start)
    onset = next(p.start for k, p in enumerate(pulses[:held[0] + 1])
                 if is_sustained(k, min(p.end, t[deepest]) - p.start, first, SUSTAINED_FACTOR))
    return StageB(start=float(pulse.start), reference_force=reference, peak_force=peak, force_ratio=ratio,
                  efficiency=efficiency, first_force_ratio=judged(onset)[2])


def absorption_metrics(result, control_start: float, usable_stroke: float) -> AbsorptionMetrics:
    """Metrics of a simulated absorbed impact (a :class:`~impactometer.model.SimulationResult`).

    ``control_start`` [s] is when the strategy took over (``inf`` when it never did: then the whole record after
    stage A is judged as uncontrolled); ``usable_stroke`` [m] the largest mass displacement the absorber may use.
    """
    t, force = result.time, result.contact_force
    mass = result.scenario.mass
    g = result.rig.gravity
    fs = 1.0 / (t[1] - t[0])
    pulses = contact_pulses(t, force)
    stage_a = [p.peak_force for p in pulses if not p.sustained]
    start = control_start if math.isfinite(control_start) else (pulses[1].start if len(pulses) > 1 else 0.0)
    i0 = min(int(np.searchsorted(t, start - 1e-12)), t.size - 1)
    i_stop = i0 + int(np.argmax(result.u1[i0:]))  # deepest point of the mass after the control start
    stopped = result.v1[i_stop] <= STOPPED_FRACTION * result.scenario.velocity
    body = cfc_filter(force, fs, BODY_CFC) if t.size > 16 else force
    peak = float(force[i0:].max())
    peak_body = float(body[i0:].max())
    stroke = float(result.u1[i_stop] - result.u1[i0])
    work = 0.5 * mass * result.v1[i0] ** 2 - 0.5 * mass * result.v1[i_stop] ** 2 + mass * g * stroke
    piston = result.rig.cylinder.piston_mass
    bounce = 0.5 * mass * piston / (mass + piston) * float(result.v1[i0] - result.v2[i0]) ** 2
    rebound = float(result.u1[i_stop] - result.u1[i_stop:].min()) if stopped else math.nan
    b = stage_b(result, control_start, usable_stroke, filtered=body)

    def efficiency(level: float) -> float:
        return float(work / (level * stroke)) if level > 0.0 and stroke > 0.0 else math.nan

    return AbsorptionMetrics(
        control_start=float(control_start), stage_b=math.isfinite(b.start), stage_b_start=b.start,
        reference_force=b.reference_force, stage_b_peak_force=b.peak_force, stage_b_force_ratio=b.force_ratio,
        stage_b_efficiency=b.efficiency, stage_b_force_ratio_first=b.first_force_ratio,
        peak_force_stage_a=float(max(stage_a)) if stage_a else math.nan,
        peak_force_controlled=peak, peak_force_controlled_cfc60=peak_body,
        max_deceleration=float(force[i0:].max() / mass - g), energy_absorbed=float(work), bounce_energy=bounce,
        stroke_controlled=stroke, stroke_used=float(result.u1.max() - result.u1[0]),
        efficiency=efficiency(peak), efficiency_cfc60=efficiency(peak_body),
        bottomed_out=bool(np.any(result.bottom_stop_force > 0.0) or "ended_at_bottom" in result.extra),
        time_to_stop=float(t[i_stop]) if stopped else math.nan,
        rebound=rebound, rebounded=bool(rebound > REBOUND_THRESHOLD))
