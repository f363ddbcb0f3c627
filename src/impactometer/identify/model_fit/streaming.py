"""Streaming model-based identification: the model's answer from the first milliseconds of an impact, updated at a
stated cadence, and the batch fit of the record as the final answer.

The robust :class:`~impactometer.identify.peak_to_peak.streaming.StreamingIdentifier` runs on every sample: its
trigger finds the impact and its ring buffer holds the samples. The model reads them (:mod:`.growing` holds the
algorithms, this class the schedule):

- **First answer** as soon as ``first`` (default ``STAGES[0]``, 4 ms) of record after first contact has arrived:
  M1, V0 and the contact instant fitted with the stand's law and parameters held, from the robust answer where
  the stream has one by then, else from the best impacts of the start grid (:func:`.select._grid_starts`, whose
  predictions are made before the impact). It is given where it explains the samples after contact down to
  their noise.
- **Contact law**: the other laws are fitted on that first window, one at each update, and screened as the batch
  fit screens them (:func:`.select._screen`: dropped where their BIC exceeds a best law that explains the window by
  more than 1000); where the stand's law does not explain the first window, at once. Where more than one law is
  left, each is updated up to ``STAGES[SCREEN_WINDOW]`` (15 ms), where the smallest BIC chooses. The choice is
  kept; the final answer revisits it (the batch fit compares every law again).
- **Updates** every ``cadence`` of record after the first answer: the fit of the record so far, warm-started from
  the last update's optimum, by one Levenberg-Marquardt step of the engine's solver (:func:`.engine.solve`: one
  Jacobian, one or two residuals); a few more where it leaves χ²/dof above 1.1. Before 15 ms the stand is held;
  from it on every unknown of the batch fit is free.
- **Final answer** once ``window`` (50 ms) of record after first contact has arrived, or at ``finish()``:
  :func:`~impactometer.identify.model_fit.identify` of the buffered samples, the batch answer of the same samples.

Standard errors: the inverse Fisher information at the update, inflated by sqrt(χ²/dof) above 1. Before 15 ms the
stand's parameters are held at the rig's values, and so is the σ: it is the σ of a stand known as the rig states
it (``sigma_given`` in the details says so); the first pulses alone cannot tell M1 from the contact's parameters.
"""

from __future__ import annotations

import contextlib
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from ...errors import IdentificationError, ParameterError, ParameterTypeError, shown
from ...recording import VALVE_OPENING, Recording, check_sample_rate
from ...rig import STAND_KEY, Rig, get_rig
from ...sensors import anti_alias_delay
from ...validation import check_real, renamed
from .. import model_fit as batch
from ..details import ModelDetails, StreamStage
from ..peak_to_peak.streaming import StreamingIdentifier, check_open, last_outcome
from ..result import Identification
from .engine import (
    CHANNELS,
    LEAD_SAMPLES,
    LawFit,
    Observed,
    anti_alias_design,
    check_length,
    contact_laws,
    observe,
    window,
)
from .first_window import _warm
from .forward import _check_uncertain, _make_grid
from .growing import _explained, _first_fit, _Growing, _update
from .select import SCREEN_WINDOW, STAGES, _grid_predictions, _grid_starts, _Start

#: default time between updates [s] of record: an update of the record up to 50 ms after contact took a median
#: 4.7 ms on one core of the (loaded) development machine, the first answer 3 ms (docs/model_identification.md)
CADENCE = 0.01
#: default record after first contact whose batch fit is the final answer [s]
WINDOW = 0.05
#: most pre-trigger the model reads [s] (the noise σ and the offsets come from it)
PRE_TRIGGER = 0.02
#: shortest first window [s]: the first contact pulse's rise alone (V0, not M1)
MIN_FIRST = 0.002
#: starts of the grid tried in turn for the first answer, where the robust stream has none yet
GRID_STARTS = 3


