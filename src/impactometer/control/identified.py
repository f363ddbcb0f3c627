"""M1 and V0 as the closed loop gets them: the model fit or the streaming identification of the noisy closed-valve
record (or a response map, or the oracle), and what the controller may trust of it.

Until the control starts the valve is closed, so the identification reads a record of the closed-valve impact (made
by :func:`impactometer.sensors.record`, anti-alias filter and noise included). A controller that drives the valve
before its answer gives the model stream the record of its own run with the valve's opening as an input
(:func:`run_record`).
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import replace
from typing import Any

import numpy as np

from ..errors import IdentificationError, ParameterError, ResponseMapError
from ..identify.details import ModelDetails
from ..identify.peak_to_peak.streaming import StreamingIdentifier
from ..identify.response_map import identify_recording
from ..identify.result import Identification
from ..recording import ACCELERATION, FORCE, VALVE_OPENING, Recording
from ..rig import Rig, Scenario
from ..sensors import record
from ..signals.noise import quiet_noise_std
from ..validation import finite_or_none, renamed
from .estimator import MASS_TRUST

#: length of the closed-valve record given to the identification [s], and the quiet record before first contact
#: [s] (a streaming DAQ has it; the identification takes the offsets and the noise level from its last ~1000
#: samples: a 2 ms one leaves 7 of the 125 grid impacts without an estimate and gives 2.5× the mass error)
IDENTIFICATION_WINDOW = 0.1
PRE_TRIGGER = 0.025
#: samples per chunk pushed into the streaming identifier (a DAQ block)
STREAM_CHUNK = 16
#: the first model answer whose mass has a standard error below this fraction of it is acted on [-]
MODEL_MASS_TRUST = 0.2
#: the model stream's first window, its cadence and the longest record after first contact it reads for the
#: loop [s]
MODEL_FIRST, MODEL_CADENCE, MODEL_LAST = 0.003, 0.001, 0.015
#: the loop's default latency budget [s]: from the last sample an answer used to the valve command that acts on it.
#: It is what a compiled real-time core (the stream's whole update as compiled code on one core, fed by the DAQ block
#: by block) must meet: the DAQ block (:data:`STREAM_CHUNK` samples, 0.32 ms at 50 kHz), one update and the valve
#: driver's command within 1 ms. A requirement of the real-time system: this implementation's processor time per push
#: (a median just under 1 ms for an update on one core here, about 3 ms for the first answer's) is measured by
#: ``benchmarks/bench_loop_latency.py``, never counted in a simulation (it depends on the machine and its load, and
#: the same arguments must give the same numbers).
LATENCY = 1e-3
#: record after the contact is detected from which V0 is taken [s] (:func:`contact_velocity`): within the first
#: rise of the contact force on the stands built in (its quarter period is 1.5-3 ms), long enough for a standard
#: error of a few per cent at 2 % noise
VELOCITY_WINDOW = 5e-4
#: the controller trusts an identified velocity whose standard error is below this fraction of it [-] (and a mass
#: by the estimator's ``MASS_TRUST``)
VELOCITY_TRUST = 0.5


#: floor of the relative standard error of an answer's mass where the controller's stage-B estimate refines it [-],
#: the error each identification is validated to (its stated σ is taken where larger). The model fit of the stand:
#: its stated σ is calibrated (truth within ±2σ in 93-96 % of 625 records per contact law at 5 % noise, efficiency
#: 0.83-0.96 of the Cramér-Rao bound, ``results/accuracy_model``; the stream's first answers 19-20 of 20,
#: docs/model_identification.md), and its largest mass error there is 2.0-2.9 %: 1 % keeps that tail within the 3σ
#: of the consistency test without widening a stated σ of 1 % or more.
MODEL_MASS_FLOOR = 0.01
#: the peak-to-peak early answer (and every other identification): its ±2σ coverage is 92-97 % at 5 % noise, but
#: its largest mass errors are 21-46 % on the pad and stiff stands (143 % with the hysteretic contact,
#: ``results/accuracy_peak_to_peak``): it rests on a few contact pulses, and on a stand that reaches stage B early
#: its error is often larger than stated (an answer of 5 kg for a 40 kg mass happens)
ROBUST_MASS_FLOOR = 0.25


def mass_floor(found: Identification) -> float:
    """The floor of the relative standard error of ``found``'s mass the controller takes [-] (``mass_floor`` of
    :class:`.settings.ControlSettings`): :data:`MODEL_MASS_FLOOR` for the model fit's own answer (``model/ml``),
    0 for the oracle (known exactly), :data:`ROBUST_MASS_FLOOR` for the others (a model answer that fell back to
    the peak-to-peak one included)."""
    if found.family == "oracle":
        return 0.0
    return MODEL_MASS_FLOOR if found.method == "model/ml" else ROBUST_MASS_FLOOR


def usable_mass(found: Identification) -> float:
    """The mass the controller takes [kg]: the identified mass if finite, positive and with a standard error below
    ``MASS_TRUST`` of it, else NaN (the controller then waits for its stage-B estimate)."""
    ok = math.isfinite(found.mass) and found.mass > 0.0 and not found.mass_std >= MASS_TRUST * found.mass
    return found.mass if ok else math.nan


def usable_velocity(found: Identification) -> float:
    """The velocity the controller takes [m/s]: the identified velocity if finite, positive and with a standard
    error below ``VELOCITY_TRUST`` of it, else NaN."""
    ok = math.isfinite(found.velocity) and found.velocity > 0.0 \
        and not found.velocity_std >= VELOCITY_TRUST * found.velocity
    return found.velocity if ok else math.nan


def loop_method(found: Identification) -> str:
    """The loop's name of the identification (its ``identification`` option): the peak-to-peak variant
    (``robust``, ``paper``) or the method's family (``response-map``, ``oracle``)."""
    return found.variant if found.family == "peak-to-peak" else found.family


