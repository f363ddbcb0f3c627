"""The closed loop: simulated sensors (with noise) → identification of M1 and V0 → a strategy that starts when
the identification becomes available; compared with an oracle that knows the true M1 and V0.

By default (``early``) the force strategies act from first contact on what is known (V0 from the first samples, M1's
prior over the rated masses) and the model identification reads the record of the run with the valve's opening as an
input; with ``early=False`` (the ``wait`` policy) the valve stays closed until the control starts, so the
identification reads a record of the closed-valve impact (:mod:`.identified`).

The controller's own sensors (contact force, piston
acceleration, chamber pressures, rod displacement) get white Gaussian noise of the same relative level: ``noise`` ×
the RMS of each channel over the closed-valve record. Besides the force sensor, the accelerometer and the chamber
pressure sensors of the paper's Fig. 10, the absorber reads the piston displacement (a displacement transducer on
the rod): integrating the acceleration twice drifts by about 1 cm over the 0.4 s of a controlled stroke at 2 % noise,
as much as the whole stroke margin.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..errors import ParameterError, shown
from ..identify.result import Identification
from ..rig import ABSORPTION_RIG, Rig, Scenario, get_rig
from ..signals.pulses import contact_pulses
from ..validation import check_flag, check_integer, check_real, finite_or_none
from . import plant
from .bound import EfficiencyBound, efficiency_bound, first_collision_peak
from .event import BODY_CFC, STOPPED_FRACTION, CommonWindow, body_load, common_window, impact_force
from .identified import (
    IDENTIFICATION_WINDOW,
    LATENCY,
    contact_velocity,
    identification_record,
    identify_impact,
    loop_method,
    loop_summary,
    mass_floor,
    run_record,
    usable_mass,
    usable_velocity,
)
from .metrics import AbsorptionMetrics, absorption_metrics
from .reference import EVALUATIONS as REFERENCE_EVALUATIONS
from .reference import AchievableReference, achievable_reference
from .strategies import ControlContext, get_strategy, strategy_names
from .valve import Absorber

#: identification methods of the loop
IDENTIFICATIONS = ("robust", "paper", "model", "oracle", "response-map")
#: a valve strategy's run ends this long after the mass's deepest point [s]: long enough for the rebound of a mass
#: resting on the closed gas spring (a period of 0.1-0.3 s) to show
REBOUND_WINDOW = 0.15
#: a run whose mass has not stopped at the end of its record is simulated again for twice as long, up to this
#: duration [s]; one that has not stopped then is reported as a run that cannot stop (``stopped`` False)
MAX_DURATION = 4.0


@dataclass(frozen=True, kw_only=True)
class StrategyRun:
    """One strategy applied to the impact: the histories, the controller's histories and the metrics."""

    strategy: str
    result: Any  # SimulationResult
    controller: dict[str, np.ndarray]
    metrics: AbsorptionMetrics
    valve_opening_constant: float = math.nan
    #: the instant the strategy's controller takes the identification's answer [s] (inf: never; NaN: closed valve)
    answer_at: float = math.nan


