"""Contact pulses of a force signal (stage A); which of them starts sustained contact is decided in
:mod:`.stage_b`.

One noise-aware pulse detector in two forms that share a compiled kernel and its constants (``DETECT_SIGMAS``,
``RELEASE_SIGMAS``, ``HOLD``): :class:`PulseDetector` takes the samples in chunks of any size,
:func:`detect_pulses` takes them all at once (and is the former fed once). The impact trigger (:mod:`.trigger`)
follows pulses with the same step (:func:`edge`) and its own hold (``TRIGGER_HOLD``); :func:`contact_pulses` cuts
noise-free (simulated) forces at a threshold.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from ..errors import IdentificationError
from .stage_b import SUSTAINED_FACTOR, is_sustained


@dataclass(frozen=True, kw_only=True)
class Pulse:
    """One contact pulse: onset, peak and end times [s], peak force [N], impulse ∫Fc dt [N·s]."""

    start: float
    peak_time: float
    end: float
    peak_force: float
    impulse: float
    sustained: bool = False


def contact_pulses(time: np.ndarray, force: np.ndarray, *, threshold: float = 0.0,
                   sustained_factor: float = SUSTAINED_FACTOR) -> list[Pulse]:
    """Contact pulses of ``force`` [N] sampled at ``time`` [s]: runs where the force exceeds ``threshold`` [N].

    A pulse is marked ``sustained`` (stage B, :func:`~.stage_b.is_sustained`) when it lasts longer than
    ``sustained_factor`` times the longest pulse before it (the first pulse itself never is); pulses after the
    first sustained one are not reported.
    """
    time = np.asarray(time, dtype=float)
    force = np.asarray(force, dtype=float)
    if time.shape != force.shape or time.ndim != 1 or time.size < 3:
        raise IdentificationError(f"time and force must be 1-D arrays of equal length >= 3, got shapes "
                                  f"{time.shape} and {force.shape}")
    above = force > threshold
    edges = np.diff(above.astype(np.int8))
    starts = (np.flatnonzero(edges == 1) + 1).tolist()
    ends = (np.flatnonzero(edges == -1) + 1).tolist()
    if above[0]:
        starts.insert(0, 0)
    if above[-1]:
        ends.append(force.size)
    pulses: list[Pulse] = []
    for i0, i1 in zip(starts, ends, strict=False):
        segment = slice(max(i0 - 1, 0), min(i1 + 1, force.size))
        ipk = i0 + int(np.argmax(force[i0:i1]))
        t_start = time[max(i0 - 1, 0)]
        t_end = time[min(i1, force.size - 1)]
        longest = max((q.end - q.start for q in pulses), default=0.0)
        # a pulse cut by the end of the record is stage B only once it has lasted that long: a short one is
        # simply the next bounce, cut
        sustained = is_sustained(len(pulses), t_end - t_start, longest, sustained_factor)
        pulses.append(Pulse(start=float(t_start), peak_time=float(time[ipk]), end=float(t_end),
                            peak_force=float(force[ipk]),
                            impulse=float(np.trapezoid(np.clip(force[segment], 0.0, None), time[segment])),
                            sustained=bool(sustained)))
        if sustained:
            break
    return pulses


# --------------------------------------------------------------------------------------------------------------
# Noise-robust detection (used by the peak-to-peak identification)

#: a pulse is declared where the force exceeds this many noise standard deviations
DETECT_SIGMAS = 5.0
#: a pulse ends (and a gap may begin) where the force falls below this many noise standard deviations
RELEASE_SIGMAS = 2.0
#: samples beyond a level that start or end a whole pulse (:func:`detect_pulses`, :class:`PulseDetector`; the
#: controller's contact detection and the confirmation of its turning points use it too): a lone noise sample
#: neither starts nor ends one
HOLD = 3
#: samples beyond a level that start or end a pulse inside an impact for the trigger (:mod:`.trigger`): it reports
#: a pulse end at its first sample at or below the release level, so that the streaming answer comes without
#: delay (an end that noise brings early only costs one more solve; the pulses themselves come from
#: :func:`detect_pulses` with ``HOLD``). Not one rule with ``HOLD``: a longer trigger hold delays every streaming
#: update, a shorter detector hold lets noise split pulses
TRIGGER_HOLD = 1
#: the levels never use a σ below this fraction of the largest force [-]: below it the shape of an edge is
#: anti-alias ringing (about ±5 % of a force jump) and rounding rather than contact
FLOOR_FRACTION = 5e-3
#: standard error of the median of n Gaussian samples over that of their mean, sqrt(π/2)
MEDIAN_EFFICIENCY = 1.2533141373155003
#: a gap between pulses is a separation unless the median force of its middle half lies more than this many of its
#: standard errors above zero [-]. One-sided Gaussian false-alarm rate 3e-5 per gap, so that a force-free flight is
#: practically never merged into one pulse with its neighbours (a merged flight loses an onset and a separation,
#: which can cost tens of per cent of the velocity; docs/identification.md, step 3, gives the measurement); a contact
#: that does not part but whose force stays this close to zero carries too little force for its onset row to be off
#: by more than the noise
SEPARATION_SIGMAS = 4.0


@dataclass(frozen=True, kw_only=True)
class PulseSpan:
    """Sample indices of one contact pulse within a force array.

    ``zero`` is the last sample before the pulse consistent with zero force, ``first`` the first sample above
    the detection level, ``peak`` the maximum and ``end`` the first sample after the peak back below the release
    level (-1 when the pulse is still running at the end of the data).
    """

    zero: int
    first: int
    peak: int
    end: int

    @property
    def complete(self) -> bool:
        """Whether the pulse ended within the data (``end`` is a sample index)."""
        return self.end >= 0


def detection_levels(noise: float, force_scale: float) -> tuple[float, float]:
    """(detect, release) force levels [N] for a noise standard deviation [N] and the largest force [N]."""
    sigma = max(float(noise), FLOOR_FRACTION * float(force_scale), 1e-12)
    return DETECT_SIGMAS * sigma, RELEASE_SIGMAS * sigma


# state of the compiled detector: (int) inside a pulse, length of the current run, first sample of the pulse, last
# sample at or below the release level, peak sample, lower bound of the zero sample, samples seen, zero sample,
# peak of the current run above the detection level; (float) peak force of the pulse, of the run
_INSIDE, _RUN, _FIRST, _LOW, _PEAK, _BOUND, _SEEN, _ZERO, _RUN_PEAK = range(9)
_PMAX, _RUN_MAX = range(2)
NO_EVENT, PULSE_START, PULSE_END = 0, 1, 2


@njit(cache=True)
def edge(v, detect, release, hold, inside, run):
    """One sample ``v`` [N] of the detector's hysteresis: (inside, run, whether the pulse started or ended).

    Outside a pulse, ``run`` counts consecutive samples above ``detect`` [N]; inside, consecutive samples at or
    below ``release`` [N]. When it reaches ``hold`` the pulse started (at the first sample of the run) or ended.
    """
    beyond = v > detect if inside == 0 else v <= release
    run = run + 1 if beyond else 0
    if run == hold:
        return 1 - inside, 0, True
    return inside, run, False


@njit(cache=True)
def _scan(x, detect, release, hold, istate, fstate):
    """Advance the detector over the samples ``x`` [N] up to the first pulse start or end.

    Returns (event, samples consumed). A pulse starts at the first of ``hold`` consecutive samples above
    ``detect`` [N] and ends at the first of ``hold`` consecutive samples at or below ``release`` [N]; the
    absolute indices are in the state (``_FIRST``, ``_ZERO``, ``_PEAK`` and, at an end, ``_BOUND``).
    """
    for k in range(x.shape[0]):
        v = x[k]
        index = istate[_SEEN]
        istate[_SEEN] += 1
        if istate[_INSIDE] == 0:
            if v > detect and (istate[_RUN] == 0 or v > fstate[_RUN_MAX]):
                istate[_RUN_PEAK] = index
                fstate[_RUN_MAX] = v
            elif not v > release:
                istate[_LOW] = index
        elif v > fstate[_PMAX]:
            istate[_PEAK] = index
            fstate[_PMAX] = v
        inside, istate[_RUN], changed = edge(v, detect, release, hold, istate[_INSIDE], istate[_RUN])
        istate[_INSIDE] = inside
        if changed and inside == 1:
            first = index - hold + 1
            istate[_FIRST] = first
            istate[_PEAK], fstate[_PMAX] = istate[_RUN_PEAK], fstate[_RUN_MAX]
            # the last sample consistent with zero force before the pulse, not before the bound
            istate[_ZERO] = first - 1 if first == istate[_BOUND] else max(istate[_LOW], istate[_BOUND])
            return PULSE_START, k + 1
        if changed:
            istate[_BOUND] = index - hold + 1
            istate[_LOW] = index
            return PULSE_END, k + 1
    return NO_EVENT, x.shape[0]


def _separated(gap: np.ndarray, sigma: float) -> bool:
    """Whether the force between two pulses (``gap`` [N], from the end of one to the start of the next) is
    consistent with zero: the median of its middle half within ``SEPARATION_SIGMAS``·1.25·``sigma``/√n of zero
    (n = samples there).

    The median, not the mean: the slow foot of a gentle re-contact may reach into the middle half."""
    quarter = gap.size // 4  # the middle half: away from the tail and the next foot
    middle = gap[quarter:gap.size - quarter]
    level = SEPARATION_SIGMAS * MEDIAN_EFFICIENCY * sigma / np.sqrt(max(middle.size, 1))
    return not (middle.size > 0 and np.median(middle) > level)


class PulseDetector:
    """The pulse detector in incremental form: push samples of an offset-free force, read the pulses found so far.

    Parameters
    ----------
    noise, force_scale : float
        Standard deviation of the white noise of the force [N], and the largest force [N] (which sets the
        resolution floor of the levels, :func:`detection_levels`).
    start : int
        No pulse starts before this sample.

    Notes
    -----
    Sample by sample, in a compiled kernel whose state lives in two small arrays, so the pulses do not depend on
    how the samples are chunked: fed the whole force at once it is :func:`detect_pulses`. The samples of the
    current gap between two pulses are kept (the gap test needs their median).
    """

    def __init__(self, noise: float, force_scale: float, *, start: int = 0):
        self.detect, self.release = detection_levels(noise, force_scale)
        # the gap test uses the noise itself: the resolution floor of the levels is for edges (ringing), and any
        # positive force in the middle of a gap means the bodies still touch
        self.gap_sigma = max(float(noise), 1e-6 * float(force_scale), 1e-12)
        self.start = max(int(start), 0)
        self._istate = np.zeros(9, dtype=np.int64)
        self._istate[_LOW] = -1
        self._istate[_BOUND] = self.start
        self._fstate = np.zeros(2)
        self._spans: list[list] = []  # [zero, first, peak, end (-1: running), peak force]
        self._kept: list[np.ndarray] = []  # samples since the end of the last pulse (the gap so far)

    @property
    def seen(self) -> int:
        """Samples pushed so far."""
        return int(self._istate[_SEEN])

    def push(self, chunk) -> list[PulseSpan]:
        """Feed the next samples of the force [N]; return the pulses found so far (:attr:`pulses`)."""
        x = np.asarray(chunk, dtype=float).reshape(-1)
        skip = min(max(self.start - self.seen, 0), x.size)
        self._istate[_SEEN] += skip
        x = x[skip:]
        while x.size:
            event, used = _scan(x, self.detect, self.release, HOLD, self._istate, self._fstate)
            self._kept.append(x[:used])
            if event == PULSE_START:
                self._started()
            elif event == PULSE_END:
                last = self._spans[-1]
                last[2], last[3], last[4] = int(self._istate[_PEAK]), int(self._istate[_BOUND]), self._fstate[_PMAX]
            x = x[used:]
            self._trim()
        return self.pulses

    @property
    def pulses(self) -> list[PulseSpan]:
        """The pulses found so far, the last one with ``end = -1`` while it runs."""
        return [PulseSpan(zero=zero, first=first, peak=int(self._istate[_PEAK]) if end < 0 else peak, end=end)
                for zero, first, peak, end, _ in self._spans]

    def _samples(self, start: int) -> np.ndarray:
        """The kept samples from absolute index ``start`` up to the last one seen."""
        kept = self._kept[0] if len(self._kept) == 1 else np.concatenate(self._kept)
        return kept[kept.size - (self.seen - start):]

    def _trim(self) -> None:
        """Keep the samples of the current gap, else the last ``HOLD - 1`` (a pulse edge's hold run)."""
        gap = bool(self._spans) and self._istate[_INSIDE] == 0
        keep = self.seen - int(self._spans[-1][3]) if gap else HOLD - 1
        while self._kept and sum(c.size for c in self._kept[1:]) >= keep:
            self._kept.pop(0)

    def _started(self) -> None:
        """A pulse started: a new one, or the last one again where the gap before it is not a separation."""
        first, peak, force = int(self._istate[_FIRST]), int(self._istate[_PEAK]), float(self._fstate[_PMAX])
        if self._spans:  # the last pulse has ended (a running pulse cannot be followed by a start)
            last = self._spans[-1]
            gap = self._samples(last[3])[:first - last[3]]
            if not _separated(gap, self.gap_sigma):  # the same pulse: its peak is the largest force since its
                best, best_force = last[2], last[4]  # first sample, the earliest of equal ones
                if gap.size and gap.max() > best_force:
                    best, best_force = last[3] + int(np.argmax(gap)), float(gap.max())
                if not force > best_force:
                    self._istate[_PEAK], self._fstate[_PMAX] = best, best_force
                last[3] = -1
                return
        self._spans.append([max(int(self._istate[_ZERO]), 0), first, peak, -1, force])


def detect_pulses(force: np.ndarray, noise: float, *, force_scale: float | None = None,
                  start: int = 0) -> list[PulseSpan]:
    """Contact pulses of an offset-free ``force`` [N] with white noise of standard deviation ``noise`` [N].

    A pulse starts where the force exceeds ``DETECT_SIGMAS``·σ for ``HOLD`` consecutive samples (not before
    sample ``start``) and ends where it stays at or below ``RELEASE_SIGMAS``·σ for ``HOLD`` samples. A gap between
    two pulses counts as a separation only when the force in it is consistent with zero (the median of its middle
    half within ``SEPARATION_SIGMAS``·1.25·σ/√n of zero, n = samples there); otherwise both are merged into one
    pulse. A pulse still running at the end of the data has ``end = -1``. The batch form of :class:`PulseDetector`
    (``force_scale`` [N], the largest force, defaults to that of ``force``).
    """
    f = np.asarray(force, dtype=float)
    scale = (float(np.max(np.abs(f))) if f.size else 0.0) if force_scale is None else float(force_scale)
    return PulseDetector(noise, scale, start=start).push(f)


#: a pulse whose peak rises less than ``RINGING_FACTOR`` times above the deepest the force falls below zero right
#: after it, where that is more than ``RINGING_SIGMAS`` noise σ, is ringing, not contact (:func:`without_ringing`) [-]
RINGING_FACTOR, RINGING_SIGMAS = 3.0, 4.0


def without_ringing(spans: list[PulseSpan], force: np.ndarray, noise: float) -> list[PulseSpan]:
    """The pulses of ``spans`` that are contact, not ringing: a contact only pushes, a load cell rings both ways.

    A complete pulse is left out where the force, within the pulse's own length after its end, swings below zero
    by more than ``RINGING_SIGMAS`` times the ``noise`` [N] and by more than 1/``RINGING_FACTOR`` of the pulse's
    peak (a ringing lobe is followed by a trough of about its size; a contact pulse by a flight at zero force, or
    by the anti-alias filter's undershoot of about 5 % of its rise): a 20 N blip of a striker's ringing after its
    main pulse was counted as a pulse (and made the identification wait for a second pulse that never came).
    Pulses still running at the end of the data are kept.
    """
    f = np.asarray(force, dtype=float)
    kept = []
    for span in spans:
        if span.complete:
            width = span.end - span.zero
            near = f[span.end:span.end + width + 1]
            swing = -float(near.min()) if near.size else 0.0
            if swing > RINGING_SIGMAS * noise and RINGING_FACTOR * swing > float(f[span.peak]):
                continue
        kept.append(span)
    return kept


def first_peak(force: np.ndarray, span: PulseSpan, drop: float) -> int | None:
    """Index of the first maximum of a pulse that the force then falls below by more than ``drop`` [N].

    For a complete pulse this is the sample :attr:`PulseSpan.peak` when the pulse has one hump; for a pulse that
    runs into sustained contact it is the end of the rebound part, the first force peak after the onset. None when
    the force has not yet fallen that far from any maximum.
    """
    stop = force.size if not span.complete else span.end
    f = np.asarray(force[span.first:stop], dtype=float)
    if f.size == 0:
        return None
    running = np.maximum.accumulate(f)
    fallen = np.flatnonzero(f < running - drop)
    if fallen.size == 0:
        return None
    return span.first + int(np.argmax(f[:fallen[0]]))
