"""The closed loop: simulated sensors (with noise) → identification of M1 and V0 → a strategy that starts when
the identification becomes available; compared with an oracle that knows the true M1 and V0.

Until the control starts the valve is closed, so the identification reads a record of the closed-valve impact
(made by :func:`impactometer.sensors.record`, anti-alias filter and noise included). The controller's own
sensors (contact force, piston acceleration, chamber pressures) get white Gaussian noise of the same relative
level: ``noise`` × the RMS of each channel over the closed-valve record. Besides the force sensor, the
accelerometer and the chamber pressure sensors of the paper's Fig. 10, the absorber reads the piston displacement
(a displacement transducer on the rod): integrating the acceleration twice drifts by about 1 cm over the 0.4 s of
a controlled stroke at 2 % noise, as much as the whole stroke margin.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from ..errors import IdentificationError, ParameterError, shown
from ..identify.pulses import contact_pulses
from ..rig import Rig, Scenario, get_rig
from . import controller as ctl
from . import simulate as loop
from .bound import EfficiencyBound, efficiency_bound, first_collision_peak
from .metrics import AbsorptionMetrics, absorption_metrics
from .strategies import ControlContext, get_strategy, strategy_names
from .valve import Absorber

if TYPE_CHECKING:  # for annotations only: the map module is imported where it is used
    from ..identify.response_map import MapIdentification
    from ..identify.result import Identification

#: identification methods of the loop
IDENTIFICATIONS = ("robust", "paper", "oracle", "response-map")
#: length of the closed-valve record given to the identification [s], and the quiet record before first contact
#: [s] (a streaming DAQ has it; the identification takes the offsets and the noise level from its last ~1000
#: samples: with 2 ms instead of 25 ms it gave no estimate in 7 of the 125 grid impacts and 2.5× the mass error)
IDENTIFICATION_WINDOW = 0.1
PRE_TRIGGER = 0.025
#: samples per chunk pushed into the streaming identifier (a DAQ block)
STREAM_CHUNK = 16
#: channels whose noise the controller sees, in the order of the loop's sensor rows
SENSOR_CHANNELS = ("contact_force", "a2", "pressure_lower", "pressure_upper", "u2")


@dataclass(frozen=True, kw_only=True)
class StrategyRun:
    """One strategy applied to the impact: the histories, the controller's histories and the metrics."""

    strategy: str
    result: Any  # SimulationResult
    controller: dict[str, np.ndarray]
    metrics: AbsorptionMetrics
    valve_area_constant: float = math.nan


@dataclass(frozen=True, kw_only=True)
class Identified:
    """What the loop acted on: M1 [kg], V0 [m/s], when it was known [s], by which method (and why it failed)."""

    method: str
    mass: float
    velocity: float
    available_at: float
    error: str | None = None

    def to_dict(self) -> dict[str, Any]:
        def num(x):
            return None if x is None or not math.isfinite(x) else float(x)

        return {"method": self.method, "mass_kg": num(self.mass), "velocity_m_s": num(self.velocity),
                "available_at_s": num(self.available_at), "error": self.error}


