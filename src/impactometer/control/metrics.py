"""Per-run metrics of an absorber: the whole event and R_B on the impact's common window (the headline,
:mod:`.event`), and the earlier columns (supplementary).

Headline (see :mod:`.event`): the whole-event CFC 60 peak / F0, the peak deceleration in g, η = absorbed work /
(peak × stroke used), the stroke used and its share of the usable stroke, whether the mass stopped (and when),
bottoming (any bottom-stop force, or a run ended at the bottom stop), the rebound (upward travel of the mass after
its deepest point); R_B = CFC 60 peak over [t_w, deepest point] / max(F_ref, F_floor) with t_w the impact's first
sustained contact with the valve closed; R_B,wide the same peak from the end of the first contact pulse + 1 ms
(``wide_window_*``: a peak moved before t_w still counts).

Supplementary, each run on its own window (``own_window_*``, the earlier headline): the deepest point of the mass;
the run's own stage B is the contact pulse that holds it, when that pulse is not the first one and has lasted, from
its start to the deepest point, longer than 4 × the first pulse; t_s = max(its start, control start); F_ref at t_s;
R = CFC 60 peak over [t_s, deepest point] / F_ref and η_B = W_B / (that peak × s_rem). This window restarts where
the bodies part after the control start and differs between the strategies of one impact: it is not a fair
comparison, and is kept only to show what it hid (``own_window_force_ratio_first``: t_B at the run's first
sustained contact). The control-start columns: ``controlled_efficiency`` = W / (F_peak · Δu1) after the control
start, peaks after the control start, ``bounce_energy`` = μ·(v1 − v2)²/2 at the control start with
μ = M1·M2/(M1 + M2).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from ..signals.pulses import contact_pulses
from ..signals.stage_b import SUSTAINED_WINDOW_FACTOR, is_sustained
from ..validation import finite_or_none
from .event import (
    BODY_CFC,
    STOPPED_FRACTION,
    CommonWindow,
    body_load,
    first_sustained_contact,
    whole_event,
    window_peak,
)
from .target import stopping_force

__all__ = ["BODY_CFC", "REBOUND_THRESHOLD", "STOPPED_FRACTION", "AbsorptionMetrics", "StageB",
           "absorption_metrics", "stage_b"]

#: upward travel of the mass after it stopped that counts as a rebound [m]
REBOUND_THRESHOLD = 1e-3

#: units of the keys of ``AbsorptionMetrics.to_dict()``
UNITS = {"control_start": "s", "impact_force": "N", "whole_event_peak_force": "N", "stroke_used": "m",
         "time_to_stop": "s", "rebound": "m", "common_window_start": "s", "reference_force": "N",
         "floor_force": "N", "stage_b_peak_force": "N", "wide_window_start": "s", "wide_window_peak_force": "N",
         "own_window_start": "s", "own_window_reference_force": "N",
         "own_window_peak_force": "N", "peak_force_stage_a": "N", "peak_force_controlled": "N",
         "peak_force_controlled_cfc60": "N", "max_deceleration": "m_s2", "energy_absorbed": "J",
         "bounce_energy": "J", "stroke_controlled": "m"}


@dataclass(frozen=True, kw_only=True)
class AbsorptionMetrics:
    """Outcome of one absorbed impact (SI units; NaN where undefined).

    Headline: the whole event (``impact_force`` F0 to ``time_to_stop``, ``stopped``, ``bottomed_out``,
    ``rebound``) and the controller on the impact's common window (``common_window_start`` t_w,
    ``reference_force`` F_ref, ``floor_force`` F_floor, ``stage_b_peak_force``, ``stage_b_ratio`` R_B;
    ``wide_window_start``, ``wide_window_peak_force`` and ``wide_window_ratio`` R_B,wide from the first pulse's end
    + 1 ms); see
    :mod:`.event`. The ``own_window_*`` and control-start fields are supplementary (module notes).
    """

    control_start: float
    impact_force: float
    whole_event_peak_force: float
    whole_event_peak_ratio: float
    peak_deceleration_g: float
    whole_event_efficiency: float
    stroke_used: float
    stroke_utilisation: float
    stopped: bool
    time_to_stop: float
    bottomed_out: bool
    rebound: float
    rebounded: bool
    common_window_start: float
    reference_force: float
    floor_force: float
    stage_b_peak_force: float
    stage_b_ratio: float
    wide_window_start: float
    wide_window_peak_force: float
    wide_window_ratio: float
    own_window: bool
    own_window_start: float
    own_window_reference_force: float
    own_window_peak_force: float
    own_window_force_ratio: float
    own_window_efficiency: float
    own_window_force_ratio_first: float
    peak_force_stage_a: float
    peak_force_controlled: float
    peak_force_controlled_cfc60: float
    max_deceleration: float
    energy_absorbed: float
    bounce_energy: float
    stroke_controlled: float
    controlled_efficiency: float
    controlled_efficiency_cfc60: float

    def to_dict(self) -> dict[str, float | bool | None]:
        """JSON-ready mapping with unit-suffixed keys (``reference_force_N``, ``stroke_used_m``, ...); NaN ->
        None."""
        out = {}
        for key, value in asdict(self).items():
            if isinstance(value, float):
                value = finite_or_none(value)
            out[f"{key}_{UNITS[key]}" if key in UNITS else key] = value
        return out


@dataclass(frozen=True, kw_only=True)
class StageB:
    """The run's own stage-B window (supplementary; NaN where there is none).

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
    if not is_sustained(held[0], t[deepest] - pulse.start, first, SUSTAINED_WINDOW_FACTOR):
        return none  # the first pulse or a bounce holds the deepest point
    body = body_load(result) if filtered is None else filtered

    def judged(onset: float) -> tuple[float, float, float, float]:
        """F_ref, peak, R and η_B from t_s = max(onset, control start) to the deepest point (NaN if none); a
        control that never started leaves t_s = onset."""
        i0 = int(np.searchsorted(t, max(onset, control_start if math.isfinite(control_start) else onset) - 1e-12))
        remaining = usable_stroke - u1[i0] if i0 < deepest else 0.0
        if remaining <= 0.0:
            return math.nan, math.nan, math.nan, math.nan
        reference = stopping_force(mass, max(float(v1[i0]), 0.0), remaining, g)
        peak = float(body[i0:deepest + 1].max())
        work = 0.5 * mass * (v1[i0] ** 2 - v1[deepest] ** 2) + mass * g * (u1[deepest] - u1[i0])
        return float(reference), peak, float(peak / reference), float(work / (peak * remaining))

    reference, peak, ratio, efficiency = judged(pulse.start)
    onset = first_sustained_contact(t, force, u1)
    return StageB(start=float(pulse.start), reference_force=reference, peak_force=peak, force_ratio=ratio,
                  efficiency=efficiency, first_force_ratio=judged(onset)[2])