@dataclass(frozen=True, kw_only=True)
class AbsorptionResult:
    """The impact absorbed with one or more strategies, the identification they used and the bound η_max.

    ``control_start`` [s] is the instant the absorber took over, the same for every strategy's metrics: the
    identification's answer, or earlier, when a force strategy knew M1 and v1 from its own stage-B estimates
    (``inf`` when neither came).
    """

    scenario: Scenario
    rig: Rig
    absorber: Absorber
    identified: Identification
    runs: dict[str, StrategyRun]
    bound: EfficiencyBound
    over_capacity: bool
    window: CommonWindow = CommonWindow(start=math.nan, reference_force=math.nan, floor_force=math.nan)
    control_start: float = math.inf
    reference: AchievableReference | None = None
    notes: tuple[str, ...] = ()
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def identification(self) -> str:
        """The loop's name of the identification it acted on: ``robust``, ``paper``, ``response-map`` or
        ``oracle``."""
        return loop_method(self.identified)

    @property
    def metrics(self) -> dict[str, AbsorptionMetrics]:
        """Metrics by strategy name."""
        return {name: run.metrics for name, run in self.runs.items()}

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready summary: scenario, identification, bound and per-strategy metrics (no histories)."""
        strategies = {}
        for name, run in self.runs.items():
            strategies[name] = run.metrics.to_dict()
            if math.isfinite(run.valve_opening_constant):
                strategies[name]["valve_opening"] = run.valve_opening_constant
            if not math.isnan(run.answer_at):
                strategies[name]["answer_at_s"] = finite_or_none(run.answer_at)
            mass = run.controller.get("estimated_mass")
            if mass is not None and np.any(np.isfinite(mass)):
                last = int(np.flatnonzero(np.isfinite(mass))[-1])
                strategies[name]["estimated_mass_kg"] = finite_or_none(float(mass[last]))
                std = float(run.controller["estimated_mass_std"][last])
                strategies[name]["estimated_mass_std_kg"] = finite_or_none(std)
        reference, window = self.reference, self.window
        return {"mass_kg": self.scenario.mass, "velocity_m_s": self.scenario.velocity,
                "pressure_gauge_Pa": self.scenario.pressure_gauge, "identification": loop_summary(self.identified),
                "rig": self.rig.name, "usable_stroke_m": self.absorber.usable_stroke(self.rig),
                "control_start_s": finite_or_none(self.control_start),
                "common_window_start_s": finite_or_none(window.start),
                "wide_window_start_s": finite_or_none(window.wide_start),
                "reference_force_N": finite_or_none(window.reference_force),
                "floor_force_N": finite_or_none(window.floor_force), "common_window_excluded": window.reason or None,
                **({} if reference is None else reference.to_dict()),
                "efficiency_max": finite_or_none(self.bound.efficiency),
                "bound_force_N": finite_or_none(self.bound.level),
                "first_collision_peak_N": finite_or_none(self.bound.first_collision_peak),
                "efficiency_first_collision": finite_or_none(self.bound.efficiency_first_collision),
                "over_capacity": self.over_capacity, "notes": list(self.notes), "strategies": strategies}

    def plot(self, ax=None):
        """The force histories of every strategy on one figure (the paper's Fig. 10b;
        :func:`impactometer.plotting.absorption.plot_absorption`)."""
        from ..plotting.absorption import plot_absorption

        loads = {name: body_load(run.result) for name, run in self.runs.items()}
        return plot_absorption(self, loads, BODY_CFC, ax=ax)


def early_knowledge(scenario: Scenario, rig: Rig, absorber: Absorber, *, noise: float, seed: int,
                    sample_rate: float, latency: float) -> dict[str, float]:
    """What a controller knows from first contact on, as :class:`.strategies.ControlContext` fields: V0 from the
    first samples of the contact (:func:`~.identified.contact_velocity` on the noisy record the identification
    reads, from ``early_start`` = its data's end + ``latency`` [s]) and M1's prior over the stand's rated masses
    (``early_mass`` ± ``early_mass_std`` [kg], :meth:`.valve.Absorber.mass_prior`). Empty where V0 is not found or
    not trusted (the controller then waits for the identification)."""
    rec = identification_record(scenario, rig, noise=noise, seed=seed, sample_rate=sample_rate)
    v0 = contact_velocity(rec, rig, latency=latency)
    if not math.isfinite(usable_velocity(v0)):
        return {}
    mass, mass_std = absorber.mass_prior()
    return {"early_start": float(v0.available_at), "early_mass": mass, "early_mass_std": mass_std,
            "early_velocity": float(v0.velocity)}


def _knew(history: dict[str, np.ndarray], result) -> float:
    """First sample [s] at which a controller knew both M1 and v1 (``inf`` if never)."""
    known = np.isfinite(history["estimated_mass"]) & np.isfinite(history["estimated_velocity"])
    return float(result.time[np.argmax(known)]) if known.any() else math.inf


def default_duration(scenario: Scenario, usable_stroke: float) -> float:
    """Simulated time long enough for the slowest strategy to stop the mass [s]: 0.15 s + 4·usable stroke / V0,
    within [0.3, 1.2] s (the valve strategies' runs end ``REBOUND_WINDOW`` after the mass's deepest point)."""
    return float(min(1.2, max(0.3, 0.15 + 4.0 * usable_stroke / scenario.velocity)))


def sensor_sigma(closed_result, noise: float) -> np.ndarray:
    """Standard deviation of each of the controller's sensors (in the order of ``plant.SENSOR_CHANNELS``):
    ``noise`` × each channel's RMS over the closed-valve record's first ``IDENTIFICATION_WINDOW``."""
    window = closed_result.time <= IDENTIFICATION_WINDOW
    return np.array([noise * float(np.sqrt(np.mean(getattr(closed_result, name)[window] ** 2)))
                     for name in plant.SENSOR_CHANNELS])


def sensor_noise(sigma: np.ndarray, samples: int, seed: int) -> np.ndarray:
    """Noise matrix (N_SENSOR, ``samples``) of the controller's sensors with standard deviations ``sigma``; drawn
    sample by sample, so a longer run sees the same noise over the samples the shorter one had."""
    rng = np.random.default_rng([int(seed), 7])
    return sigma[:, None] * rng.standard_normal((samples, sigma.size)).T


def run_until_stopped(scenario: Scenario, rig: Rig, control, absorber: Absorber, *, duration: float,
                      sample_rate: float, sigma: np.ndarray, seed: int):
    """A controlled run (``simulate_controlled``) simulated until the mass has stopped: a run whose mass still
    moves at the end of its record is simulated again for twice as long, up to ``MAX_DURATION`` [s] (and to the
    end of its record, where it had ended ``REBOUND_WINDOW`` after a bounce taken for the stop)."""
    stop_after = REBOUND_WINDOW
    while True:
        samples = plant.sample_times(duration, sample_rate).size
        result, history = plant.simulate_controlled(
            scenario, rig, control=control, drive=absorber.drive, duration=duration, sample_rate=sample_rate,
            sensor_noise=sensor_noise(sigma, samples, seed), stop_after=stop_after)
        deepest = int(np.argmax(result.u1))
        moving = abs(result.v1[deepest]) > STOPPED_FRACTION * scenario.velocity
        if not moving or "ended_at_bottom" in result.extra or duration >= MAX_DURATION:
            return result, history
        if result.time.size < samples:  # ended after a turn of the mass that was a bounce, not the stop
            stop_after = math.inf
            continue
        duration = min(2.0 * duration, MAX_DURATION)


def _identified(scenario: Scenario, rig: Rig, closed, identification: str, *, noise: float, seed: int,
                sample_rate: float, control_start: float | None, response_map,
                latency: float) -> Identification:
    """What the loop knows of M1 and V0 and when: the identification's answer (known at ``control_start`` [s]
    where that is given), or the oracle's (from the start of the closed-valve run's second contact pulse)."""
    if identification == "oracle":
        if control_start is None:  # from the start of the second contact pulse (stage B, or the last rebound)
            pulses = contact_pulses(closed.time, closed.contact_force)
            at, error = (pulses[1].start, None) if len(pulses) > 1 else (math.inf, "a single contact pulse")
        else:
            at, error = float(control_start), None
        return Identification(method="oracle", mass=scenario.mass, velocity=scenario.velocity, mass_std=0.0,
                              velocity_std=0.0, available_at=at, error=error)
    found = identify_impact(scenario, rig, method=identification, noise=noise, seed=seed, sample_rate=sample_rate,
                            response_map=response_map, latency=latency)
    if control_start is not None and found.error is None:
        found = dataclasses.replace(found, available_at=float(control_start))
    return found


def _notes(found: Identification, required: float, usable: float, absorber: Absorber) -> list[str]:
    """What the user should know of the run: an identification that failed or is not trusted, an impact beyond
    the absorber's rated force (``required`` [N] over the ``usable`` stroke [m])."""
    notes = []
    if found.error is not None:
        notes.append(f"identification failed ({found.error}): the force strategies act on their own stage-B "
                     f"estimates, the others keep the valve closed")
    elif not math.isfinite(usable_mass(found)) or not math.isfinite(usable_velocity(found)):
        notes.append(f"identified M1 = {found.mass:.3g} ± {found.mass_std:.2g} kg, V0 = {found.velocity:.3g} ± "
                     f"{found.velocity_std:.2g} m/s not trusted: the controller waits for its stage-B estimate")
    if required > absorber.rated_force:
        notes.append(f"impact energy needs a constant force of {required:.0f} N over the usable stroke "
                     f"({usable:.3f} m), above the rated {absorber.rated_force:.0f} N: the best achievable outcome "
                     f"is shown")
    return notes


