"""How an absorbed impact is judged: the whole event (what a person or a payload feels) and the controller on one
common window per impact.

Whole event (each run on its own, from first contact until the mass has stopped):

- F0 = M1·(V0²/(2·s_usable) + g), the constant force that stops the mass in the usable stroke from first contact
  (the ideal absorber of the whole event);
- ``peak_ratio`` = peak of the CFC 60 filtered contact force over the whole run / F0 (ideal 1; CFC 60 is the SAE
  J211 class for whole-body loads); ``peak_deceleration_g`` = (that peak / M1 − g)/g, the mass's peak deceleration
  in g;
- η = W / (peak × stroke used), W = M1·(V0² − v1(deepest)²)/2 + M1·g·(u1(deepest) − u1(0)) the energy absorbed
  from first contact to the deepest point; stroke utilisation = stroke used / usable stroke;
- the mass has stopped when its velocity at its deepest point is below ``STOPPED_FRACTION`` of V0; a run that has
  not stopped at the end of its record is simulated longer (``control.loop``), and one that cannot stop within the
  longest simulation is reported as such (``stopped`` False), never judged on a cut record.

Controller (R_B, on a window common to every strategy, the oracle and the reference of one impact):

- the window starts at the first sustained contact of the impact with the valve closed, t_w (the start of the first
  contact pulse after the first one that lasts, to the deepest point, longer than
  ``stage_b.SUSTAINED_WINDOW_FACTOR`` × the first pulse; the closed-valve run is the same for every strategy of the
  impact) and is never restarted; it ends at each run's deepest point;
- F_ref = M1·(v1(t_w)²/(2·(s_usable − u1(t_w))) + g) from the closed-valve state at t_w: the lowest constant force
  that stops the mass in the stroke left;
- F_floor = M1·(F_friction + (p − p_atm)·A_rod)/(M1 + M2): while mass and piston move together the contact force
  cannot fall below it, whatever the valve does. p is the pressure of both chambers merged adiabatically at t_w
  (the lowest the lower chamber can reach through a valve to the upper one; a valve venting to the atmosphere
  reaches p_atm);
- R_B = peak of the CFC 60 contact force over [t_w, deepest point] / max(F_ref, F_floor) (ideal 1);
- R_B,wide: the same peak taken from t_1 + ``WIDE_DELAY`` instead, t_1 the end of the first contact pulse of the
  closed-valve run, over the same denominator. A controller that moves the stage-B peak before t_w (by acting
  early, or by letting the bodies part and meet again) would lower R_B without lowering the load; R_B,wide counts
  such a peak. It is never below R_B where t_1 + ``WIDE_DELAY`` <= t_w.

An impact whose closed-valve run has no sustained contact before its deepest point (a light mass stopped by the gas
spring in stage A) has no common window: it is excluded from R_B and counted apart, with its reason.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..filters import cfc_filter
from ..signals.pulses import contact_pulses
from ..signals.stage_b import SUSTAINED_WINDOW_FACTOR, is_sustained
from .bound import open_curve
from .target import stopping_force

#: channel frequency class of the filtered (body-load) contact force
BODY_CFC = 60
#: the wide window of R_B starts this long after the end of the first contact pulse [s] (clear of that pulse's
#: collision, which no valve changes)
WIDE_DELAY = 1e-3
#: the mass counts as stopped at its deepest point when its velocity there is below this fraction of V0
STOPPED_FRACTION = 0.01


@dataclass(frozen=True, kw_only=True)
class CommonWindow:
    """The window of R_B of one impact (NaN start and forces when there is none; ``reason`` then says why).

    Attributes
    ----------
    start : First sustained contact of the closed-valve run, t_w [s].
    reference_force : F_ref from the closed-valve state at t_w [N].
    floor_force : F_floor at t_w [N].
    reason : Why the impact has no window ("" when it has one).
    wide_start : Start of the wide window, the end of the closed-valve run's first contact pulse + ``WIDE_DELAY``
        [s] (NaN without a window).
    """

    start: float
    reference_force: float
    floor_force: float
    reason: str = ""
    wide_start: float = math.nan

    @property
    def denominator(self) -> float:
        """max(F_ref, F_floor) [N] (NaN without a window)."""
        return max(self.reference_force, self.floor_force) if math.isfinite(self.start) else math.nan


@dataclass(frozen=True, kw_only=True)
class WholeEvent:
    """One run judged from first contact until the mass stops (see the module notes; SI units)."""

    impact_force: float
    peak_force: float
    peak_ratio: float
    peak_deceleration_g: float
    efficiency: float
    stroke_used: float
    stroke_utilisation: float
    stopped: bool
    time_to_stop: float
    deepest_time: float


def impact_force(mass: float, velocity: float, usable_stroke: float, gravity: float) -> float:
    """F0 = M1·(V0²/(2·s_usable) + g) [N] for M1 [kg], V0 [m/s], s_usable [m] and g [m/s²]."""
    return float(stopping_force(float(mass), float(velocity), float(usable_stroke), float(gravity)))


def body_load(result) -> np.ndarray:
    """CFC 60 filtered contact force of a simulated run [N] (the force itself for a record too short to filter)."""
    t = result.time
    return cfc_filter(result.contact_force, 1.0 / (t[1] - t[0]), BODY_CFC) if t.size > 16 else result.contact_force


def floor_force(rig, mass: float, *, piston_position: float, pressure_lower: float, pressure_upper: float,
                vented: bool = False) -> float:
    """F_floor = M1·(F_friction + (p − p_atm)·A_rod)/(M1 + M2) [N] with p the chambers' pressures [Pa] at piston
    position ``piston_position`` [m] merged adiabatically (p_atm when ``vented``: the valve vents to the
    atmosphere)."""
    if vented:
        return float(mass * rig.friction.force / (mass + rig.cylinder.piston_mass))
    return float(open_curve(rig, mass, np.array([piston_position]), piston_position=piston_position,
                            pressure_lower=pressure_lower, pressure_upper=pressure_upper)[0])


def first_sustained_contact(time: np.ndarray, force: np.ndarray, u1: np.ndarray) -> float:
    """Start [s] of the first sustained contact before the deepest point of ``u1`` [m] (NaN when none)."""
    pulses = contact_pulses(time, force, sustained_factor=math.inf)  # every pulse, none marked
    if not pulses:
        return math.nan
    deepest = float(time[int(np.argmax(u1))])
    first = pulses[0].end - pulses[0].start
    for k, p in enumerate(pulses):
        if p.start > deepest:
            break
        if is_sustained(k, min(p.end, deepest) - p.start, first, SUSTAINED_WINDOW_FACTOR):
            return float(p.start)
    return math.nan


def common_window(closed_result, usable_stroke: float, *, vented: bool = False) -> CommonWindow:
    """The R_B window of an impact from its closed-valve run (a SimulationResult; see the module notes)."""
    r = closed_result
    start = first_sustained_contact(r.time, r.contact_force, r.u1)
    if not math.isfinite(start):
        return CommonWindow(start=math.nan, reference_force=math.nan, floor_force=math.nan,
                            reason="no sustained contact before the deepest point with the valve closed (stopped "
                                   "in stage A)")
    i = int(np.searchsorted(r.time, start - 1e-12))
    mass, g = r.scenario.mass, r.rig.gravity
    remaining = usable_stroke - float(r.u1[i])
    if remaining <= 0.0:
        return CommonWindow(start=math.nan, reference_force=math.nan, floor_force=math.nan,
                            reason="the usable stroke is used up at the first sustained contact")
    reference = mass * (max(float(r.v1[i]), 0.0) ** 2 / (2.0 * remaining) + g)
    floor = floor_force(r.rig, mass, piston_position=float(r.u2[i]), pressure_lower=float(r.pressure_lower[i]),
                        pressure_upper=float(r.pressure_upper[i]), vented=vented)
    first = contact_pulses(r.time, r.contact_force, sustained_factor=math.inf)[0]
    return CommonWindow(start=float(start), reference_force=float(reference), floor_force=floor,
                        wide_start=float(first.end) + WIDE_DELAY)


def window_peak(result, window: CommonWindow, *, filtered: np.ndarray | None = None,
                wide: bool = False) -> tuple[float, float]:
    """CFC 60 peak [N] over [t_w, deepest point] of a run and R_B [-] (NaN without a window, or when the run's
    deepest point comes before t_w); ``wide``: over [t_1 + ``WIDE_DELAY``, deepest point] and R_B,wide."""
    start = window.wide_start if wide else window.start
    if not (math.isfinite(window.start) and math.isfinite(start)):
        return math.nan, math.nan
    t = result.time
    deepest = int(np.argmax(result.u1))
    i0 = int(np.searchsorted(t, start - 1e-12))
    if i0 > deepest:
        return math.nan, math.nan
    body = body_load(result) if filtered is None else filtered
    peak = float(body[i0:deepest + 1].max())
    return peak, float(peak / window.denominator)


def whole_event(result, usable_stroke: float, *, filtered: np.ndarray | None = None) -> WholeEvent:
    """Whole-event metrics of a simulated run (a SimulationResult) for a usable stroke [m] (module notes)."""
    mass, velocity, g = result.scenario.mass, result.scenario.velocity, result.rig.gravity
    body = body_load(result) if filtered is None else filtered
    f0 = impact_force(mass, velocity, usable_stroke, g)
    deepest = int(np.argmax(result.u1))
    stopped = bool(abs(result.v1[deepest]) <= STOPPED_FRACTION * velocity)
    stroke = float(result.u1[deepest] - result.u1[0])
    peak = float(body.max())
    work = 0.5 * mass * (velocity ** 2 - float(result.v1[deepest]) ** 2) + mass * g * stroke
    return WholeEvent(impact_force=f0, peak_force=peak, peak_ratio=peak / f0,
                      peak_deceleration_g=(peak / mass - g) / g,
                      efficiency=float(work / (peak * stroke)) if peak > 0.0 and stroke > 0.0 else math.nan,
                      stroke_used=stroke, stroke_utilisation=stroke / usable_stroke, stopped=stopped,
                      time_to_stop=float(result.time[deepest]) if stopped else math.nan,
                      deepest_time=float(result.time[deepest]))