def loop_summary(found: Identification) -> dict[str, Any]:
    """JSON-ready summary of what the loop acted on: ``method`` (:func:`loop_method`), ``mass_kg``,
    ``velocity_m_s``, their standard errors, ``available_at_s`` (None when unknown) and ``error``."""
    return {"method": loop_method(found), "mass_kg": finite_or_none(found.mass),
            "velocity_m_s": finite_or_none(found.velocity), "mass_std_kg": finite_or_none(found.mass_std),
            "velocity_std_m_s": finite_or_none(found.velocity_std),
            "available_at_s": finite_or_none(found.available_at), "error": found.error}


def identify_impact(scenario: Scenario, rig: Rig, *, method: str, noise: float, seed: int,
                    sample_rate: float, response_map=None, latency: float = LATENCY,
                    until: float = math.inf, recording: Recording | None = None) -> Identification:
    """Identify M1 and V0 from a noisy closed-valve record, as a real-time system would.

    ``model``: the stand's model is fitted to the record as it grows (:func:`first_model_answer`); the first answer
    the controller can act on is taken. ``robust``/``paper``: the record streams through
    :class:`~impactometer.identify.peak_to_peak.streaming.StreamingIdentifier` and the first estimate (the early
    answer, at the end of the second contact pulse) is taken. A response map is applied to the whole record and
    reports the end of the data it read. Whichever method, the answer is known ``latency`` after the last sample it
    used: a stated budget of the real-time system, not this machine's processor time, so the same arguments give
    the same answer on any machine under any load.

    Parameters
    ----------
    scenario, rig : Scenario, Rig
        The impact and the stand.
    method : {"model", "robust", "paper", "response-map"}
        The loop's identification.
    noise : float
        Relative sensor noise [-].
    seed : int
        Seed of the noise.
    sample_rate : float
        [Hz].
    response_map : ResponseMap or path, optional
        The map for ``method="response-map"``.
    latency : float
        From the last sample the answer used to the answer's use [s] (default :data:`LATENCY`).
    until : float
        The record ends here [s] (default: :data:`IDENTIFICATION_WINDOW` after first contact): a valve that
        moves then makes the later record one the closed-valve models do not describe.
    recording : Recording, optional
        The record to identify (default :func:`identification_record`, the closed-valve impact); one with a
        ``valve_opening`` channel (:func:`run_record`) is read by the model with the valve as an input.

    Returns
    -------
    Identification
        ``available_at`` [s]: the end of its data (not before first contact, t = 0) + ``latency``; ``details`` add
        ``data_until_s`` and ``latency_s``. A failed identification has NaN mass and velocity, ``available_at`` inf
        and ``error`` set.
    """
    rec = identification_record(scenario, rig, noise=noise, seed=seed, sample_rate=sample_rate) \
        if recording is None else recording
    cut = until < rec.time[-1]
    if cut:
        kept = rec.time <= until
        rec = replace(rec, channels={key: values[kept] for key, values in rec.channels.items()})
    name = {"response-map": "response-map/fast", "model": "model/early"}.get(method, f"peak-to-peak/{method}")
    found: Identification | None
    try:
        if method == "model":
            found = first_model_answer(rec, rig, pressure_gauge=scenario.pressure_gauge, latency=latency)
        elif method == "response-map":
            if response_map is None:
                raise ParameterError("identification 'response-map' needs response_map= (a map or its file)")
            try:
                found = identify_recording(rec, response_map)
            except ResponseMapError as exc:
                if not cut:
                    raise
                # a record cut where the valve first moved can be shorter than the map's feature window
                raise IdentificationError(f"the record up to {until * 1e3:.3g} ms: {exc}") from exc
        else:
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
                raise IdentificationError(f"no estimate within the first {min(until, IDENTIFICATION_WINDOW) * 1e3:g}"
                                          " ms of the impact")
    except IdentificationError as exc:
        return Identification(method=name, mass=math.nan, velocity=math.nan, available_at=math.inf, error=str(exc))
    if not math.isfinite(found.available_at):
        return replace(found, available_at=math.inf, error="identification gave no time of availability")
    data_until = max(float(found.available_at), 0.0)
    return replace(found, available_at=data_until + latency,
                   details={**found.details, "data_until_s": data_until, "latency_s": latency})


