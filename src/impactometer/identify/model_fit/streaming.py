"""Streaming model-based identification: the model's answer from the first milliseconds of an impact, updated at a
stated cadence, and the batch fit of the record as the final answer.

The robust :class:`~impactometer.identify.peak_to_peak.streaming.StreamingIdentifier` runs on every sample: its
trigger finds the impact and its ring buffer holds the samples. The model reads them:

- **First answer**, as soon as ``STAGES[0]`` (4 ms) of record after first contact has arrived: M1, V0 and the
  contact instant fitted on that window with the stand's parameters held, by every contact law, from the robust
  answer where the stream has one by then, else from the grid of impacts of :func:`.select.grid_start`; the laws
  are screened as the batch fit screens them on its first window (:func:`.select.screen`).
- **Updates** every ``cadence`` of record after it: the fit of the record so far, warm-started from the last
  update (the previous optimum), by Levenberg-Marquardt steps (:func:`.fit.refine`; one Jacobian each). Before
  ``STAGES[SCREEN_WINDOW]`` (15 ms) the stand's parameters are held; from it on every unknown of the batch fit
  is free. The law: where the first screen leaves more than one, each is updated up to the 15 ms window, where the
  smallest BIC chooses one and keeps it; the final answer revisits the choice (it fits every law again).
- **Final answer** once ``window`` (50 ms) of record after first contact has arrived, or at ``finish()``:
  :func:`~impactometer.identify.model_fit.identify` of the buffered record, so the stream's final answer is the
  batch answer of the same samples.

Standard errors: the inverse Fisher information at the update, inflated by sqrt(χ²/dof) above 1. Before 15 ms the
stand's parameters are held at the rig's values, and so is the σ: it is the σ of a stand known exactly
(``sigma_given`` in the details says so); the first pulses alone cannot tell M1 from the contact's parameters.
"""

from __future__ import annotations

import contextlib
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from ...errors import IdentificationError, ParameterError, shown
from ...recording import Recording, check_sample_rate
from ...rig import Rig, get_rig
from ...sensors import anti_alias_delay
from ...validation import check_integer, check_real
from .. import model_fit as batch
from ..peak_to_peak.streaming import StreamingIdentifier, last_outcome
from ..result import Identification
from . import select
from .fit import MAX_EVALUATIONS, LawFit, Observed, refine
from .forward import check_uncertain
from .select import STAGES, Layouts, Start, fit_stages, grid_starts, screen, start_law

#: default time between updates [s] of record
CADENCE = 0.005
#: default record after first contact whose batch fit is the final answer [s]
WINDOW = 0.05
#: most pre-trigger the model reads [s] (the noise σ and the offsets come from it)
PRE_TRIGGER = 0.02
#: Levenberg-Marquardt steps of one update
UPDATE_STEPS = 1
#: starts of the grid tried in turn for the first answer, where the robust stream has none yet
GRID_STARTS = 3


@dataclass
class _Law:
    """One contact law followed by the updates: its layouts, last values, offsets and fit."""

    layouts: Layouts
    values: dict
    offsets: np.ndarray
    fit: LawFit