def _strategy_run(name: str, context: ControlContext, found: Identification, closed, scenario: Scenario,
                  absorber: Absorber, *, sigma: np.ndarray, seed: int, answer_of=None):
    """(settings, run, controller histories) of strategy ``name``: the closed-valve run itself for ``closed`` (and
    for every strategy but the force ones when the identification failed), else a run until the mass stops. A force
    strategy acting on partial knowledge (``context.early_start`` finite) takes the identification's answer
    ``answer_of(run, histories)`` of the record its run without the answer had (:func:`_early_run`)."""
    control = get_strategy(name)(context)
    if found.error is not None and control.strategy not in ("realtime", "predictive"):
        control = context.base("closed")  # no early answer: only the force strategies act, on their own estimates
    if control.strategy == "closed":
        return control, closed, {key: np.full_like(closed.time, np.nan) for key in plant.HISTORIES}
    if answer_of is not None and control.strategy in ("realtime", "predictive") \
            and math.isfinite(control.early_start):
        return _early_run(control, context, scenario, absorber, sigma=sigma, seed=seed, answer_of=answer_of)
    return (control, *run_until_stopped(scenario, context.rig, control, absorber, duration=context.duration,
                                        sample_rate=context.sample_rate, sigma=sigma, seed=seed))


def _early_run(control, context: ControlContext, scenario: Scenario, absorber: Absorber, *, sigma: np.ndarray,
               seed: int, answer_of):
    """A force strategy that acts from first contact on partial knowledge and takes the identification's answer:
    the run without an answer first, then the answer of the record that run had (``answer_of(run, histories)``:
    the model stream with the run's valve opening as an input, or another identification on the record up to the
    valve's first motion) acted on from its ``available_at``, the end of its data + the latency. The run with the
    answer is the same as the one without it up to that instant, so the record up to the answer's data end is the
    one the answer read: one pass, no fixed point to seek (the answer cannot change the data it was made from).
    Without an answer the run on partial knowledge, refined in stage B, is the run."""
    waiting = dataclasses.replace(control, start=math.inf)
    result, history = run_until_stopped(scenario, context.rig, waiting, absorber, duration=context.duration,
                                        sample_rate=context.sample_rate, sigma=sigma, seed=seed)
    answer = answer_of(result, history)
    mass, velocity = usable_mass(answer), usable_velocity(answer)
    if answer.error is not None or not math.isfinite(mass) or answer.available_at >= result.time[-1]:
        return waiting, result, history
    known = dataclasses.replace(control, start=float(answer.available_at), mass=mass,
                                mass_std=answer.mass_std if not math.isnan(answer.mass_std) else math.inf,
                                mass_floor=mass_floor(answer),
                                velocity=velocity if math.isfinite(velocity) else control.early_velocity)
    return (known, *run_until_stopped(scenario, context.rig, known, absorber, duration=context.duration,
                                      sample_rate=context.sample_rate, sigma=sigma, seed=seed))