def identification_record(scenario: Scenario, rig: Rig, *, noise: float, seed: int,
                           sample_rate: float) -> Recording:
    """The noisy closed-valve record the identification reads (:data:`IDENTIFICATION_WINDOW` after first contact,
    :data:`PRE_TRIGGER` before it)."""
    return record(scenario, rig, sample_rate=sample_rate, duration=IDENTIFICATION_WINDOW, noise=noise, seed=seed,
                  pre_trigger=PRE_TRIGGER)


def run_record(closed_record: Recording, closed, run, opening: np.ndarray) -> Recording:
    """The noisy record of a run whose valve moved, with valve Z's opening as a channel: the closed-valve record
    ``closed_record`` (:func:`identification_record`) plus the run's change of the clean contact force and piston
    acceleration (``run`` − ``closed``, the controlled and the closed-valve simulations on one sample grid from first
    contact), delayed by the record's anti-alias delay (the change is slow against the filter: the valve's lag is
    milliseconds), and ``valve_opening`` [-], the run's opening ``opening`` at each of its samples (zero before
    first contact and after the run). The same noise draw as the closed-valve record: where the valve stays
    closed the record is that one, bit for bit."""
    n = min(closed.time.size, run.time.size)
    at = closed_record.time - float(closed_record.metadata.get("anti_alias_delay_s", 0.0))
    channels = dict(closed_record.channels)
    for name, model in ((FORCE, "contact_force"), (ACCELERATION, "a2")):
        change = getattr(run, model)[:n] - getattr(closed, model)[:n]
        channels[name] = channels[name] + np.interp(at, closed.time[:n], change, left=0.0, right=0.0)
    t = closed_record.time
    index = np.rint(t * closed_record.sample_rate).astype(int)
    inside = (index >= 0) & (index < n)
    channels[VALVE_OPENING] = np.where(inside, np.clip(np.asarray(opening, float)[np.clip(index, 0, n - 1)],
                                                       0.0, 1.0), 0.0)
    return replace(closed_record, channels=channels)