def check_schedule(cadence: float = CADENCE, first: float = STAGES[0][0], window: float = WINDOW, *,
                   sample_rate: float | None = None) -> tuple[float, float, float]:
    """``cadence``, ``first`` and ``window`` [s] of a :class:`ModelStream` as floats, or ParameterError naming the
    one out of range: the cadence at least a sample period (> 0 where ``sample_rate`` [Hz] is not known yet),
    ``first`` from ``MIN_FIRST`` to the screening window, ``window`` at least ``first`` plus one cadence."""
    cadence = check_real("cadence", cadence, low=0.0 if sample_rate is None else 1.0 / sample_rate,
                         low_open=sample_rate is None, unit=" [s]", error=ParameterError)
    first = check_real("first", first, low=MIN_FIRST, high=STAGES[SCREEN_WINDOW][0], unit=" [s]",
                       error=ParameterError)
    window = check_real("window", window, low=first + cadence, unit=" [s]", error=ParameterError)
    return cadence, first, window


@dataclass
class _Impact:
    """The running impact: its trigger and first buffered sample (stream indices), the contact instant the fit
    counts from [s], the next update's last sample (exclusive) and the fit of its growing record."""

    trigger: int
    first: int
    contact_time: float
    next_stop: int
    fit: _Growing
    done: bool = False
    checked: bool = False
    #: the pre-trigger's noise σ and median, the same for every update (:func:`.engine.observe`)
    quiet: dict = field(default_factory=dict)


