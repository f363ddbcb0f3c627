"""Streaming peak-to-peak identification: push chunks of any size, get estimates as soon as the data allows.

The dual form of :func:`~impactometer.identify.peak_to_peak.identify_arrays`: the same compiled trigger runs sample by
sample, the samples of the current impact sit in a fixed ring buffer (constant memory over endless input), and at
every pulse end the same solver runs on the buffered segment. After an impact closes (a quiet spell or the maximum
duration) the identifier re-arms for the next one.
"""

from __future__ import annotations

import contextlib

import numpy as np
from numba import njit

from ...errors import IdentificationError, ParameterError, StreamFinishedError
from ...recording import check_sample_rate
from ...signals import trigger
from ...signals.stage_b import is_sustained
from ...validation import check_integer, check_real
from ..result import Identification
from .batch import GRAVITY, early_answer, solve
from .options import check_options
from .segment import MAX_DURATION, PRE_SAMPLES, QUIET_TIME, TRIGGER_FLOOR, Segment, early_ready, prepare


@njit(cache=True)
def _store(force, acceleration, ring_force, ring_acceleration, seen):
    """Copy a chunk into the ring buffers; the index of the first non-finite sample (nothing copied) or -1."""
    n = force.shape[0]
    for i in range(n):
        if not (np.isfinite(force[i]) and np.isfinite(acceleration[i])):
            return i
    capacity = ring_force.shape[0]
    for i in range(n):
        j = (seen + i) % capacity
        ring_force[j] = force[i]
        ring_acceleration[j] = acceleration[i]
    return -1


#: while the contact is sustained (stage B) and the impact has no answer yet, one is tried this often [s]: a
#: controller waits for it
FIRST_INTERVAL = 0.002
#: once it has one, the answer is updated at most this often [s] ...
UPDATE_INTERVAL = 0.01
#: ... and when the impact has lasted this multiple of its length at the last update: the stage-B rows grow with
#: the record, so each update lowers the standard error by a similar fraction (about 30 % at 2, as 1/√N), and
#: the cost of a long stage B grows as its logarithm rather than its square
UPDATE_GROWTH = 2.0