@dataclass
class _Impact:
    """The state of the running impact: its trigger and first buffered sample (stream indices), the contact
    instant the fit counts from [s], the next update's last sample, the laws followed and the chosen one."""

    trigger: int
    first: int
    contact_time: float
    next_stop: int
    laws: dict[str, _Law] = field(default_factory=dict)
    chosen: str | None = None
    choice: str = ""
    start: Start | None = None
    done: bool = False


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
    rig, pressure, uncertain, contact
        As in :func:`.identify`.
    cadence : float
        Record between updates [s].
    window : float
        Record after first contact whose batch fit is the final answer [s].

    Notes
    -----
    ``push`` returns the new estimates, each an :class:`Identification` (``model/ml``; ``model/fallback`` where the
    model leaves χ²/dof above ``MAX_REDUCED_CHI2`` and the robust stream has an answer) whose ``available_at`` is
    the time of the last sample it used and whose details give ``stage`` (``first``, ``update``, ``final``),
    ``update_time_s`` (the wall time the update took), ``cadence_s`` and ``window_ms``. ``estimates`` keeps those
    of the current impact, ``outcomes`` the final answer or refusal of every impact, ``last_record`` the samples the
    last final answer read (a :class:`Recording`), ``update_times`` the wall time of every estimate [s] and
    ``skipped`` why an update gave no estimate.
    """

    def __init__(self, sample_rate: float, *, start_time: float = 0.0, metadata: dict | None = None,
                 rig: Rig | str | None = None, pressure: float | None = None, uncertain: Sequence[str] | None = None,
                 contact: str | None = "auto", cadence: float = CADENCE, window: float = WINDOW):
        sample_rate = check_sample_rate(sample_rate, error=ParameterError)
        self.cadence = check_real("cadence", cadence, low=1.0 / sample_rate, unit=" [s]", error=ParameterError)
        self.window = check_real("window", window, low=STAGES[0][0] + self.cadence, unit=" [s]",
                                 error=ParameterError)
        self.robust = StreamingIdentifier(sample_rate, start_time=start_time)
        self.sample_rate, self.start_time = float(sample_rate), float(start_time)
        self.rig, self.laws = get_rig(rig), batch._laws(contact)
        self.uncertain, self.contact = check_uncertain(uncertain, self.laws), contact
        self.metadata = dict(metadata or {})
        probe = self._recording(np.zeros((2, 1)), 0)
        self.design = batch._design(probe)
        self.pressure = batch._pressure(probe, pressure, self.rig)
        self.delay = anti_alias_delay(self.design, sample_rate)
        self._chunk = max(int(self.cadence * sample_rate), 1)
        self._impact: _Impact | None = None
        self.estimates: list[Identification] = []
        self.outcomes: list[Identification | IdentificationError] = []
        self.update_times: list[float] = []
        self.skipped: list[str] = []
        self.last_record: Recording | None = None

    def _recording(self, channels: np.ndarray, first: int) -> Recording:
        return Recording(sample_rate=self.sample_rate, channels=dict(zip(batch.CHANNELS, channels, strict=True)),
                         start_time=self.start_time + first / self.sample_rate, metadata=self.metadata,
                         source="stream")

    def push(self, force_chunk, acceleration_chunk) -> list[Identification]:
        """Feed samples (any number); return the model's estimates that became available."""
        try:
            f = np.atleast_1d(np.asarray(force_chunk, dtype=float))
            a = np.atleast_1d(np.asarray(acceleration_chunk, dtype=float))
        except (TypeError, ValueError):
            raise IdentificationError("force and acceleration chunks must hold numbers") from None
        if f.ndim != 1 or f.shape != a.shape:
            raise IdentificationError(f"force and acceleration chunks must be 1-D of equal length, got shapes "
                                      f"{f.shape} and {a.shape}")
        out: list[Identification] = []
        for k in range(0, f.size, self._chunk):  # an impact's trigger is seen within a cadence
            self.robust.push(f[k:k + self._chunk], a[k:k + self._chunk])
            out += self._advance()
        return out

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
                               next_stop=self._stop(contact, STAGES[0][0]))
        self.estimates = []

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
        recording = self._recording(np.vstack(self.robust.buffered(impact.first, stop)), impact.first)
        try:
            data = batch._observe(recording, self.design, impact.contact_time, min_duration=0.0)
            fit = self._first(impact, data, span) if not impact.laws else self._refit(impact, data, span)
        except IdentificationError as exc:  # no estimate this time; the final answer decides
            self.skipped.append(f"{recording.start_time + span:.6g} s: {exc}")
            return []
        if fit is None:
            return []
        return self._emit(fit, recording, stage="update" if self.estimates else "first", clock=clock, span=span,
                          impact=impact)

    def _first(self, impact: _Impact, data: Observed, span: float) -> LawFit | None:
        """Every law fitted on the first window (stand held), from the robust answer where the stream has one,
        else from the grid's best starts in turn until one explains the window (χ²/dof <= EARLY_REDUCED_CHI2);
        then the first screen."""
        pressure_start = self.metadata.get("pressure_gauge_Pa") or batch.DEFAULT_PRESSURE_START
        if self.robust.estimates:
            robust = self.robust.estimates[-1]
            starts = [Start(mass=robust.mass, velocity=robust.velocity, contact_time=impact.contact_time,
                            pressure=self.pressure, pressure_start=pressure_start)]
        else:
            starts = grid_starts(data, self.rig, impact.contact_time, self.pressure, pressure_start,
                                 count=GRID_STARTS)
        own = self.rig.contact.law if self.rig.contact.law in self.laws else self.laws[0]
        found: _Law | None = None
        for start in starts:  # the stand's own law, to convergence, from each start until one explains the window
            try:
                state = self._fit_first(own, start, data, None, MAX_EVALUATIONS)
            except IdentificationError as exc:
                self.skipped.append(f"{own} on the first {span * 1e3:.3g} ms: {exc}")
                continue
            if found is None or state.fit.chi2 < found.fit.chi2:
                found, impact.start = state, start
            if found.fit.reduced_chi2 <= select.EARLY_REDUCED_CHI2:
                break
        if found is None or impact.start is None:
            return None
        best = {own: found}
        for law in self.laws:  # the others from its answer, as far as the screen needs
            if law != own:
                try:
                    best[law] = self._fit_first(law, impact.start, data, found.values, select.SCREEN_EVALUATIONS)
                except IdentificationError as exc:
                    self.skipped.append(f"{law} on the first {span * 1e3:.3g} ms: {exc}")
        impact.laws = best
        dropped = screen({law: state.fit for law, state in best.items()}, span, select.EARLY_MARGIN,
                         within=select.EARLY_REDUCED_CHI2)
        for law in dropped:
            del impact.laws[law]
        if len(impact.laws) == 1:
            impact.chosen = next(iter(impact.laws))
            impact.choice = (f"{impact.chosen}: the only law left on the first {span * 1e3:.3g} ms"
                             + (f" ({'; '.join(f'{k}: {v}' for k, v in dropped.items())})" if dropped else ""))
        return _lowest(impact.laws) if impact.laws else None

    def _fit_first(self, law: str, start: Start, data: Observed, core: dict | None, evaluations: int) -> _Law:
        """``law`` fitted on the first window with the stand held, from ``start`` or the ``core`` values (M1, V0,
        the contact instant) of another law's fit."""
        layouts, values = start_law(self.rig, law, self.uncertain, start, self.sample_rate)
        if core is not None:
            values.update({name: core[name] for name in ("mass", "velocity", "contact_time")})
        fit, values, offsets = fit_stages(data, layouts, values, data.offsets, ((None, "core"),), start,
                                          evaluations=evaluations)
        return _Law(layouts, values, offsets, fit)

    def _refit(self, impact: _Impact, data: Observed, span: float) -> LawFit | None:
        """Every law followed, updated from its last values; the choice at the screening window."""
        kind = "core" if span < STAGES[select.SCREEN_WINDOW][0] else "all"
        for law, state in list(impact.laws.items()):
            try:
                fit = refine(data, state.layouts(kind, state.values), state.values, state.offsets,
                             steps=UPDATE_STEPS)
            except IdentificationError:
                if len(impact.laws) > 1:
                    del impact.laws[law]
                continue
            impact.laws[law] = _Law(state.layouts, {**state.values, **fit.values}, fit.offsets, fit)
        if impact.chosen is None and kind == "all" and impact.laws:
            fits = {law: state.fit for law, state in impact.laws.items()}
            dropped = screen(fits, span, select.SCREEN_MARGIN)
            impact.chosen = min(fits, key=lambda law: fits[law].bic)
            impact.choice = (f"{impact.chosen}: the smallest BIC on the first {span * 1e3:.3g} ms"
                             + (f" ({'; '.join(f'{k}: {v}' for k, v in dropped.items())})" if dropped else ""))
            impact.laws = {impact.chosen: impact.laws[impact.chosen]}
        return _lowest(impact.laws) if impact.laws else None


    def _emit(self, fit: LawFit, recording: Recording, *, stage: str, clock: float, span: float,
              impact: _Impact) -> list[Identification]:
        held = fit.layout.names == impact.laws[fit.law].layouts.fixed["core"].names
        if held and fit.reduced_chi2 > select.EARLY_REDUCED_CHI2:  # held stand: only an answer that explains
            self.skipped.append(f"{recording.source} up to {span * 1e3:.3g} ms after first contact: the {fit.law} "
                                f"model leaves chi2/dof = {fit.reduced_chi2:.3g} > {select.EARLY_REDUCED_CHI2:g}")
            return []  # the record so far down to its noise is given
        common = {"stage": stage, "cadence_s": self.cadence, "window_ms": span * 1e3,
                  "law_choice": impact.choice or "not yet: the laws are compared on the first "
                  f"{STAGES[select.SCREEN_WINDOW][0] * 1e3:g} ms",
                  "sigma_given": "the stand's parameters held at the rig's values" if held else
                  "every unknown of the batch fit free"}
        if fit.reduced_chi2 > batch.MAX_REDUCED_CHI2:
            if not self.robust.estimates:
                return []
            robust = self.robust.estimates[-1]
            reason = (f"the best model ({fit.law}) leaves chi2/dof = {fit.reduced_chi2:.3g} > "
                      f"{batch.MAX_REDUCED_CHI2:g} on the record so far: the robust stream's answer is given")
            answer = replace(robust, method="model/fallback", available_at=recording.start_time + (
                recording.contact_force.size - 1) / self.sample_rate, details={
                **robust.details, **common, "path": "fallback", "reason": reason, "contact_law": fit.law})
        else:
            answer = batch._answer(recording, self.rig, fit, {**common, "start": _start_of(impact.start)})
        elapsed = time.perf_counter() - clock
        self.update_times.append(elapsed)
        answer = replace(answer, details={**answer.details, "update_time_s": elapsed})
        self.estimates.append(answer)
        return [answer]

    def _conclude(self, impact: _Impact, stop: int) -> list[Identification]:
        """The final answer: the batch fit of the record up to ``stop`` (or its refusal, kept in ``outcomes``)."""
        impact.done = True
        clock = time.perf_counter()
        stop = min(stop, self.robust.seen)
        try:
            recording = self._recording(np.vstack(self.robust.buffered(impact.first, stop)), impact.first)
            self.last_record = recording
            final = batch.identify(recording, rig=self.rig, pressure=self.pressure, uncertain=self.uncertain,
                             contact=self.contact)
        except IdentificationError as exc:
            self.outcomes.append(exc)
            return []
        span = recording.start_time + (recording.contact_force.size - 1) / self.sample_rate - impact.contact_time
        final = replace(final, details={**final.details, "stage": "final", "cadence_s": self.cadence,
                                        "window_ms": span * 1e3, "update_time_s": time.perf_counter() - clock})
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
        if self._impact is not None and not self._impact.done:
            self._conclude(self._impact, self.robust.seen)
        return last_outcome(self.outcomes)