def contact_velocity(recording: Recording, rig: Rig, *, window: float = VELOCITY_WINDOW,
                     latency: float = LATENCY) -> Identification:
    """V0 from the first samples of the contact: the rise of the pad's compression.

    On its first loading the pad's compression is δ = F/k (hysteretic and Kelvin-Voigt laws without damping:
    F/k; Hunt-Crossley: (F/k)^(2/3)), and over the first fraction of a millisecond the mass has lost a negligible
    part of its velocity (∫∫Fc/M1 dt² is below 0.5 % of V0·t after 0.5 ms for M1 >= 10 kg on the stands built in),
    so δ + u2 = V0·(t − t0), u2 the piston's displacement integrated twice from its accelerometer. A straight line
    fitted to the samples from the contact's detection (:data:`~impactometer.signals.pulses.DETECT_SIGMAS` noise
    levels for :data:`~impactometer.signals.pulses.HOLD` samples) to ``window`` [s] later gives V0 as its slope and
    its standard error from the residuals. The offsets and the force's noise come from the record before the
    contact. Whatever the valve does later, these samples come before it can act (the answer is known at their end
    + ``latency``, and the valve's dead time follows).

    Returns
    -------
    Identification
        ``velocity`` and ``velocity_std`` [m/s], ``available_at`` the end of the data + ``latency`` [s], mass NaN;
        ``error`` set (velocity NaN, ``available_at`` inf) where no contact is detected or the window has fewer
        than 4 samples.
    """
    from ..signals.pulses import DETECT_SIGMAS, HOLD

    t = recording.time
    quiet = t < -0.001
    force = recording.contact_force - (float(np.mean(recording.contact_force[quiet])) if quiet.any() else 0.0)
    sigma = _force_noise(recording)
    above = force > DETECT_SIGMAS * max(sigma, 1e-9)
    held = np.convolve(above.astype(int), np.ones(HOLD, int), mode="valid") == HOLD
    failed = Identification(method="contact-velocity", mass=math.nan, velocity=math.nan, available_at=math.inf,
                            error="no contact detected in the record")
    if not held.any():
        return failed
    first = int(np.argmax(held))
    take = (t >= t[first]) & (t <= t[first] + window)
    if take.sum() < 4:
        return replace(failed, error=f"fewer than 4 samples within {window * 1e3:g} ms of the contact")
    acceleration = recording.piston_acceleration - (float(np.mean(recording.piston_acceleration[quiet]))
                                                    if quiet.any() else 0.0)
    dt = 1.0 / recording.sample_rate
    after = np.where(t >= t[first] - HOLD * dt, acceleration, 0.0)  # the piston rests until the contact
    velocity2 = np.cumsum(after) * dt
    displacement2 = np.cumsum(velocity2) * dt
    stiffness = float(rig.contact.stiffness)
    ratio = np.clip(force[take], 0.0, None) / stiffness
    compression = ratio ** (2.0 / 3.0) if rig.contact.law == "hunt-crossley" else ratio
    x, y = t[take], compression + displacement2[take]
    slope, intercept = np.polyfit(x, y, 1)
    residual = y - (slope * x + intercept)
    std = float(np.sqrt(np.sum(residual ** 2) / (x.size - 2) / np.sum((x - x.mean()) ** 2)))
    until = float(x[-1])
    return Identification(method="contact-velocity", mass=math.nan, velocity=float(slope), velocity_std=std,
                          available_at=max(until, 0.0) + latency,
                          details={"data_until_s": until, "latency_s": latency, "samples": int(x.size)})


@renamed(pressure="pressure_gauge")
def first_model_answer(recording: Recording, rig: Rig, *, pressure_gauge: float,
                       latency: float = LATENCY) -> Identification:
    """The first answer of the model stream that the controller can act on (:func:`model_answers`); its
    ``available_at`` [s] is the end of the data it used (add the latency for the instant it is acted on)."""
    answers = [found for _, _, found in model_answers(recording, rig, pressure_gauge=pressure_gauge, latency=latency)
               if found is not None]  # the stream ends after its answer
    if answers:
        return answers[0]
    raise IdentificationError(f"no model answer with a mass known within {MODEL_MASS_TRUST:.0%} within "
                              f"{MODEL_LAST * 1e3:g} ms of first contact")


def _force_noise(recording: Recording) -> float:
    """Standard deviation of the force before first contact (t = 0, less 1 ms) [N]; 0 without such samples."""
    quiet = recording.contact_force[recording.time < -0.001]
    return float(quiet_noise_std(quiet)) if quiet.size > 1 else 0.0


