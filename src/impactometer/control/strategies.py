"""Absorption strategies: a registry from name to a planner that turns what the impactometer knows into the
settings of the controller (:class:`~impactometer.control.settings.ControlSettings`).

- ``closed``: the valve stays closed (gas spring).
- ``constant``: one opening, held from the control start until the estimated mass velocity reaches zero or the
  closed gas spring is needed to stop the bodies within the remaining stroke (then the valve closes for good),
  chosen by optimisation with the model for the identified M1 and V0: the opening with the lowest peak contact
  force after the control start whose stroke stays within the usable stroke.
- ``realtime``: feedback on the chamber pressures that holds the contact force at F* = M1·(v²/(2·s_remaining) + g)
  from the current estimates (:mod:`.estimator`: M1 refined in sustained contact, v from the momentum balance and,
  in sustained contact, from the piston observer; s_remaining from the rod displacement).
- ``predictive``: the same target, with the valve's dead time and lag planned for: the controller predicts the
  chamber pressures and the opening over the dead time from the commands already sent (its model of the actuator)
  and sets the command that brings the opening, after the lag, to what the predicted state needs; re-planned at
  every sample as the estimates improve. It acts from the control start, in stage A when the identification
  comes before stage B.
- ``auto``: the better of ``realtime`` and ``predictive`` on the acceptance grid (:data:`AUTO`: ``predictive``).

Every valve strategy keeps the valve closed while the closed gas spring is needed to stop the bodies within the
remaining stroke (``control.controller.must_close``). After the stop, ``realtime`` and ``predictive`` brake the
rebound: while the gas the stroke compressed lifts the bodies, they vent it towards the weight.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..errors import ParameterError
from ..rig import Rig, Scenario
from . import plant
from .settings import ControlSettings
from .valve import Absorber


@dataclass(frozen=True, kw_only=True)
class ControlContext:
    """What a strategy may use: the stand, the absorber, the identified impact and when it became known.

    Attributes
    ----------
    rig : The stand.  absorber : Usable stroke, rated force, valve drive.
    mass, velocity : Identified (or, for the oracle, true) M1 [kg] and V0 [m/s]; NaN mass: not usable (the
        controller waits for its stage-B estimate).
    mass_std : Standard error of ``mass`` [kg] (0 for the oracle, which also does not refine it).
    mass_floor : Floor of ``mass_std`` as a fraction of ``mass`` [-] (the identification's validated error,
        :func:`.identified.mass_floor`).
    pressure_gauge : Charge pressure p0 [Pa gauge] (known: the stand was charged to it).
    start : Time the control starts [s] (the identification's ``available_at``).
    duration, sample_rate : Simulated time [s] and controller rate [Hz].
    pressure_lower_start, temperature_lower_start : Lower-chamber pressure [Pa absolute] and gas temperature [K] at
        first contact.
    force_noise, acceleration_noise : Standard deviations of the force sensor's [N] and the accelerometer's
        [m/s²] noise.
    early_start, early_mass, early_mass_std, early_velocity : What is known before the control start, from
        ``early_start`` [s] on (``inf``: nothing): a prior of M1 [kg] with its standard deviation and V0 [m/s]
        (:class:`.settings.ControlSettings`); the force strategies act on it.
    """

    rig: Rig
    absorber: Absorber
    mass: float
    velocity: float
    pressure_gauge: float
    start: float
    duration: float
    sample_rate: float
    pressure_lower_start: float
    temperature_lower_start: float
    mass_std: float = math.inf
    force_noise: float = 0.0
    acceleration_noise: float = 0.0
    early_start: float = math.inf
    early_mass: float = math.nan
    early_mass_std: float = math.inf
    early_velocity: float = math.nan
    mass_floor: float = 0.0

    def base(self, strategy: str, **extra) -> ControlSettings:
        """Controller settings with the common fields filled."""
        oracle = self.mass_std == 0.0
        return ControlSettings(strategy=strategy, start=self.start, mass=self.mass, mass_std=self.mass_std,
                               velocity=self.velocity, usable_stroke=self.absorber.usable_stroke(self.rig),
                               pressure_lower_start=self.pressure_lower_start,
                               temperature_lower_start=self.temperature_lower_start,
                               force_noise=self.force_noise, acceleration_noise=self.acceleration_noise,
                               refine_mass=not oracle, early_start=self.early_start, early_mass=self.early_mass,
                               early_mass_std=self.early_mass_std, early_velocity=self.early_velocity,
                               mass_floor=self.mass_floor, **extra)


def plan_closed(context: ControlContext) -> ControlSettings:
    """Valve closed throughout."""
    return context.base("closed")


def plan_realtime(context: ControlContext) -> ControlSettings:
    """Real-time force control from the control start (see the module notes)."""
    return context.base("realtime", max_force=context.absorber.rated_force * 4.0,
                        tau_control=realtime_tau_control(context.absorber.drive), tau_filter=REALTIME_TAU_FILTER,
                        bounce_gate=context.absorber.bounce_gate, bounce_threshold=BOUNCE_THRESHOLD)


def plan_predictive(context: ControlContext) -> ControlSettings:
    """Predictive force control from the control start (see the module notes)."""
    return context.base("predictive", max_force=context.absorber.rated_force * 4.0,
                        tau_control=predictive_tau_control(context.absorber.drive), tau_filter=REALTIME_TAU_FILTER)


#: time constant of the gas-force loop of a valve without lag, and of the pressure filters of the controllers [s]
REALTIME_TAU_CONTROL = 2e-3
REALTIME_TAU_FILTER = 5e-4
#: shortest time constant of the predictive gas-force loop [s] (twice the pressure filters')
PREDICTIVE_TAU_FLOOR = 1e-3


def realtime_tau_control(drive) -> float:
    """Time constant of the real-time gas-force loop [s]: 2 ms plus twice the valve's dead time and lag (a
    feedback loop much faster than its actuator oscillates; the real-time law does not model the actuator)."""
    return REALTIME_TAU_CONTROL + 2.0 * (drive.dead_time + drive.time_constant)


def predictive_tau_control(drive) -> float:
    """Time constant of the predictive gas-force loop [s]: the valve's own lag, at least ``PREDICTIVE_TAU_FLOOR``
    (the dead time is predicted and the lag compensated, so the loop need not wait for them)."""
    return max(drive.time_constant, PREDICTIVE_TAU_FLOOR)
#: relative velocity v1 − v2 [m/s] above which the bounce gate lets the force law open the valve
BOUNCE_THRESHOLD = 0.0
#: sample rate of the model runs of the constant-opening optimisation [Hz]
PLANNING_RATE = 10e3


def constant_outcome(context: ControlContext, opening: float) -> tuple[float, float]:
    """Peak contact force after the control start [N] and largest mass displacement [m] predicted by the model for
    a constant ``opening`` [-] with the identified M1 and V0 (noise-free sensors)."""
    scenario = Scenario(mass=context.mass, velocity=context.velocity, pressure_gauge=context.pressure_gauge)
    control = dataclasses.replace(context.base("constant", opening=opening), mass_std=0.0, refine_mass=False)
    result, _ = plant.simulate_controlled(scenario, context.rig, control=control, drive=context.absorber.drive,
                                         duration=context.duration, sample_rate=PLANNING_RATE)
    after = result.time >= context.start  # none when the control starts after the simulated span: nothing to act on
    peak = float(result.contact_force[after].max()) if after.any() else 0.0
    return peak, float(result.u1.max())


def optimal_constant_opening(context: ControlContext, *, candidates: int = 9, refinements: int = 4) -> float:
    """Opening [-] with the lowest predicted peak force after the control start among those whose stroke stays
    within the usable stroke; 0 (closed) when no opening is feasible or the mass is not known.

    A log-spaced scan over (0, 1] is followed by golden-section refinement around the best feasible opening.
    """
    if not context.mass > 0.0:
        return 0.0
    usable = context.absorber.usable_stroke(context.rig)
    cache: dict[float, float] = {}

    def cost(opening: float) -> float:
        if opening not in cache:
            peak, stroke = constant_outcome(context, opening)
            cache[opening] = peak if stroke <= usable else math.inf
        return cache[opening]

    grid = [0.0] + list(np.geomspace(1.0 / 64.0, 1.0, candidates))
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
    return min(cache, key=lambda opening: (cache[opening], -opening))


def plan_constant(context: ControlContext) -> ControlSettings:
    """The optimised constant opening (closed for good once the mass stops or its stroke runs short)."""
    return context.base("constant", opening=optimal_constant_opening(context))


#: the strategy ``auto`` runs: the better of ``realtime`` and ``predictive`` on the acceptance grid
AUTO = "predictive"
#: strategy name -> planner(context) -> controller settings
STRATEGIES: dict[str, Callable[[ControlContext], ControlSettings]] = {
    "closed": plan_closed, "constant": plan_constant, "realtime": plan_realtime, "predictive": plan_predictive}
STRATEGIES["auto"] = STRATEGIES[AUTO]
#: the strategies of ``"all"`` (``auto`` is another name of one of them)
ALL = ("closed", "constant", "realtime", "predictive")


def get_strategy(name: str) -> Callable[[ControlContext], ControlSettings]:
    """The planner of strategy ``name``; ParameterError listing the valid names otherwise."""
    if not isinstance(name, str) or name not in STRATEGIES:
        raise ParameterError(f"strategy must be one of {sorted(STRATEGIES)}, got {name!r}")
    return STRATEGIES[name]


def strategy_names(selection: str | list[str] | tuple[str, ...]) -> list[str]:
    """Strategy names of ``selection`` (``"all"``, one name, or a list), validated, in registry order."""
    if not isinstance(selection, (str, list, tuple)):
        raise ParameterError(f"strategy selection must be 'all', a strategy name or a list of them, got "
                             f"{type(selection).__name__}")
    names = list(ALL) if selection == "all" else [selection] if isinstance(selection, str) else list(selection)
    for name in names:
        get_strategy(name)
    if not names:
        raise ParameterError("strategy selection must name at least one strategy, got an empty list")
    return names