class StreamingIdentifier:
    """Identify impacts from an endless stream of contact force [N] and piston acceleration [m/s²] samples.

    Parameters
    ----------
    sample_rate : float
        Sample rate [Hz].
    variant : {"robust", "paper"}
    gravity : float
        Gravitational acceleration [m/s²].
    start_time : float
        Time of the first sample pushed [s].
    floor : float
        Smallest trigger level [N] (the force channel's resolution).
    contact_phase : bool
        ``robust`` only: see :func:`~impactometer.identify.peak_to_peak.identify_arrays`.
    estimates : bool
        False: the stream only triggers and buffers (no estimate, no final answer; ``outcomes`` stays empty), for a
        caller that needs the impact's samples alone and not the half millisecond of work at each pulse's end.

    Notes
    -----
    ``push`` returns the new estimates (each an :class:`Identification` whose ``available_at`` is the time of the
    last sample it used); ``estimates`` keeps those of the current impact, ``completed`` the final answer of
    every closed impact that has one, and ``outcomes`` the final answer or the refusal of every closed impact.
    Every estimate passes the checks of the batch function (:func:`~.plausibility.check_segment`), and the final
    answer of an impact (or its refusal) equals the batch function's on the same samples.
    """

    def __init__(self, sample_rate: float, *, variant: str = "robust", gravity: float = GRAVITY,
                 start_time: float = 0.0, floor: float = TRIGGER_FLOOR, contact_phase: bool = False,
                 estimates: bool = True):
        sample_rate = check_sample_rate(sample_rate, error=ParameterError)
        variant, gravity, start_time = check_options(variant, gravity, start_time, error=ParameterError)
        floor = check_real("floor", floor, low=0.0, unit=" [N]", error=ParameterError)
        self.sample_rate, self.variant, self.gravity = float(sample_rate), variant, gravity
        self.start_time, self.floor = start_time, floor
        self.contact_phase = bool(contact_phase)
        self.estimating = bool(estimates)
        self.quiet = max(int(QUIET_TIME * sample_rate), 1)
        self.max_samples = max(int(MAX_DURATION * sample_rate), 1)
        self.baseline = trigger.baseline_samples(sample_rate)
        self.capacity = PRE_SAMPLES + self.max_samples + 2
        self._force = np.zeros(self.capacity)
        self._acc = np.zeros(self.capacity)
        self._fstate, self._istate = trigger.new_state()
        self._step = self.capacity // 4
        self._events = np.zeros((3 * self._step + 2, 2), dtype=np.int64)
        self.seen = 0
        self.finished = False  # finish() called: no more samples
        self._start: int | None = None  # first buffered sample of the running impact; None while armed
        self._pre = 0
        self._early: Identification | None = None
        self._early_done = False
        self._onsets: dict = {}
        self._last_close = -1
        self.estimates: list[Identification] = []
        self.completed: list[Identification] = []
        self.outcomes: list[Identification | IdentificationError] = []
        # stage B: the running pulse's start, the longest pulse so far, the last update [samples]
        self._inside_since = self._longest = self._last_update = 0
        self._update_samples = max(int(UPDATE_INTERVAL * sample_rate), 1)
        self._first_samples = max(int(FIRST_INTERVAL * sample_rate), 1)

    @property
    def armed(self) -> bool:
        """True while waiting for an impact."""
        return self._start is None

    @property
    def trigger_index(self) -> int | None:
        """Stream index of the running impact's trigger sample (None while armed)."""
        return None if self._start is None else self._start + self._pre

    @property
    def impact_start(self) -> int | None:
        """Stream index of the running impact's first buffered sample (None while armed)."""
        return self._start

    def buffered(self, start: int, stop: int) -> tuple[np.ndarray, np.ndarray]:
        """Copies of the force [N] and acceleration [m/s²] samples of stream indices ``start`` to ``stop``
        (exclusive), which must still be in the ring buffer (the last ``capacity`` samples pushed)."""
        if not (0 <= start <= stop <= self.seen and self.seen - start <= self.capacity):
            raise IdentificationError(f"samples {start}..{stop} are not in the buffer (it holds "
                                      f"{max(self.seen - self.capacity, 0)}..{self.seen})")
        idx = np.arange(start, stop) % self.capacity
        return self._force[idx], self._acc[idx]

    def push(self, force_chunk, acceleration_chunk) -> list[Identification]:
        """Feed samples (any number, down to one); return the estimates that became available.

        Raises
        ------
        StreamFinishedError
            After :meth:`finish`: the stream has ended (start a new identifier for another stream).
        """
        check_open(self)
        try:
            f = np.asarray(force_chunk, dtype=np.float64)
            a = np.asarray(acceleration_chunk, dtype=np.float64)
        except (TypeError, ValueError):
            raise IdentificationError("force and acceleration chunks must hold numbers") from None
        if f.ndim == 0:
            f, a = f.reshape(1), a.reshape(-1)
        if f.ndim != 1 or f.shape != a.shape:
            raise IdentificationError(f"force and acceleration chunks must be 1-D of equal length, got shapes "
                                      f"{f.shape} and {a.shape}")
        if f.size <= self._step:
            return self._push(f, a)
        out: list[Identification] = []
        for k in range(0, f.size, self._step):
            out.extend(self._push(f[k:k + self._step], a[k:k + self._step]))
        return out

    def _push(self, f, a) -> list[Identification]:
        bad = _store(f, a, self._force, self._acc, self.seen)
        if bad >= 0:
            raise IdentificationError(f"non-finite sample at stream index {self.seen + bad}; expected finite "
                                      "numbers")
        was_inside = self._start is not None and bool(self._istate[trigger.INSIDE])
        n_ev = trigger.run_trigger(f, self._fstate, self._istate, self.floor, self.quiet, self.max_samples,
                                   self.baseline, self._events)
        self.seen += f.size
        out = []
        for code, index in self._events[:n_ev]:
            out.extend(self._event(int(code), int(index)))
        if self._start is not None and self.variant == "robust" and self.estimating:
            inside = bool(self._istate[trigger.INSIDE])
            if inside and not was_inside:
                self._inside_since = self.seen - f.size
            if inside and self._sustained() and self._update_due():
                self._last_update = self.seen
                out.extend(self._solve(self.seen))
        return out

    def _sustained(self) -> bool:
        """Whether the running pulse has lasted longer than a bounce could (stage B): time for an update."""
        # a pulse before this one (``_longest`` > 0), and this one many bounces long: the one rule of stage B
        return is_sustained(int(self._longest > 0), self.seen - self._inside_since, self._longest)

    def _update_due(self) -> bool:
        """Whether a stage-B update is due: ``FIRST_INTERVAL`` since the last try while the impact has no answer;
        then ``UPDATE_INTERVAL`` since the last update, and the impact (counted from its trigger) ``UPDATE_GROWTH``
        times as long as then."""
        if not self.estimates:
            return self.seen - self._last_update >= self._first_samples
        assert self._start is not None  # called only while an impact runs
        trigger_at = self._start + self._pre
        return self.seen - self._last_update >= self._update_samples \
            and self.seen - trigger_at >= UPDATE_GROWTH * (self._last_update - trigger_at)

    def _segment(self, stop: int) -> Segment:
        assert self._start is not None  # called only while an impact runs
        return prepare(*self.buffered(self._start, stop), self.sample_rate,
                       self.start_time + self._start / self.sample_rate, self._pre, cache=self._onsets)

    def _event(self, code: int, index: int) -> list[Identification]:
        if code == trigger.EVENT_TRIGGER:
            if index <= trigger.WARM_SAMPLES and self._last_close < 0:
                self._start, self._pre = 0, 0
            else:
                self._start = max(index - PRE_SAMPLES, self._last_close + 1, 0)
                self._pre = index - self._start
            self._early, self._early_done = None, False
            self._onsets = {}
            self.estimates = []
            self._inside_since, self._longest, self._last_update = index, 0, index
            return []
        if self._start is None:
            return []
        if code == trigger.EVENT_PULSE_END:
            self._longest = max(self._longest, index - self._inside_since)
        if not self.estimating:
            if code == trigger.EVENT_CLOSE:
                self._start, self._last_close = None, index
            return []
        if code == trigger.EVENT_CLOSE:
            return self._conclude(index + 1, index)
        return self._solve(index + 1, final=code != trigger.EVENT_PAST_PEAK)

    def _early_step(self, seg: Segment) -> list[Identification]:
        """The early answer, once, as soon as the segment allows it (as the batch function finds it)."""
        if self.variant != "robust" or self._early_done or not early_ready(seg):
            return []
        self._early_done = True
        self._early = early_answer(seg, self.gravity)
        return [] if self._early is None else [self._early]

    def _solve(self, stop: int, final: bool = True) -> list[Identification]:
        seg = self._segment(stop)
        new = self._early_step(seg)
        # the paper variant needs the second peak; the robust one answers from stage B or a second pulse
        if final and (sum(p.complete for p in seg.pulses) >= 2 or (self.variant == "robust" and self._sustained())):
            with contextlib.suppress(IdentificationError):  # no answer yet: the impact's end decides (_conclude)
                new.append(solve(seg, self.variant, self.gravity, early=self._early,
                                 contact_phase=self.contact_phase))
        return self._record(new)

    def _record(self, new: list[Identification]) -> list[Identification]:
        new = [r for r in new if not self.estimates or r != self.estimates[-1]]
        self.estimates.extend(new)
        return new

    def _conclude(self, stop: int, close: int) -> list[Identification]:
        """End of the impact: its final answer exactly as the batch function gives it on these samples, or the
        refusal the batch function would raise (kept in ``outcomes``)."""
        seg = self._segment(stop)
        new = self._early_step(seg)
        try:
            final = solve(seg, self.variant, self.gravity, early=self._early, contact_phase=self.contact_phase)
        except IdentificationError as exc:
            self.outcomes.append(exc)
        else:
            self.outcomes.append(final)
            self.completed.append(final)
            new.append(final)
        self._start = None
        self._last_close = close
        return self._record(new)

    def finish(self) -> Identification | None:
        """End of the stream: the final answer of the last impact (the running one, else the last closed one), as
        the batch function gives it on its samples; None when the stream held no impact.

        Raises
        ------
        IdentificationError
            The refusal the batch function gives for that impact (saturated force, dead accelerometer, no
            positive mass, too few contact pulses, ...).
        """
        self.finished = True
        if self._start is not None:
            self._conclude(self.seen, self.seen - 1)
        return last_outcome(self.outcomes)