def _turned(recording: Recording, until: float, noise: float, time: np.ndarray | None = None) -> bool:
    """Whether the force of the first contact pulse has turned over in the record up to ``until`` [s]: its
    maximum since first contact (t = 0) stands :data:`~impactometer.signals.extrema.TURN_SIGMAS`
    noise levels ``noise`` [N] above the force at ``until``. Before its turn the first pulse's rise depends on M1
    hardly at all (on a soft pad a fit of it can put a 30 kg mass at 3 kg with a small stated σ). ``time``: the
    record's ``time`` where the caller has it made."""
    from ..signals.extrema import TURN_SIGMAS

    t = recording.time if time is None else time
    # the samples from t = 0 to ``until``: a slice of the increasing instants (the mask of both bounds, read off)
    seen = recording.contact_force[np.searchsorted(t, 0.0, "left"):np.searchsorted(t, until, "right")]
    return seen.size > 0 and float(seen.max() - seen[-1]) > TURN_SIGMAS * noise


def _stage(found: Identification) -> str | None:
    """The model stream's stage of ``found`` (``first``, ``update``, ``final``), read off its typed details (their
    mapping form builds every detail's dict)."""
    details = found.details
    if isinstance(details, ModelDetails):
        return None if details.stream is None else details.stream.stage
    return details.get("stage")


@renamed(pressure="pressure_gauge")
def model_answers(recording: Recording, rig: Rig, *, pressure_gauge: float,
                  latency: float = LATENCY) -> Iterator[tuple[float, int, Identification | None]]:
    """The loop's model stream, push by push, as a real-time system with a latency budget gets it.

    The record streams through :class:`~impactometer.identify.model_fit.streaming.ModelStream` (the stand's own
    contact law and parameters known: a calibrated stand; first window :data:`MODEL_FIRST`, an update every
    :data:`MODEL_CADENCE`) in chunks of :data:`STREAM_CHUNK` samples, each pushed once its last sample has arrived.
    An update whose data end at t is done at t + ``latency`` [s], and the next update reads the record up to at
    least then (the core is busy with one update at a time). The first estimate whose mass has a standard error
    below :data:`MODEL_MASS_TRUST` of it and that read the record past the first force peak (:func:`_turned`) is
    the answer; none comes after :data:`MODEL_LAST` of record after first contact.

    Yields
    ------
    (float, int, Identification or None)
        For each push: the time its last sample arrived [s], the stream's updates it made, and the answer when this
        push gave it (``available_at`` the end of its data [s]); the iteration ends after the answer. Generated
        lazily, so that a benchmark can time each push of the stream the loop runs.
    """
    import numba

    from ..identify.model_fit.streaming import ModelStream

    stream = ModelStream(recording.sample_rate, start_time=recording.start_time, metadata=recording.metadata,
                         rig=rig, pressure_gauge=pressure_gauge, contact=rig.contact.law, cadence=MODEL_CADENCE,
                         first=MODEL_FIRST, window=MODEL_LAST,  # its grid of starts is made here, before the impact
                         robust_starts=False)  # no robust estimate comes before the first window's end
    force, acceleration, time = recording.contact_force, recording.piston_acceleration, recording.time
    opening = recording.channels.get(VALVE_OPENING)  # valve Z's opening [-], an input of the fit where given
    noise = _force_noise(recording)
    threads = numba.get_num_threads()
    numba.set_num_threads(1)  # one core, as on the real-time system: the same numbers whatever the machine's cores
    try:
        for k in range(0, force.size, STREAM_CHUNK):
            if recording.start_time + k / recording.sample_rate > MODEL_LAST:
                return  # t = 0 is first contact
            chunk = slice(k, min(k + STREAM_CHUNK, force.size))
            arrived = float(time[chunk.stop - 1])  # a chunk is pushed once its last sample is in
            answer, updates = None, 0
            for found in stream.push(force[chunk], acceleration[chunk], None if opening is None else opening[chunk]):
                if _stage(found) == "final":
                    break  # the batch fit of MODEL_LAST: too late for the controller
                updates += 1
                stream.defer(found.available_at + latency)  # the next update reads what has arrived by then
                if found.method == "model/ml" and found.mass_std < MODEL_MASS_TRUST * found.mass \
                        and _turned(recording, found.available_at, noise, time):
                    answer = found
                    break
            yield arrived, updates, answer
            if answer is not None:
                return
    finally:
        numba.set_num_threads(threads)
