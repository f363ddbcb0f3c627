"""Per-run metrics of an absorber: stage-A peaks, controlled peak force, efficiency, stroke, bottoming, rebound.

Conventions: the control starts at ``control_start``; the absorption ends when the mass reaches its deepest point
after it (stopped when its velocity there is below 1 % of V0; a mass that is still moving at the end of the
record has not stopped). Energy absorbed after the control start is the work the contact force does on the mass,
W = M1·v1(t_c)²/2 + M1·g·(u1(t_stop) − u1(t_c)); the efficiency is η = W / (F_peak · Δu1) with F_peak the peak
contact force after the control start and Δu1 = u1(t_stop) − u1(t_c) the stroke used meanwhile (η = 1 for a
perfectly constant force). ``*_cfc60`` values use the contact force filtered with channel class CFC 60 (SAE J211,
the class for the load on a body), i.e. the load averaged over the contact pulses. ``bounce_energy`` is the
kinetic energy of the relative motion of mass and piston at the control start, μ·(v1 − v2)²/2 with
μ = M1·M2/(M1 + M2): energy the contact (not the gas spring) has to dissipate, in collisions whose peaks are set
by it, whatever the valve does.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from ..filters import cfc_filter
from ..identify.pulses import contact_pulses

#: upward travel of the mass after it stopped that counts as a rebound [m]
REBOUND_THRESHOLD = 1e-3
#: the mass counts as stopped at its deepest point when its velocity there is below this fraction of V0
STOPPED_FRACTION = 0.01
#: channel frequency class of the filtered (body-load) contact force
BODY_CFC = 60


@dataclass(frozen=True, kw_only=True)
class AbsorptionMetrics:
    """Outcome of one absorbed impact (SI units; NaN where undefined, e.g. no stop within the record)."""

    control_start: float
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
        units = {"control_start": "s", "peak_force_stage_a": "N", "peak_force_controlled": "N",
                 "peak_force_controlled_cfc60": "N", "max_deceleration": "m_s2", "energy_absorbed": "J",
                 "bounce_energy": "J", "stroke_controlled": "m", "stroke_used": "m", "time_to_stop": "s",
                 "rebound": "m"}
        out = {}
        for key, value in asdict(self).items():
            if isinstance(value, float) and not math.isfinite(value):
                value = None
            out[f"{key}_{units[key]}" if key in units else key] = value
        return out


def absorption_metrics(result, control_start: float) -> AbsorptionMetrics:
    """Metrics of a simulated absorbed impact (a :class:`~impactometer.model.SimulationResult`).

    ``control_start`` [s] is when the strategy took over (``inf`` when it never did: then the whole record after
    stage A is judged as uncontrolled).
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

    def efficiency(level: float) -> float:
        return float(work / (level * stroke)) if level > 0.0 and stroke > 0.0 else math.nan

    return AbsorptionMetrics(
        control_start=float(control_start), peak_force_stage_a=float(max(stage_a)) if stage_a else math.nan,
        peak_force_controlled=peak, peak_force_controlled_cfc60=peak_body,
        max_deceleration=float(force[i0:].max() / mass - g), energy_absorbed=float(work), bounce_energy=bounce,
        stroke_controlled=stroke, stroke_used=float(result.u1.max() - result.u1[0]),
        efficiency=efficiency(peak), efficiency_cfc60=efficiency(peak_body),
        bottomed_out=bool(np.any(result.bottom_stop_force > 0.0) or "ended_at_bottom" in result.extra),
        time_to_stop=float(t[i_stop]) if stopped else math.nan,
        rebound=rebound, rebounded=bool(rebound > REBOUND_THRESHOLD))
