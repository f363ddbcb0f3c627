"""The best any valve program can do on the stand: the efficiency bound η_max.

A valve can only lower the gas force below the closed-valve (gas-spring) curve. From the state at the control
start the best program therefore follows the closed-valve curve until it reaches a constant level F_c, then holds
F_c, with F_c chosen so that the mass stops exactly at the end of the usable stroke. Its efficiency (same definition
as :mod:`impactometer.control.metrics`) is the bound η_max.

The curve is the contact force of sustained contact (mass and piston moving together) with the valve closed:
F_closed(s) = M1·(Fp(u2) + F_friction)/(M1 + M2), with the chamber pressures following p·V^γ = const from their
values at the control start (the closed chambers are adiabatic) and the piston position u2 = s − δ(F) behind the
mass position s by the static contact compression δ. Stage-A contact pulses are not part of the idealised program.

The bound ignores that at the control start the piston is flying off the mass after a collision: the relative
motion carries the bounce energy μ·(v1 − v2)²/2 that only the contact dissipates, in collisions whose peaks are
far above F_c. :func:`first_collision_peak` measures the peak of the next collision when the valve opens fully at
the control start (the fastest drop of the gas force the valve can make), and
``EfficiencyBound.efficiency_first_collision`` is the bound program's efficiency with its peak raised to it: a
supplementary reference, reported next to η_max, not a replacement for it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import ControlError
from ..model.forces import pneumatic_force
from ..signals.pulses import contact_pulses
from .plant import simulate_controlled
from .settings import ControlSettings


@dataclass(frozen=True, kw_only=True)
class EfficiencyBound:
    """The bound program from the control start.

    Attributes
    ----------
    level : Constant contact force F_c held after the closed-valve curve reaches it [N] (the peak force).
    efficiency : η_max [-].
    stroke : Mass travel from the control start to the stop [m].
    energy : Work the contact force must do on the mass after the control start [J].
    over_capacity : True when even the closed valve cannot stop the mass within the usable stroke.
    first_collision_peak : Peak of the first collision after the control start with the valve fully open from
        the control start [N] (NaN when not computed).
    """

    level: float
    efficiency: float
    stroke: float
    energy: float
    over_capacity: bool
    first_collision_peak: float = math.nan

    @property
    def efficiency_first_collision(self) -> float:
        """Efficiency of the bound program with its peak raised to ``first_collision_peak`` [-] (NaN if unknown)."""
        peak = max(self.level, self.first_collision_peak)
        if not (math.isfinite(peak) and peak > 0.0 and self.stroke > 0.0):
            return math.nan
        return float(min(1.0, self.energy / (peak * self.stroke)))


def _compression(force: np.ndarray, rig) -> np.ndarray:
    """Static contact compression [m] at contact force ``force`` [N]."""
    k = rig.contact.stiffness
    if rig.contact.law == "hunt-crossley":
        return (np.clip(force, 0.0, None) / k) ** (2.0 / 3.0)
    return np.clip(force, 0.0, None) / k


def closed_curve(rig, mass: float, positions: np.ndarray, *, piston_position: float, pressure_lower: float,
                 pressure_upper: float) -> np.ndarray:
    """Sustained-contact contact force of the closed valve [N] at mass positions ``positions`` [m].

    The chamber pressures [Pa] are given at piston position ``piston_position`` [m] and follow p·V^γ = const.
    """
    c, gamma = rig.cylinder, rig.gas.gamma
    lower0 = c.area * (c.lower_length - piston_position) + c.dead_volume_lower
    upper0 = c.annulus_area * (c.upper_length + piston_position) + c.dead_volume_upper
    share = mass / (mass + c.piston_mass)
    force = np.zeros_like(positions)
    for _ in range(4):  # fixed point on the contact compression (a small correction)
        u2 = np.clip(positions - _compression(force, rig), 0.0, c.stroke)  # the piston stays in its stroke
        lower = np.maximum(c.area * (c.lower_length - u2) + c.dead_volume_lower, 1e-9 * lower0)
        upper = c.annulus_area * (c.upper_length + u2) + c.dead_volume_upper
        p_lower = pressure_lower * (lower0 / lower) ** gamma
        p_upper = pressure_upper * (upper0 / upper) ** gamma
        fp = pneumatic_force(p_lower, p_upper, c.area, c.rod_area, rig.gas.atmospheric_pressure)
        force = np.clip(share * (fp + rig.friction.force), 0.0, None)
    return force


def open_curve(rig, mass: float, positions: np.ndarray, *, piston_position: float, pressure_lower: float,
               pressure_upper: float) -> np.ndarray:
    """Sustained-contact contact force with the valve wide open and the chambers merged [N] (the lowest force a
    valve between the chambers can give): one gas volume, mixed adiabatically at the control start
    (p·V = pL·VL + pU·VU) and compressed isentropically by the rod."""
    c, gamma = rig.cylinder, rig.gas.gamma
    lower0 = c.area * (c.lower_length - piston_position) + c.dead_volume_lower
    upper0 = c.annulus_area * (c.upper_length + piston_position) + c.dead_volume_upper
    mixed = (pressure_lower * lower0 + pressure_upper * upper0) / (lower0 + upper0)
    total = lower0 + upper0 - c.rod_area * (positions - piston_position)
    pressure = mixed * ((lower0 + upper0) / total) ** gamma
    share = mass / (mass + c.piston_mass)
    return np.clip(share * ((pressure - rig.gas.atmospheric_pressure) * c.rod_area + rig.friction.force), 0.0, None)


def _stop(force: np.ndarray, s: np.ndarray, energy: float, weight: float) -> int:
    """Index of the first grid point where the work of ``force`` has absorbed the energy, or -1."""
    work = np.concatenate(([0.0], np.cumsum(0.5 * (force[1:] + force[:-1]) * np.diff(s))))
    done = np.flatnonzero(work - weight * (s - s[0]) >= energy)
    return int(done[0]) if done.size else -1


def efficiency_bound(closed_result, control_start: float, usable_stroke: float, *,
                     points: int = 4001) -> EfficiencyBound:
    """η_max of the impact simulated (valve closed) in ``closed_result``, for control from ``control_start`` [s].

    Parameters
    ----------
    closed_result : SimulationResult
        The impact with the valve closed (its state at the control start is the start of the bound program).
    control_start : float
        Time the control starts [s].
    usable_stroke : float
        Largest mass displacement allowed [m].
    points : int
        Resolution of the stroke grid.

    Notes
    -----
    The program is F(s) = max(F_open(s), min(F_closed(s), F_c)) with the lowest F_c that stops the mass within the
    usable stroke; when even the wide-open valve stops it earlier, F_c = 0 (the open-valve curve).
    """
    r = closed_result
    i0 = int(np.searchsorted(r.time, control_start - 1e-12))
    if i0 >= r.time.size:
        raise ControlError(f"control_start {control_start!r} s is after the end of the closed-valve record "
                           f"({r.time[-1]!r} s)")
    rig, mass, g = r.rig, r.scenario.mass, r.rig.gravity
    start = float(r.u1[i0])
    energy = float(0.5 * mass * max(r.v1[i0], 0.0) ** 2)
    if start >= usable_stroke or energy <= 0.0:
        return EfficiencyBound(level=math.nan, efficiency=math.nan, stroke=0.0, energy=energy,
                               over_capacity=start >= usable_stroke)
    s = np.linspace(start, usable_stroke, points)
    state = dict(piston_position=float(r.u2[i0]), pressure_lower=float(r.pressure_lower[i0]),
                 pressure_upper=float(r.pressure_upper[i0]))
    closed = closed_curve(rig, mass, s, **state)
    lowest = np.minimum(open_curve(rig, mass, s, **state), closed)

    def program(level: float) -> np.ndarray:
        return np.maximum(lowest, np.minimum(closed, level))

    def outcome(level: float, over: bool) -> EfficiencyBound:
        f = program(level)
        stop = _stop(f, s, energy, mass * g)
        stop = points - 1 if stop < 0 else max(stop, 1)
        stroke = float(s[stop] - start)
        work = energy + mass * g * stroke
        return EfficiencyBound(level=float(f[:stop + 1].max()), efficiency=float(min(1.0, work / (
            f[:stop + 1].max() * stroke))), stroke=stroke, energy=float(work), over_capacity=over)

    if _stop(closed, s, energy, mass * g) < 0:  # even the closed valve overshoots the usable stroke
        return outcome(float(closed.max()), True)
    if _stop(lowest, s, energy, mass * g) >= 0:  # the wide-open valve stops it within the stroke
        return outcome(0.0, False)
    low, high = 0.0, float(closed.max())
    for _ in range(60):
        mid = 0.5 * (low + high)
        low, high = (low, mid) if _stop(program(mid), s, energy, mass * g) >= 0 else (mid, high)
    return outcome(high, False)


#: time after the control start within which :func:`first_collision_peak` looks for the next collision [s]
COLLISION_WINDOW = 0.1


def first_collision_peak(scenario, rig, drive, control_start: float, *, sample_rate: float = 50e3) -> float:
    """Peak contact force [N] of the first collision after ``control_start`` [s] with valve Z fully open from then
    on (``drive`` a ValveDrive: its dead time and lag apply); the largest force within ``COLLISION_WINDOW`` after
    the control start if no collision begins within it."""
    control = ControlSettings(strategy="constant", start=control_start, opening=1.0, mass=scenario.mass,
                              velocity=scenario.velocity, close_on_stop=False, supervise=False, refine_mass=False)
    result, _ = simulate_controlled(scenario, rig, control=control, drive=drive,
                                    duration=control_start + COLLISION_WINDOW, sample_rate=sample_rate)
    t, force = result.time, result.contact_force
    after = t >= control_start - 1e-12
    later = [p for p in contact_pulses(t, force) if p.start > control_start]
    if later:
        after &= t <= later[0].end
    return float(force[after].max()) if np.any(after) else math.nan