def _check(scenario, noise, seed, identification, absorber, control_start) -> None:
    if not isinstance(scenario, Scenario):
        raise ParameterError(f"scenario must be a Scenario, got {scenario!r}")
    check_real("noise", noise, low=0.0, high=1.0, unit=" (a fraction of each channel's RMS)")
    check_integer("seed", seed, low=0)
    if not isinstance(identification, str) or identification not in IDENTIFICATIONS:
        raise ParameterError(f"identification must be one of {list(IDENTIFICATIONS)}, got {shown(identification)}")
    if not isinstance(absorber, Absorber):
        raise ParameterError(f"absorber must be an Absorber, got {absorber!r}")
    if control_start is not None:
        check_real("control_start", control_start, low=0.0, unit=" [s] or None")


def absorb(scenario: Scenario, rig: Rig | str | None = None, *, strategy: str | list[str] = "all",
           identification: str = "model", noise: float = 0.02, seed: int = 0, absorber: Absorber | None = None,
           sample_rate: float = 50e3, duration: float | None = None, control_start: float | None = None,
           response_map=None, reference: bool = False, reference_evaluations: int = REFERENCE_EVALUATIONS,
           latency: float = LATENCY, early: bool = True) -> AbsorptionResult:
    """Absorb one impact with the closed loop identify → control.

    Parameters
    ----------
    scenario : Scenario
        The true impact: M1 [kg], V0 [m/s], p0 [Pa gauge].
    rig : Rig or str, optional
        The stand (default ``drop-stand-pad``, :data:`ABSORPTION_RIG`).
    strategy : str or list of str
        ``"closed"``, ``"constant"``, ``"realtime"``, ``"predictive"``, ``"auto"``, a list of them, or ``"all"``.
    identification : {"model", "robust", "paper", "oracle", "response-map"}
        How M1 and V0 are obtained from the noisy closed-valve record: the model fit of the stand as the record grows
        (its first answer with the mass known within 20 %, when its fit is done; the default), the peak-to-peak
        identification (its early answer when it has one), the true values (oracle), or a response map
        (``response_map=``).
    noise : float
        Sensor noise as a fraction of each channel's RMS [-] (identification record and controller sensors).
    seed : int
        Seed of every noise realisation.
    absorber : Absorber, optional
        Usable stroke, rated force and valve drive (default ``Absorber()``).
    sample_rate : float
        Sensor and controller rate [Hz].
    duration : float, optional
        Simulated time [s] (default :func:`default_duration`).
    control_start : float, optional
        Override of the time the identification's answer is known [s] (e.g. the oracle started when the
        identified loop starts). The oracle otherwise knows M1 and V0 from the start of the second contact pulse.
    response_map : ResponseMap or path, optional
        The map for ``identification="response-map"``.
    reference : bool
        Also search the achievable reference (:mod:`.reference`; a dozen simulations, plus
        ``reference_evaluations`` for its piecewise-constant programs).
    reference_evaluations : int
        Plant simulations of the piecewise-constant search of the reference (0: that family is skipped).
    latency : float
        The real-time system's latency budget [s]: an identification's answer is acted on this long after the last
        sample it used (default :data:`~.identified.LATENCY`, 1 ms: a compiled real-time core). Stated, not
        measured: the same arguments give the same numbers on any machine. Not used by the oracle, nor with
        ``control_start``.
    early : bool
        The policy. True (the default, ``early``): act on what is known as soon as it is known
        (:func:`early_knowledge`): the force strategies drive the valve
        from V0's answer (:func:`~.identified.contact_velocity`, ~0.5 ms of contact + ``latency``) with M1 taken
        from the prior over ``absorber.rated_masses`` and refined by the controller's stage-B estimate. The model
        identification reads the run's own record with the valve's opening as an input
        (:func:`~.identified.run_record`); the others, which fit the closed-valve stand, read only the record before
        the valve can have moved (a record read after it would bias them). False (``wait``): the valve stays closed
        until the identification's answer (or the controller's own stage-B estimate) gives M1.

    Returns
    -------
    AbsorptionResult
        ``.metrics`` by strategy, ``.reference``, ``.bound`` (η_max), ``.plot()``.
    """
    absorber = Absorber() if absorber is None else absorber
    _check(scenario, noise, seed, identification, absorber, control_start)
    check_flag("reference", reference)
    check_integer("reference_evaluations", reference_evaluations, low=0, high=10_000)
    check_real("latency", latency, low=0.0, high=0.1, unit=" [s]")
    check_flag("early", early)
    names = strategy_names(strategy)
    rig = get_rig(ABSORPTION_RIG if rig is None else rig)
    scenario.check_against(rig)
    usable = absorber.usable_stroke(rig)
    duration = default_duration(scenario, usable) if duration is None else duration
    closed, _ = plant.simulate_controlled(scenario, rig, drive=absorber.drive, duration=duration,
                                         sample_rate=sample_rate)
    found = _identified(scenario, rig, closed, identification, noise=noise, seed=seed, sample_rate=sample_rate,
                        control_start=control_start, response_map=response_map, latency=latency)
    required = impact_force(scenario.mass, scenario.velocity, usable, rig.gravity)
    over = required > absorber.rated_force
    notes = _notes(found, required, usable, absorber)
    start = found.available_at if found.error is None else math.inf
    known = {}
    if early and identification != "oracle":
        known = early_knowledge(scenario, rig, absorber, noise=noise, seed=seed, sample_rate=sample_rate,
                                latency=latency)
    sigma = sensor_sigma(closed, noise)
    window = common_window(closed, usable, vented=absorber.drive.route == "atmosphere")
    trusted_mass = usable_mass(found)
    context = ControlContext(rig=rig, absorber=absorber, mass=trusted_mass, velocity=usable_velocity(found),
                             mass_std=found.mass_std if math.isfinite(trusted_mass)
                             and not math.isnan(found.mass_std) else math.inf, mass_floor=mass_floor(found),
                             pressure_gauge=scenario.pressure_gauge, start=start, duration=duration,
                             sample_rate=sample_rate, pressure_lower_start=float(closed.pressure_lower[0]),
                             temperature_lower_start=rig.gas.temperature, force_noise=float(sigma[0]),
                             acceleration_noise=float(sigma[1]), **known)
    answer_of = None
    if known:
        closed_record = identification_record(scenario, rig, noise=noise, seed=seed, sample_rate=sample_rate) \
            if identification == "model" else None  # what the model's record of a run is made from

        def answer_of(run, history: dict[str, np.ndarray]) -> Identification:
            if closed_record is not None:  # the model: the valve's opening an input of the fit, the run's record
                return identify_impact(scenario, rig, method=identification, noise=noise, seed=seed,
                                       sample_rate=sample_rate, latency=latency, recording=run_record(
                                           closed_record, closed, run, history["valve_opening"]))
            # the others read the closed-valve stand: the record up to the valve's first motion (its first
            # command + the drive's dead time, which the controller knows)
            sent = np.flatnonzero(history["valve_command"] > 0.0)
            moved = float(run.time[sent[0]]) + absorber.drive.dead_time if sent.size else math.inf
            return identify_impact(scenario, rig, method=identification, noise=noise, seed=seed,
                                   sample_rate=sample_rate, response_map=response_map, latency=latency, until=moved)
    simulated = {name: _strategy_run(name, context, found, closed, scenario, absorber, sigma=sigma, seed=seed,
                                     answer_of=answer_of) for name in names}
    start = min([start] + [_knew(history, result) for control, result, history in simulated.values()
                           if control.strategy in ("realtime", "predictive")])
    runs = {name: StrategyRun(strategy=name, result=result, controller=history,
                              metrics=absorption_metrics(result, start, usable, window),
                              valve_opening_constant=control.opening if control.strategy == "constant" else math.nan,
                              answer_at=math.nan if control.strategy == "closed" else control.start)
            for name, (control, result, history) in simulated.items()}
    if math.isfinite(start) and start <= closed.time[-1]:
        bound = dataclasses.replace(efficiency_bound(closed, start, usable), first_collision_peak=first_collision_peak(
            scenario, rig, absorber.drive, start, sample_rate=sample_rate))
    else:
        bound = EfficiencyBound(level=math.nan, efficiency=math.nan, stroke=0.0, energy=0.0, over_capacity=False)
    achievable = None
    if reference:
        achievable = achievable_reference(scenario, rig, absorber, start, window=window,
                                          pressure_lower_start=float(closed.pressure_lower[0]), duration=duration,
                                          sample_rate=sample_rate, evaluations=reference_evaluations,
                                          partial_switch=found.available_at if found.error is None else math.inf)
    return AbsorptionResult(scenario=scenario, rig=rig, absorber=absorber, identified=found, runs=runs, bound=bound,
                            over_capacity=bool(over or bound.over_capacity), control_start=start,
                            reference=achievable, notes=tuple(notes), window=window)