def _lowest(laws: dict[str, _Law]) -> LawFit:
    """The fit of smallest BIC among ``laws``."""
    return min((state.fit for state in laws.values()), key=lambda fit: fit.bic)


def _start_of(start: Start | None) -> dict:
    return {} if start is None else {"mass_kg": start.mass, "velocity_m_s": start.velocity,
                                     "contact_time_s": start.contact_time}


def stream_model_arrays(force, acceleration, sample_rate: float, *, chunk: int = 64,
                        **options) -> list[Identification]:
    """Replay arrays through a :class:`ModelStream` in chunks of ``chunk`` samples; every estimate in order of
    availability, the final answer included (a refused final answer adds none)."""
    chunk = check_integer("chunk", chunk, low=1, unit=" [samples]", error=ParameterError)
    if len(force) != len(acceleration):
        raise ParameterError(f"force and acceleration must have equal lengths, got {len(force)} and "
                             f"{shown(len(acceleration))}")
    stream = ModelStream(sample_rate, **options)
    out = []
    for k in range(0, len(force), chunk):
        out += stream.push(force[k:k + chunk], acceleration[k:k + chunk])
    shown_before = len(stream.estimates)
    with contextlib.suppress(IdentificationError):  # a refused final answer adds none
        stream.finish()
    return out + stream.estimates[shown_before:]