def check_open(stream) -> None:
    """StreamFinishedError where ``stream`` (a streaming identifier) has been finished."""
    if stream.finished:
        raise StreamFinishedError(f"push() after finish(): this {type(stream).__name__} has ended its stream; "
                                  "create a new one for more samples")


def last_outcome(outcomes: list[Identification | IdentificationError]) -> Identification | None:
    """The last impact's final answer (None without an impact), or its refusal raised."""
    if not outcomes:
        return None
    if isinstance(outcomes[-1], IdentificationError):
        raise outcomes[-1]
    return outcomes[-1]


def stream_arrays(force, acceleration, sample_rate: float, *, chunk: int = 64, **options) -> list[Identification]:
    """Replay arrays through a :class:`StreamingIdentifier` in chunks; every estimate in order of availability,
    the final answer that the end of the data completes included."""
    chunk = check_integer("chunk", chunk, low=1, unit=" [samples]", error=ParameterError)
    ident = StreamingIdentifier(sample_rate, **options)
    out = []
    for k in range(0, len(force), chunk):
        out.extend(ident.push(force[k:k + chunk], acceleration[k:k + chunk]))
    shown = len(ident.estimates)
    with contextlib.suppress(IdentificationError):  # a refused last impact adds no final answer
        ident.finish()
    return out + ident.estimates[shown:]