@dataclass(frozen=True, kw_only=True)
class AbsorptionResult:
    """The impact absorbed with one or more strategies, the identification they used and the bound η_max."""

    scenario: Scenario
    rig: Rig
    absorber: Absorber
    identified: Identified
    runs: dict[str, StrategyRun]
    bound: EfficiencyBound
    over_capacity: bool
    notes: tuple[str, ...] = ()
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def metrics(self) -> dict[str, AbsorptionMetrics]:
        """Metrics by strategy name."""
        return {name: run.metrics for name, run in self.runs.items()}

    @property
    def control_start(self) -> float:
        """Time the strategies took over [s] (``inf`` when the identification failed)."""
        return self.identified.available_at if self.identified.error is None else math.inf

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready summary: scenario, identification, bound and per-strategy metrics (no histories)."""
        strategies = {}
        for name, run in self.runs.items():
            strategies[name] = {**run.metrics.to_dict(), "control_start_s": _num(self.control_start)}
            if math.isfinite(run.valve_area_constant):
                strategies[name]["valve_area_m2"] = run.valve_area_constant
        return {"mass_kg": self.scenario.mass, "velocity_m_s": self.scenario.velocity,
                "pressure_gauge_Pa": self.scenario.pressure_gauge, "identification": self.identified.to_dict(),
                "usable_stroke_m": self.absorber.usable_stroke(self.rig),
                "efficiency_max": _num(self.bound.efficiency), "bound_force_N": _num(self.bound.level),
                "first_collision_peak_N": _num(self.bound.first_collision_peak),
                "efficiency_first_collision": _num(self.bound.efficiency_first_collision),
                "over_capacity": self.over_capacity, "notes": list(self.notes), "strategies": strategies}

    def plot(self, ax=None):
        """The force histories of every strategy on one figure (the paper's Fig. 10b); see ``control.plots``."""
        from .plots import plot_absorption

        return plot_absorption(self, ax=ax)


def _num(x: float) -> float | None:
    return None if x is None or not math.isfinite(x) else float(x)


def default_duration(scenario: Scenario, usable_stroke: float) -> float:
    """Simulated time long enough for the slowest strategy to stop the mass [s]: 0.15 s + 4·usable stroke / V0,
    within [0.3, 1.2] s."""
    return float(min(1.2, max(0.3, 0.15 + 4.0 * usable_stroke / scenario.velocity)))


def identify_impact(scenario: Scenario, rig: Rig, *, method: str, noise: float, seed: int,
                    sample_rate: float, response_map=None) -> Identified:
    """Identify M1 and V0 from a noisy closed-valve record, as a real-time system would: the record streams
    through :class:`~impactometer.identify.streaming.StreamingIdentifier` and the first estimate (the early
    answer, at the end of the second contact pulse) is taken when it arrives. A response map is applied to the
    whole record and reports its own ``available_at``. A failed identification is returned with ``error`` set."""
    from ..sensors import record

    rec = record(scenario, rig, sample_rate=sample_rate, duration=IDENTIFICATION_WINDOW, noise=noise, seed=seed,
                 pre_trigger=PRE_TRIGGER)
    found: Identification | MapIdentification | None
    try:
        if method == "response-map":
            from ..identify.response_map import identify_recording

            if response_map is None:
                raise ParameterError("identification 'response-map' needs response_map= (a map or its file)")
            found = identify_recording(rec, response_map)
        else:
            from ..identify.streaming import StreamingIdentifier

            stream = StreamingIdentifier(rec.sample_rate, variant=method, gravity=rig.gravity,
                                         start_time=rec.start_time)
            found = None
            for k in range(0, rec.time.size, STREAM_CHUNK):
                estimates = stream.push(rec.contact_force[k:k + STREAM_CHUNK],
                                        rec.piston_acceleration[k:k + STREAM_CHUNK])
                if estimates:
                    found = estimates[0]
                    break
            if found is None:
                raise IdentificationError(f"no estimate within the first {IDENTIFICATION_WINDOW * 1e3:g} ms "
                                          "of the impact")
    except IdentificationError as exc:
        return Identified(method=method, mass=math.nan, velocity=math.nan, available_at=math.inf, error=str(exc))
    if not (found.mass > 0 and found.velocity > 0 and math.isfinite(found.available_at)):
        return Identified(method=method, mass=float(found.mass), velocity=float(found.velocity),
                          available_at=math.inf, error="identification gave no usable mass and velocity")
    return Identified(method=method, mass=float(found.mass), velocity=float(found.velocity),
                      available_at=max(float(found.available_at), 0.0))


def sensor_noise(closed_result, noise: float, seed: int) -> np.ndarray:
    """Noise matrix of the controller's sensors: ``noise`` × each channel's RMS over the closed-valve record."""
    t = closed_result.time
    window = t <= IDENTIFICATION_WINDOW
    rng = np.random.default_rng([int(seed), 7])
    rows = []
    for name in SENSOR_CHANNELS:
        x = getattr(closed_result, name)[window]
        rows.append(noise * float(np.sqrt(np.mean(x * x))) * rng.standard_normal(t.size))
    return np.array(rows)


def _check(scenario, noise, seed, identification, absorber, control_start) -> None:
    if not isinstance(scenario, Scenario):
        raise ParameterError(f"scenario must be a Scenario, got {scenario!r}")
    if isinstance(noise, bool) or not isinstance(noise, (int, float)) or not 0.0 <= noise <= 1.0:
        raise ParameterError(f"noise must be a fraction within [0, 1] of each channel's RMS, got {shown(noise)}")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ParameterError(f"seed must be an integer >= 0, got {shown(seed)}")
    if not isinstance(identification, str) or identification not in IDENTIFICATIONS:
        raise ParameterError(f"identification must be one of {list(IDENTIFICATIONS)}, got {shown(identification)}")
    if not isinstance(absorber, Absorber):
        raise ParameterError(f"absorber must be an Absorber, got {absorber!r}")
    if control_start is not None and (isinstance(control_start, bool) or not isinstance(control_start, (int, float))
                                      or not math.isfinite(control_start) or control_start < 0):
        raise ParameterError(f"control_start must be a finite time >= 0 [s] or None, got {shown(control_start)}")


def absorb(scenario: Scenario, rig: Rig | str | None = None, *, strategy: str | list[str] = "all",
           identification: str = "robust", noise: float = 0.02, seed: int = 0, absorber: Absorber | None = None,
           sample_rate: float = 50e3, duration: float | None = None, control_start: float | None = None,
           response_map=None) -> AbsorptionResult:
    """Absorb one impact with the closed loop identify → control.

    Parameters
    ----------
    scenario : Scenario
        The true impact: M1 [kg], V0 [m/s], p0 [Pa gauge].
    rig : Rig or str, optional
        The stand (default ``drop-stand``).
    strategy : str or list of str
        ``"closed"``, ``"constant"``, ``"realtime"``, a list of them, or ``"all"``.
    identification : {"robust", "paper", "oracle", "response-map"}
        How M1 and V0 are obtained: peak-to-peak identification on the noisy closed-valve record (its early
        answer when it has one), the true values (oracle), or a response map (``response_map=``).
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
        Override of the time the control starts [s] (e.g. the oracle started when the identified loop starts).
        The oracle otherwise starts at the end of the second contact pulse, when the early identification can
        first be ready.
    response_map : ResponseMap or path, optional
        The map for ``identification="response-map"``.

    Returns
    -------
    AbsorptionResult
        ``.metrics`` by strategy, ``.bound`` (η_max), ``.plot()``.
    """
    absorber = Absorber() if absorber is None else absorber
    _check(scenario, noise, seed, identification, absorber, control_start)
    names = strategy_names(strategy)
    rig = get_rig(rig)
    scenario.check_against(rig)
    usable = absorber.usable_stroke(rig)
    duration = default_duration(scenario, usable) if duration is None else duration
    closed, _ = loop.simulate_controlled(scenario, rig, drive=absorber.drive, duration=duration,
                                         sample_rate=sample_rate)
    if identification == "oracle":
        pulses = contact_pulses(closed.time, closed.contact_force)
        start = pulses[1].end if len(pulses) > 1 else (pulses[0].end if pulses else 0.0)
        found = Identified(method="oracle", mass=scenario.mass, velocity=scenario.velocity, available_at=start)
    else:
        found = identify_impact(scenario, rig, method=identification, noise=noise, seed=seed,
                                sample_rate=sample_rate, response_map=response_map)
    if control_start is not None and found.error is None:
        found = Identified(method=found.method, mass=found.mass, velocity=found.velocity,
                           available_at=float(control_start))
    notes = []
    if found.error is not None:
        notes.append(f"identification failed ({found.error}); the valve stays closed")
    required = (0.5 * scenario.mass * scenario.velocity ** 2 + scenario.mass * rig.gravity * usable) / usable
    over = required > absorber.rated_force
    if over:
        notes.append(f"impact energy needs a constant force of {required:.0f} N over the usable stroke "
                     f"({usable:.3f} m), above the rated {absorber.rated_force:.0f} N: the best achievable outcome "
                     f"is shown")
    start = found.available_at if found.error is None else math.inf
    if math.isfinite(start) and start <= closed.time[-1]:
        bound = dataclasses.replace(efficiency_bound(closed, start, usable), first_collision_peak=first_collision_peak(
            scenario, rig, absorber.drive, start, sample_rate=sample_rate))
    else:
        bound = EfficiencyBound(level=math.nan, efficiency=math.nan, stroke=0.0, energy=0.0, over_capacity=False)
    context = ControlContext(rig=rig, absorber=absorber, mass=found.mass if found.error is None else scenario.mass,
                             velocity=found.velocity if found.error is None else scenario.velocity,
                             pressure_gauge=scenario.pressure_gauge, start=start, duration=duration,
                             sample_rate=sample_rate, charge_pressure=float(closed.pressure_lower[0]),
                             charge_temperature=rig.gas.temperature)
    noise_matrix = sensor_noise(closed, noise, seed)
    runs = {}
    for name in names:
        control = get_strategy(name)(context) if found.error is None else context.base(ctl.CLOSED)
        if control[ctl.STRATEGY] == ctl.CLOSED:
            result = closed
            history = {key: np.zeros_like(closed.time) for key in loop.EXTRA}
        else:
            result, history = loop.simulate_controlled(scenario, rig, control=control, drive=absorber.drive,
                                                       duration=duration, sample_rate=sample_rate,
                                                       sensor_noise=noise_matrix)
        area = float(control[ctl.AREA_CONSTANT]) if control[ctl.STRATEGY] == ctl.CONSTANT else math.nan
        runs[name] = StrategyRun(strategy=name, result=result, controller=history,
                                 metrics=absorption_metrics(result, start), valve_area_constant=area)
    return AbsorptionResult(scenario=scenario, rig=rig, absorber=absorber, identified=found, runs=runs, bound=bound,
                            over_capacity=bool(over or bound.over_capacity), notes=tuple(notes))

