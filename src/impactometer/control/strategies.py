"""Absorption strategies: a registry from name to a planner that turns what the impactometer knows into the
controller parameters of the compiled loop (:mod:`impactometer.control.controller`).

- ``closed``: the valve stays closed (gas spring).
- ``constant``: one opening, held from the control start until the estimated mass velocity reaches zero or the
  closed gas spring is needed to stop the bodies within the remaining stroke (then the valve closes for good),
  chosen by optimisation with the model for the identified M1 and V0: the opening with the lowest peak contact
  force after the control start whose stroke stays within the usable stroke.
- ``realtime``: feedback on the chamber pressures that holds the contact force at F* = M1·(v²/(2·s_remaining) + g),
  with v propagated from the identified V0 by the momentum balance of the mass (measured contact force), the
  remaining stroke from the measured piston displacement and the piston velocity from the integrated piston
  acceleration. Both valve strategies close the valve for good when the closed gas spring is needed to stop the
  bodies within the remaining stroke (``control.controller.must_close``).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..errors import ParameterError
from ..rig import Rig, Scenario
from . import controller as ctl
from . import simulate as loop
from .valve import Absorber


@dataclass(frozen=True, kw_only=True)
class ControlContext:
    """What a strategy may use: the stand, the absorber, the identified impact and when it became known.

    Attributes
    ----------
    rig : The stand.  absorber : Usable stroke, rated force, valve drive.
    mass, velocity : Identified (or, for the oracle, true) M1 [kg] and V0 [m/s].
    pressure_gauge : Charge pressure p0 [Pa gauge] (known: the stand was charged to it).
    start : Time the control starts [s] (the identification's ``available_at``).
    duration, sample_rate : Simulated time [s] and controller rate [Hz].
    charge_pressure, charge_temperature : Lower chamber pressure [Pa] and gas temperature [K] at first contact.
    """

    rig: Rig
    absorber: Absorber
    mass: float
    velocity: float
    pressure_gauge: float
    start: float
    duration: float
    sample_rate: float
    charge_pressure: float
    charge_temperature: float

    def base(self, strategy: int, **extra) -> np.ndarray:
        """Controller vector with the common fields filled."""
        return ctl.control_vector(strategy=strategy, start=self.start, mass=self.mass, velocity=self.velocity,
                                   usable_stroke=self.absorber.usable_stroke(self.rig),
                                   charge_pressure=self.charge_pressure,
                                   charge_temperature=self.charge_temperature, **extra)


def plan_closed(context: ControlContext) -> np.ndarray:
    """Valve closed throughout."""
    return context.base(ctl.CLOSED)


def plan_realtime(context: ControlContext) -> np.ndarray:
    """Real-time force control from the control start (see the module notes)."""
    return context.base(ctl.REALTIME, max_force=context.absorber.rated_force * 4.0,
                        tau_control=REALTIME_TAU_CONTROL, tau_filter=REALTIME_TAU_FILTER,
                        bounce_gate=context.absorber.bounce_gate, bounce_threshold=BOUNCE_THRESHOLD)


#: time constant of the gas-force loop and of the pressure filters of the real-time controller [s]
REALTIME_TAU_CONTROL = 2e-3
REALTIME_TAU_FILTER = 5e-4
#: relative velocity v1 − v2 [m/s] above which the bounce gate lets the force law open the valve
BOUNCE_THRESHOLD = 0.0
#: sample rate of the model runs of the constant-opening optimisation [Hz]
PLANNING_RATE = 10e3


def constant_outcome(context: ControlContext, area: float) -> tuple[float, float]:
    """Peak contact force after the control start [N] and largest mass displacement [m] predicted by the model for
    a constant opening ``area`` [m²] with the identified M1 and V0 (noise-free sensors)."""
    scenario = Scenario(mass=context.mass, velocity=context.velocity, pressure_gauge=context.pressure_gauge)
    control = context.base(ctl.CONSTANT, area=area)
    result, _ = loop.simulate_controlled(scenario, context.rig, control=control, drive=context.absorber.drive,
                                         duration=context.duration, sample_rate=PLANNING_RATE)
    after = result.time >= context.start
    return float(result.contact_force[after].max()), float(result.u1.max())


def optimal_constant_area(context: ControlContext, *, candidates: int = 9, refinements: int = 4) -> float:
    """Opening [m²] with the lowest predicted peak force after the control start among those whose stroke stays
    within the usable stroke; 0 (closed) when no opening is feasible.

    A log-spaced scan over (0, A_max] is followed by golden-section refinement around the best feasible opening.
    """
    a_max = context.rig.valve.max_area
    usable = context.absorber.usable_stroke(context.rig)
    cache: dict[float, float] = {}

    def cost(area: float) -> float:
        if area not in cache:
            peak, stroke = constant_outcome(context, area)
            cache[area] = peak if stroke <= usable else math.inf
        return cache[area]

    grid = [0.0] + list(a_max * np.geomspace(1.0 / 64.0, 1.0, candidates))
    costs = [cost(a) for a in grid]
    best = int(np.argmin(costs))
    if not math.isfinite(costs[best]):
        return 0.0
    low, high = grid[max(best - 1, 0)], grid[min(best + 1, len(grid) - 1)]
    ratio = (math.sqrt(5.0) - 1.0) / 2.0
    for _ in range(refinements):
        a = high - ratio * (high - low)
        b = low + ratio * (high - low)
        if cost(a) <= cost(b):
            high = b
        else:
            low = a
    return min(cache, key=lambda area: (cache[area], -area))


def plan_constant(context: ControlContext) -> np.ndarray:
    """The optimised constant opening (closed for good once the mass stops or its stroke runs short)."""
    return context.base(ctl.CONSTANT, area=optimal_constant_area(context))


#: strategy name -> planner(context) -> controller vector
STRATEGIES: dict[str, Callable[[ControlContext], np.ndarray]] = {
    "closed": plan_closed, "constant": plan_constant, "realtime": plan_realtime}


def get_strategy(name: str) -> Callable[[ControlContext], np.ndarray]:
    """The planner of strategy ``name``; ParameterError listing the valid names otherwise."""
    if not isinstance(name, str) or name not in STRATEGIES:
        raise ParameterError(f"strategy must be one of {sorted(STRATEGIES)}, got {name!r}")
    return STRATEGIES[name]


def strategy_names(selection: str | list[str] | tuple[str, ...]) -> list[str]:
    """Strategy names of ``selection`` (``"all"``, one name, or a list), validated, in registry order."""
    if not isinstance(selection, (str, list, tuple)):
        raise ParameterError(f"strategy selection must be 'all', a strategy name or a list of them, got "
                             f"{type(selection).__name__}")
    names = list(STRATEGIES) if selection == "all" else [selection] if isinstance(selection, str) else list(selection)
    for name in names:
        get_strategy(name)
    if not names:
        raise ParameterError("strategy selection must name at least one strategy, got an empty list")
    return names