class ModelStream:
    """Model-based identification of impacts from a stream of contact force [N] and piston acceleration [m/s²].

    Parameters
    ----------
    sample_rate : float
        Sample rate [Hz].
    start_time : float
        Time of the first sample pushed [s].
    metadata : dict, optional
        The recording's metadata (``anti_alias``, ``pressure_gauge_Pa``), as :func:`.identify` reads it.
    rig, pressure_gauge, pressure_gauge_std, uncertain, contact
        As in :func:`.identify`.
    cadence : float
        Record between updates [s].
    window : float
        Record after first contact whose batch fit is the final answer [s].
    first : float
        Record after first contact the first answer reads [s] (default the batch fit's first window, 4 ms; from
        ``MIN_FIRST`` to 15 ms): earlier answers, larger σ of M1.
    robust_starts : bool
        False: the robust stream only triggers and buffers the samples (its estimates are neither starts of the
        first fit nor fall-backs), which spares the thread its work at every pulse's end (about half a
        millisecond): the real-time loop's choice, whose first window ends before any robust estimate.

    Notes
    -----
    ``push`` returns the new estimates, each an :class:`Identification` (``model/ml``; ``model/fallback`` where the
    model leaves χ²/dof above ``MAX_REDUCED_CHI2`` and the robust stream has an answer) whose ``available_at`` is
    the time of the last sample it used and whose details give ``stage`` (``first``, ``update``, ``final``),
    ``update_time_s`` (the wall time the update took), ``cadence_s`` and ``window_ms``. ``estimates`` keeps those
    of the current impact, ``outcomes`` the final answer or refusal of every impact, ``last_record`` the samples the
    last final answer read (a :class:`Recording`), ``update_times`` the wall time of every estimate [s] and
    ``notes`` why an update of the last impact gave no estimate.
    """

    @renamed(pressure="pressure_gauge", pressure_std="pressure_gauge_std")
    def __init__(self, sample_rate: float, *, start_time: float = 0.0, metadata: dict | None = None,
                 rig: Rig | str | None = None, pressure_gauge: float | None = None,
                 pressure_gauge_std: float | None = None,
                 uncertain: Sequence[str] | None = None,
                 contact: str | None = "auto", cadence: float = CADENCE, window: float = WINDOW,
                 first: float = STAGES[0][0], robust_starts: bool = True):
        sample_rate = check_sample_rate(sample_rate, error=ParameterError)
        self.cadence, self.first, self.window = check_schedule(cadence, first, window, sample_rate=sample_rate)
        self.robust = StreamingIdentifier(sample_rate, start_time=start_time, estimates=robust_starts)
        #: valve Z's opening [-] of the samples in the robust stream's ring buffer, by the same stream index
        self._opening = np.zeros(self.robust.capacity)
        #: whether an opening above zero was ever pushed (until then the buffer's openings are all zero)
        self._opened = False
        self.sample_rate, self.start_time = float(sample_rate), float(start_time)
        self.rig = get_rig(rig)
        # the stream screens one law per update from its first window on: the power law (six contact parameters)
        # is a candidate where the stand's pad is one or where it is the law named; the batch fit tries it always
        laws = contact_laws(contact)
        self.laws = laws if len(laws) == 1 else tuple(law for law in laws
                                                      if law != "power" or self.rig.contact.law == "power")
        self.uncertain, self.contact = _check_uncertain(uncertain, self.laws), contact
        if metadata is not None and not isinstance(metadata, dict):
            raise ParameterTypeError(f"metadata must be None or a dict (the recording's metadata), got "
                                     f"{shown(metadata)}", field="metadata", expected="must be None or a dict")
        self.metadata = dict(metadata or {})
        self._pressure_gauge_start = self.metadata.get("pressure_gauge_Pa") or batch.DEFAULT_PRESSURE_GAUGE_START
        probe = self._recording(np.zeros((2, 1)), 0)
        #: the warning of a stand other than the recording's, stated once: the updates' records leave it out (its
        #: fingerprint of the stand cost a sixth of a millisecond an answer)
        self._stand_notes = batch._stand_warning(probe, self.rig)
        self._update_metadata = {k: v for k, v in self.metadata.items() if k != STAND_KEY}
        self.design = anti_alias_design(probe)
        self.pressure_gauge, self.pressure_gauge_std = batch._pressure(probe, pressure_gauge, self.rig,
                                                                       pressure_gauge_std)
        self._given_pressure = pressure_gauge, pressure_gauge_std  # the final batch fit combines them with the metadata
        self.delay = anti_alias_delay(self.design, sample_rate)
        self._grid_model = _make_grid(self.start_time, sample_rate, 1, self.design)
        self._chunk = max(int(self.cadence * sample_rate), 1)
        clock = time.perf_counter()
        _warm()  # the compiled fits, before any impact
        self._grid = self._arm()
        #: wall time of the grid's predictions, made before any impact [s]
        self.arming_time = time.perf_counter() - clock
        self._impact: _Impact | None = None
        self.estimates: list[Identification] = []
        self.outcomes: list[Identification | IdentificationError] = []
        self.update_times: list[float] = []
        self.last_record: Recording | None = None
        self.finished = False  # finish() called: no more samples

    def _arm(self) -> dict:
        """The predictions of the start grid for the window it is ranked on (the first window, at most
        ``STAGES[0]``: :func:`.select._grid_starts`) of an impact with the full pre-trigger, keyed by (samples
        before the trigger, samples of the window)."""
        pre = int(PRE_TRIGGER * self.sample_rate)
        contact = (pre - batch.TRIGGER_LEAD) / self.sample_rate - self.delay
        size = int(math.floor((contact + min(self.first, STAGES[0][0])) * self.sample_rate + 1e-9)) + 1
        try:
            return {(pre, size): _grid_predictions(_make_grid(0.0, self.sample_rate, size, self.design), self.rig,
                                                  contact, self.pressure_gauge, self._pressure_gauge_start)}
        except IdentificationError:  # a stand the model cannot start: the first impact says so
            return {}

    def _recording(self, channels: np.ndarray, first: int, metadata: dict | None = None,
                   opening: np.ndarray | None = None) -> Recording:
        named = dict(zip(CHANNELS, channels, strict=True))
        if opening is not None and np.any(opening > 0.0):  # a closed valve: the record without it, bit for bit
            named[VALVE_OPENING] = opening
        return Recording(sample_rate=self.sample_rate, channels=named,
                         start_time=self.start_time + first / self.sample_rate,
                         metadata=self.metadata if metadata is None else metadata, source="stream")

    def _buffered(self, first: int, stop: int, metadata: dict | None = None) -> Recording:
        """The record of stream indices ``first`` to ``stop`` (exclusive), with valve Z's opening where the valve
        was open in it."""
        opening = self._opening[np.arange(first, stop) % self._opening.size] if self._opened else None
        return self._recording(np.vstack(self.robust.buffered(first, stop)), first, metadata, opening)

    @property
    def notes(self) -> list[str]:
        """Why updates of the last impact gave no estimate (a fit that failed or did not explain the record)."""
        return [] if self._impact is None else self._impact.fit.notes

    def push(self, force_chunk, acceleration_chunk, opening_chunk=None) -> list[Identification]:
        """Feed samples (any number); return the model's estimates that became available (StreamFinishedError
        after :meth:`finish`).

        ``opening_chunk``: valve Z's opening [-] (0 closed, 1 fully open) at each sample, as the valve's command
        and drive give it, for a stand whose valve moves during the impact: the fits then predict the record with
        that opening (each sample's opening held from its instant), as the batch fit does with a record's
        ``valve_opening`` channel. None (or zero throughout): the valve closed, the same answers as without it.

        Raises
        ------
        IdentificationError
            Chunks that are not 1-D numbers of equal length, or an opening that is not finite or outside [0, 1].
        """
        check_open(self)
        try:
            f = np.atleast_1d(np.asarray(force_chunk, dtype=float))
            a = np.atleast_1d(np.asarray(acceleration_chunk, dtype=float))
            z = np.zeros_like(f) if opening_chunk is None else np.atleast_1d(np.asarray(opening_chunk, dtype=float))
        except (TypeError, ValueError):
            raise IdentificationError("force, acceleration and opening chunks must hold numbers") from None
        if f.ndim != 1 or f.shape != a.shape:
            raise IdentificationError(f"force and acceleration chunks must be 1-D of equal length, got shapes "
                                      f"{f.shape} and {a.shape}")
        if z.shape != f.shape:
            raise IdentificationError(f"opening_chunk must be 1-D of the force chunk's length {f.size}, got shape "
                                      f"{z.shape}")
        bad = ~(np.isfinite(z) & (z >= 0.0) & (z <= 1.0))
        if bad.any():
            raise IdentificationError(f"opening_chunk must be valve Z's opening within [0, 1] [-] at every sample, "
                                      f"got {float(z[bad][0])!r} at index {int(np.argmax(bad))}")
        self._opened = self._opened or opening_chunk is not None and bool(np.any(z > 0.0))
        out: list[Identification] = []
        for k in range(0, f.size, self._chunk):  # an impact's trigger is seen within a cadence
            part = z[k:k + self._chunk]
            self._opening[(self.robust.seen + np.arange(part.size)) % self._opening.size] = part
            self.robust.push(f[k:k + self._chunk], a[k:k + self._chunk])
            out += self._advance()
        return out

    def defer(self, until: float) -> None:
        """Let the next update read the record up to at least ``until`` [s, the stream's clock]: a real-time caller
        whose last update was done at ``until`` fits the newest samples then, not the ones it could not reach in
        time (the updates in between are skipped)."""
        impact = self._impact
        if impact is not None and not impact.done:  # the update already planned; the cadence goes on from it
            impact.next_stop = min(max(impact.next_stop, self._stop(impact.contact_time, until - impact.contact_time)),
                                   self._stop(impact.contact_time, self.window))

    def _advance(self) -> list[Identification]:
        trigger = self.robust.trigger_index
        if trigger is not None and (self._impact is None or self._impact.trigger != trigger):
            self._begin(trigger)
        impact, out = self._impact, []
        while impact is not None and not impact.done and self.robust.seen >= impact.next_stop:
            out += self._update(impact, impact.next_stop)
        return out

    def _begin(self, trigger: int) -> None:
        if self._impact is not None and not self._impact.done:
            self._conclude(self._impact, self.robust.seen)
        first = max(trigger - int(PRE_TRIGGER * self.sample_rate), self.robust.impact_start or 0)
        contact = self.start_time + (trigger - batch.TRIGGER_LEAD) / self.sample_rate - self.delay
        self._impact = _Impact(trigger=trigger, first=first, contact_time=contact,
                               next_stop=self._stop(contact, self.first),
                               fit=_Growing(rig=self.rig, laws=self.laws, uncertain=self.uncertain))
        self.estimates = []
        self._prepare(self._impact)

    def _prepare(self, impact: _Impact) -> None:
        """The checks and figures of the pre-trigger (:func:`.engine.check_length`, the noise σ and offsets of
        :func:`.engine.observe`), made at the trigger on the samples so far: they read the samples before first
        contact only, so the first answer finds them made. Where the record so far does not pass, the first update
        checks it again and says why."""
        recording = self._buffered(impact.first, self.robust.seen, self._update_metadata)
        with contextlib.suppress(IdentificationError):
            check_length(recording, min_duration=0.0)
            self._observe(recording, impact)
            impact.checked = True

    def _observe(self, recording: Recording, impact: _Impact) -> Observed:
        """The record as the fit reads it (:func:`.engine.observe`, its pre-trigger figures kept for the impact), on
        a grid whose sensor model the stream made once: the design of the anti-alias FIR costs a quarter of a
        millisecond, a first answer little more than a millisecond."""
        data = observe(recording, "none", impact.contact_time, min_duration=0.0,  # the design only makes the grid
                       quiet=impact.quiet)
        return replace(data, grid=replace(self._grid_model, start_time=data.grid.start_time, size=data.grid.size,
                                          valve=data.grid.valve))

    def _stop(self, contact: float, after: float) -> int:
        """Stream index one past the last sample of the record up to ``after`` [s] after ``contact``."""
        return int(math.floor((contact + after - self.start_time) * self.sample_rate + 1e-9)) + 1

    def _update(self, impact: _Impact, stop: int) -> list[Identification]:
        """The estimate of the record up to stream index ``stop`` (exclusive); the final answer at ``window``."""
        clock = time.perf_counter()
        span = self.start_time + (stop - 1) / self.sample_rate - impact.contact_time
        if span >= self.window - 0.5 / self.sample_rate:
            return self._conclude(impact, stop)
        impact.next_stop = min(self._stop(impact.contact_time, span + self.cadence),
                               self._stop(impact.contact_time, self.window))
        recording = self._buffered(impact.first, stop, self._update_metadata)
        try:
            if not impact.checked:  # a pre-trigger, as the batch fit needs one (the same for every update)
                check_length(recording, min_duration=0.0)
                impact.checked = True
            data = self._observe(recording, impact)
            fit = self._first(impact, data, span) if not impact.fit.states else _update(impact.fit, data, span)
        except IdentificationError as exc:  # no estimate this time; the final answer decides
            impact.fit.notes.append(f"up to {span * 1e3:.3g} ms after first contact: {exc}")
            return []
        if fit is None:
            return []
        return self._emit(fit, recording, stage="update" if self.estimates else "first", clock=clock, span=span,
                          impact=impact, data=data)

    def _first(self, impact: _Impact, data: Observed, span: float) -> LawFit | None:
        """The first answer, from the robust answer where the stream has one by then, else from the grid's best
        starts (:func:`.growing.first_fit`)."""
        if self.robust.estimates:
            robust = self.robust.estimates[-1]
            starts = [_Start(mass=robust.mass, velocity=robust.velocity, contact_time=impact.contact_time,
                            pressure_gauge=self.pressure_gauge, pressure_gauge_start=self._pressure_gauge_start,
                            pressure_gauge_std=self.pressure_gauge_std)]
        else:
            part = window(data, impact.contact_time + STAGES[0][0])  # the window the grid is ranked on
            predicted = self._grid.get((impact.trigger - impact.first, part.grid.size))
            if predicted is not None and self.design in ("causal", "none"):
                # the grid's χ² on the samples where some prediction is not zero: those before differ between its
                # impacts by nothing (the same ranking, a thousand pre-trigger samples less to sum)
                cut = max(int(math.floor((impact.contact_time - data.grid.start_time) * self.sample_rate))
                          - LEAD_SAMPLES, 0)
                part = replace(part, channels=part.channels[:, cut:], grid=replace(  # (a start a millionth of a
                    part.grid, start_time=part.grid.start_time + (cut - 1e-6) / self.sample_rate,  # period early:
                    size=part.grid.size - cut))  # the window's floor keeps its last sample)
                predicted = predicted[..., cut:]
            starts = [replace(start, pressure_gauge_std=self.pressure_gauge_std) for start in _grid_starts(
                part, self.rig, impact.contact_time, self.pressure_gauge, self._pressure_gauge_start, count=GRID_STARTS,
                predicted=predicted)]
        return _first_fit(impact.fit, data, span, starts)

    def _emit(self, fit: LawFit, recording: Recording, *, stage: str, clock: float, span: float,
              impact: _Impact, data: Observed) -> list[Identification]:
        growing = impact.fit
        held = fit.layout.names == growing.states[fit.law].layouts.fixed("core").names
        # the stand held: only an answer that explains the record so far
        if held and not _explained(growing, fit, data):
            growing.notes.append(f"up to {span * 1e3:.3g} ms after first contact: the {fit.law} model with the "
                                 "stand held does not explain the samples after contact down to their noise")
            return []
        start = growing.start
        common = ModelDetails(path="", reason="", contact_law=None, start={} if start is None else {
            "mass_kg": start.mass, "velocity_m_s": start.velocity, "contact_time_s": start.contact_time},
            stream=StreamStage(stage=stage, cadence=self.cadence, window=span, law_choice=growing.choice or (
                "not yet: the laws are compared on the first "f"{STAGES[SCREEN_WINDOW][0] * 1e3:g} ms"),
                sigma_given="the stand's parameters held at the rig's values" if held else
                "every unknown of the batch fit free"))
        if fit.reduced_chi2 > batch.MAX_REDUCED_CHI2:
            if not self.robust.estimates:
                return []
            robust = self.robust.estimates[-1]
            reason = (f"the best model ({fit.law}) leaves chi2/dof = {fit.reduced_chi2:.3g} > "
                      f"{batch.MAX_REDUCED_CHI2:g} on the record so far: the robust stream's answer is given")
            answer, warnings = robust, robust.warnings
            details = replace(common, path="fallback", reason=reason, contact_law=fit.law, fallback=robust.details)
            available_at = recording.start_time + (recording.contact_force.size - 1) / self.sample_rate
            method = "model/fallback"
        else:
            answer = batch._answer(recording, self.rig, fit, common, (self.pressure_gauge, self.pressure_gauge_std))
            warnings, available_at, method = (*self._stand_notes, *answer.warnings), answer.available_at, answer.method
            assert isinstance(answer.details, ModelDetails)  # _answer's
            details = answer.details
        assert details.stream is not None  # made above
        elapsed = time.perf_counter() - clock
        self.update_times.append(elapsed)
        answer = replace(answer, method=method, available_at=available_at, warnings=warnings,
                         details=replace(details, stream=replace(details.stream, update_time=elapsed)))
        self.estimates.append(answer)
        return [answer]

    def _conclude(self, impact: _Impact, stop: int) -> list[Identification]:
        """The final answer: the batch fit of the record up to ``stop`` (every law again, from the robust answer,
        with its fall-back), or its refusal (kept in ``outcomes``)."""
        impact.done = True
        clock = time.perf_counter()
        stop = min(stop, self.robust.seen)
        try:
            recording = self._buffered(impact.first, stop)
            self.last_record = recording
            final = batch.identify(recording, rig=self.rig, pressure_gauge=self._given_pressure[0],
                                   pressure_gauge_std=self._given_pressure[1], uncertain=self.uncertain,
                                   contact=self.contact)
        except IdentificationError as exc:
            self.outcomes.append(exc)
            return []
        span = recording.start_time + (recording.contact_force.size - 1) / self.sample_rate - impact.contact_time
        stage = StreamStage(stage="final", cadence=self.cadence, window=span, update_time=time.perf_counter() - clock,
                            law_choice=f"the batch fit's; in the stream: {impact.fit.choice}")
        assert isinstance(final.details, ModelDetails)  # identify's
        final = replace(final, details=replace(final.details, stream=stage))
        self.outcomes.append(final)
        self.estimates.append(final)
        return [final]

    def finish(self) -> Identification | None:
        """End of the stream: the final answer of the running impact (the batch fit of what it holds), else the
        last impact's; None when the stream held no impact.

        Raises
        ------
        IdentificationError
            The refusal of the batch fit for that impact (too short, no pre-trigger, ...).
        """
        self.finished = True
        if self._impact is not None and not self._impact.done:
            self._conclude(self._impact, self.robust.seen)
        return last_outcome(self.outcomes)