def absorption_metrics(result, control_start: float, usable_stroke: float,
                       window: CommonWindow | None = None) -> AbsorptionMetrics:
    """Metrics of a simulated absorbed impact (a :class:`~impactometer.model.SimulationResult`).

    ``control_start`` [s] is when the strategy took over (``inf`` when it never did: the control-start columns
    then start at the second contact pulse); ``usable_stroke`` [m] the largest mass displacement the absorber may
    use; ``window`` the impact's common window (:func:`.event.common_window` of its closed-valve run; None: R_B is
    NaN).
    """
    t, force = result.time, result.contact_force
    mass = result.scenario.mass
    g = result.rig.gravity
    pulses = contact_pulses(t, force)
    stage_a = [p.peak_force for p in pulses if not p.sustained]
    start = control_start if math.isfinite(control_start) else (pulses[1].start if len(pulses) > 1 else 0.0)
    i0 = min(int(np.searchsorted(t, start - 1e-12)), t.size - 1)
    i_stop = i0 + int(np.argmax(result.u1[i0:]))  # deepest point of the mass after the control start
    stopped = result.v1[i_stop] <= STOPPED_FRACTION * result.scenario.velocity
    body = body_load(result)
    peak = float(force[i0:].max())
    peak_body = float(body[i0:].max())
    stroke = float(result.u1[i_stop] - result.u1[i0])
    work = 0.5 * mass * result.v1[i0] ** 2 - 0.5 * mass * result.v1[i_stop] ** 2 + mass * g * stroke
    piston = result.rig.cylinder.piston_mass
    bounce = 0.5 * mass * piston / (mass + piston) * float(result.v1[i0] - result.v2[i0]) ** 2
    rebound = float(result.u1[i_stop] - result.u1[i_stop:].min()) if stopped else math.nan
    b = stage_b(result, control_start, usable_stroke, filtered=body)
    event = whole_event(result, usable_stroke, filtered=body)
    window = CommonWindow(start=math.nan, reference_force=math.nan, floor_force=math.nan) if window is None \
        else window
    window_force, ratio = window_peak(result, window, filtered=body)
    wide_force, wide_ratio = window_peak(result, window, filtered=body, wide=True)

    def efficiency(level: float) -> float:
        return float(work / (level * stroke)) if level > 0.0 and stroke > 0.0 else math.nan

    return AbsorptionMetrics(
        control_start=float(control_start), impact_force=event.impact_force,
        whole_event_peak_force=event.peak_force, whole_event_peak_ratio=event.peak_ratio,
        peak_deceleration_g=event.peak_deceleration_g, whole_event_efficiency=event.efficiency,
        stroke_used=event.stroke_used, stroke_utilisation=event.stroke_utilisation, stopped=event.stopped,
        time_to_stop=event.time_to_stop,
        bottomed_out=bool(np.any(result.bottom_stop_force > 0.0) or "ended_at_bottom" in result.extra),
        rebound=rebound, rebounded=bool(rebound > REBOUND_THRESHOLD),
        common_window_start=window.start, reference_force=window.reference_force, floor_force=window.floor_force,
        stage_b_peak_force=window_force, stage_b_ratio=ratio, wide_window_start=window.wide_start,
        wide_window_peak_force=wide_force, wide_window_ratio=wide_ratio,
        own_window=math.isfinite(b.start), own_window_start=b.start, own_window_reference_force=b.reference_force,
        own_window_peak_force=b.peak_force, own_window_force_ratio=b.force_ratio,
        own_window_efficiency=b.efficiency, own_window_force_ratio_first=b.first_force_ratio,
        peak_force_stage_a=float(max(stage_a)) if stage_a else math.nan,
        peak_force_controlled=peak, peak_force_controlled_cfc60=peak_body,
        max_deceleration=float(force[i0:].max() / mass - g), energy_absorbed=float(work), bounce_energy=bounce,
        stroke_controlled=stroke, controlled_efficiency=efficiency(peak),
        controlled_efficiency_cfc60=efficiency(peak_body))
