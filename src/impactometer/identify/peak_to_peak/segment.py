"""One impact cut from a record and prepared for identification: trigger, offsets, noise, pulses, edge times.

Shared by the batch (:mod:`peak_to_peak`) and the streaming (:mod:`streaming`) identification: the compiled
trigger finds the impact, up to ``PRE_SAMPLES`` samples before it give the offsets and the noise of both channels,
the pulses are detected and their onsets, separations and the turning points of the force located.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ...errors import IdentificationError
from ...recording import check_sample_rate
from ...signals import trigger
from ...signals.extrema import smoothing_margin, turning_points, vertex, vertex_reach
from ...signals.noise import mains_hum, quiet_noise_std, robust_noise_std
from ...signals.pulses import (
    RELEASE_SIGMAS,
    PulseSpan,
    detect_pulses,
    detection_levels,
    first_peak,
    without_ringing,
)
from ...signals.stage_b import SUSTAINED_FACTOR, sustained_index
from .onsets import onset_index, separation_index

#: pre-trigger samples kept before the trigger (offsets and noise come from them): the residual acceleration
#: offset, double-integrated, is the largest error of the final answer, so keep up to 0.1 s at 50 kHz
PRE_SAMPLES = 5000
#: samples next to the trigger left out of the pre-trigger statistics (the foot of the first rise)
GUARD_SAMPLES = 32
#: fewest pre-trigger samples for removing offsets
MIN_PRE_SAMPLES = 32
#: smallest trigger level [N]: exact (simulated) records have no noise to set one
TRIGGER_FLOOR = 1e-9
#: quiet spell that ends an impact [s] (a mass rebounding at 1.5 m/s is airborne for 0.3 s) and longest impact [s]
QUIET_TIME = 0.3
MAX_DURATION = 1.0
#: the impact's own noise estimate replaces the pre-trigger's when it is this much larger [-]
NOISE_GROWTH = 1.5
#: turning points of the force are found on a moving average over this fraction of the first pulse [1/-]
SMOOTH_PER_PULSE = 16


@dataclass(frozen=True)
class Segment:
    """One impact cut from the data: offset-free channels and what was learnt while preparing them."""

    force: np.ndarray
    acceleration: np.ndarray
    sample_rate: float
    start_time: float
    noise_force: float
    noise_acceleration: float
    pre_samples: int
    pulses: list[PulseSpan]
    #: (kind, span indices, search limit, noise) of a pulse edge -> its time and standard error [samples], shared by
    #: segments cut from the same data with the same start (the early and the final answer, streaming estimates)
    onset_cache: dict = field(default_factory=dict, compare=False)
    #: largest lag-1 autocorrelation of the pre-trigger noise of the two channels (0: white or not known) [-]
    noise_correlation: float = 0.0

    def time_of(self, index: float) -> float:
        """Time [s] of a (fractional) sample index of the segment."""
        return self.start_time + float(index) / self.sample_rate


def check_channels(force, acceleration, sample_rate) -> tuple[np.ndarray, np.ndarray, float]:
    """Validate the two channels; IdentificationError naming what is wrong."""
    sample_rate = check_sample_rate(sample_rate, error=IdentificationError)
    if acceleration is None:
        raise IdentificationError("the piston acceleration channel is missing; peak-to-peak needs contact force "
                                  "and piston acceleration")
    try:
        f = np.asarray(force, dtype=float)
        a = np.asarray(acceleration, dtype=float)
    except (TypeError, ValueError):
        raise IdentificationError("force and acceleration must be arrays of numbers") from None
    for name, x in (("contact_force", f), ("piston_acceleration", a)):
        if x.ndim != 1:
            raise IdentificationError(f"{name} must be a 1-D array, got shape {x.shape}")
        bad = np.flatnonzero(~np.isfinite(x))
        if bad.size:
            raise IdentificationError(f"{name} has a non-finite sample ({x[bad[0]]!r}) at index {int(bad[0])}; "
                                      "expected finite numbers")
    if f.size != a.size:
        raise IdentificationError(f"contact_force and piston_acceleration must have equal lengths, got {f.size} "
                                  f"and {a.size} samples")
    if f.size < 8:
        raise IdentificationError(f"the record has {f.size} samples; expected at least 8")
    return f, a, float(sample_rate)


#: samples the batch trigger advances at a time: its event buffer stays small whatever the record's length
TRIGGER_BLOCK = 1 << 16


def trigger_events(force: np.ndarray, sample_rate: float, *, floor: float) -> np.ndarray:
    """Trigger events (code, sample index) of a record, up to the end of its first impact."""
    fstate, istate = trigger.new_state()
    events = np.empty((3 * TRIGGER_BLOCK + 2, 2), dtype=np.int64)
    quiet, longest = max(int(QUIET_TIME * sample_rate), 1), max(int(MAX_DURATION * sample_rate), 1)
    found = [np.empty((0, 2), dtype=np.int64)]
    for start in range(0, force.size, TRIGGER_BLOCK):
        n = trigger.run_trigger(force[start:start + TRIGGER_BLOCK], fstate, istate, floor, quiet, longest,
                                trigger.baseline_samples(sample_rate), events)
        found.append(events[:n].copy())
        if np.any(events[:n, 0] == trigger.EVENT_CLOSE):  # the first impact is over (a close follows a trigger)
            break
    return np.concatenate(found)


def quantum(x: np.ndarray) -> float:
    """Step of a quantised channel (the smallest difference between its distinct values, when they all lie on
    a grid of that step), or 0 for continuous values."""
    values = np.unique(x)
    if values.size < 3:
        return 0.0
    step = float(np.min(np.diff(values)))
    offsets = values - values[0]
    if step <= 1e-9 * float(offsets[-1]) or not np.allclose(np.round(offsets / step) * step, offsets, rtol=0,
                                                            atol=1e-3 * step):
        return 0.0
    return step


def quiet_samples(force: np.ndarray, acceleration: np.ndarray, pre: int) -> int:
    """How many of the ``pre`` samples before the trigger give the offsets and the noise: all but the last
    ``GUARD_SAMPLES``, and none from the foot of the first rise on.

    The trigger fires ``TRIGGER_SIGMAS`` noise σ above the baseline, a fixed time into the rise of the contact
    whatever the sample rate: at 2 MHz the foot spans hundreds of samples, far more than the guard, and its slow
    rise, read as noise, would make white noise look low-pass filtered (a lag-1 correlation near 0.8). In each
    channel the foot starts after the last sample at which the mean of the ``GUARD_SAMPLES`` samples up to it lay
    within ``RELEASE_SIGMAS`` of their noise of the level before (the median of the first half of the window; σ
    from second differences, which a smooth rise hardly has); the earlier foot of the two channels ends the window.
    """
    guarded = pre - GUARD_SAMPLES
    if guarded < MIN_PRE_SAMPLES:
        return guarded
    end = guarded
    for x in (force, acceleration):
        head = np.asarray(x[:pre], dtype=float)
        level = float(np.median(head[:pre // 2]))
        mean = np.convolve(head - level, np.full(GUARD_SAMPLES, 1.0 / GUARD_SAMPLES), mode="valid")
        quiet = np.flatnonzero(mean <= RELEASE_SIGMAS * robust_noise_std(head) / np.sqrt(GUARD_SAMPLES))
        end = min(end, int(quiet[-1]) + GUARD_SAMPLES if quiet.size else 0)  # past the last quiet mean
    return end


def prepare(force: np.ndarray, acceleration: np.ndarray, sample_rate: float, start_time: float,
            pre: int, *, cache: dict | None = None) -> Segment:
    """Offsets and noise from the first ``pre`` samples (less the guard and the foot of the first rise,
    :func:`quiet_samples`), a mains hum they show removed (:func:`~impactometer.signals.noise.mains_hum`), then
    the pulses of the impact."""
    n_pre = quiet_samples(force, acceleration, pre)
    correlation = 0.0
    steps = quantum(force), quantum(acceleration)
    if n_pre >= MIN_PRE_SAMPLES:  # a mains hum the pre-trigger shows is removed from the whole segment
        hums = [mains_hum(x[:n_pre], sample_rate, x.size) for x in (force, acceleration)]
        force, acceleration = (x if hum is None else x - hum for x, hum in zip((force, acceleration), hums,
                                                                                 strict=True))
        f0, a0 = float(np.mean(force[:n_pre])), float(np.mean(acceleration[:n_pre]))
        sf, sa = float(quiet_noise_std(force[:n_pre])), float(quiet_noise_std(acceleration[:n_pre]))
        # the impact's own noise (median second difference) where it is clearly larger than the pre-trigger's
        sf = _larger_noise(sf, force[n_pre:])
        sa = _larger_noise(sa, acceleration[n_pre:])
        correlation = max(lag_correlation(force[:n_pre]), lag_correlation(acceleration[:n_pre]))
    else:
        n_pre, f0, a0 = 0, 0.0, 0.0
        sf, sa = robust_noise_std(force), robust_noise_std(acceleration)
    # resolution floor: quantisation noise (step/√12), and rounding of exact (simulated) data
    sf = max(sf, steps[0] / np.sqrt(12.0), 1e-6 * float(np.max(np.abs(force))))
    sa = max(sa, steps[1] / np.sqrt(12.0), 1e-6 * float(np.max(np.abs(acceleration))))
    f = force - f0
    a = acceleration - a0
    # nothing before the pre-trigger statistics' end; ringing is no contact
    pulses = without_ringing(detect_pulses(f, sf, start=max(n_pre, 0)), f, sf)
    return Segment(f, a, sample_rate, start_time, sf, sa, max(n_pre, 0), pulses, {} if cache is None else cache,
                   correlation)


def _larger_noise(pre: float, signal: np.ndarray) -> float:
    own = robust_noise_std(signal)
    return own if pre > 0 and own > NOISE_GROWTH * pre else pre


def lag_correlation(x: np.ndarray) -> float:
    """Lag-1 autocorrelation of ``x`` about its mean (0 for a constant): about 0 for white noise, near 1 for
    noise that a low-pass filter has smoothed."""
    y = np.asarray(x, dtype=float) - float(np.mean(x))
    power = float(y @ y)
    return float(y[1:] @ y[:-1]) / power if power > 0 else 0.0


#: a force that dips this many times its noise below its level at the start of the record, and further than it
#: rises, reads as inverted [-]
INVERTED_SIGMAS = 10.0


def inverted_dip(force: np.ndarray, noise: float | None = None) -> tuple[float, float] | None:
    """(the force's deepest dip below its level before the impact [N], its noise σ [N]) where the force reads the
    contact with the other sign (it falls ``INVERTED_SIGMAS`` times its noise and more than twice as far as it
    rises); else None."""
    x = np.asarray(force, dtype=float)
    noise = robust_noise_std(x) if noise is None else noise
    centre = float(np.median(x[: max(x.size // 10, 1)])) if x.size else 0.0  # the level before the impact
    low, high = (float(np.min(x)) - centre, float(np.max(x)) - centre) if x.size else (0.0, 0.0)
    return (low, noise) if -low > INVERTED_SIGMAS * noise and -low > 2.0 * max(high, 0.0) else None


def no_impact(force: np.ndarray, noise: float | None = None) -> IdentificationError:
    """The error for a record in which no contact pulse was found, naming the likely slip: a force channel of the
    wrong sign (a load cell in tension) shows the impact as deep negative pulses."""
    noise = robust_noise_std(np.asarray(force, dtype=float)) if noise is None else noise
    text = f"no impact found: the contact force never leaves its noise (noise {noise:.3g} N)"
    dip = inverted_dip(force, noise)
    if dip is not None:
        low = dip[0]
        return IdentificationError(f"{text} upwards, but it falls to {low:.4g} N ({-low / max(noise, 1e-300):.3g} "
                                   "times its noise): the force channel reads the contact with the other sign (a "
                                   "load cell in tension?); read it with --flip-force (flip_force=True)")
    return IdentificationError(f"{text}; expected at least one contact pulse")


def segment_bounds(force: np.ndarray, sample_rate: float) -> tuple[int, int, list[int], int]:
    """First impact: (start, stop) sample indices of its segment and the pulse-end indices in it."""
    events = trigger_events(force, sample_rate, floor=TRIGGER_FLOOR)
    trig = [int(i) for c, i in events if c == trigger.EVENT_TRIGGER]
    if not trig:
        raise no_impact(force)
    if trig[0] <= trigger.WARM_SAMPLES:  # fired at the first chance: no quiet history before the impact
        return 0, first_close(events, trig[0], force.size), pulse_ends(events, trig[0], force.size), 0
    start = max(trig[0] - PRE_SAMPLES, 0)
    stop = first_close(events, trig[0], force.size)
    return start, stop, pulse_ends(events, trig[0], stop), trig[0] - start


def first_close(events, trig: int, size: int) -> int:
    closes = [int(i) for c, i in events if c == trigger.EVENT_CLOSE and i > trig]
    return closes[0] + 1 if closes else size


def pulse_ends(events, trig: int, stop: int) -> list[int]:
    """Samples after which an answer may have become possible: pulse ends and pulses past their peak."""
    codes = (trigger.EVENT_PULSE_END, trigger.EVENT_PAST_PEAK)
    return sorted({int(i) for c, i in events if c in codes and trig < i < stop})


def segment_of(force, acceleration, sample_rate, start_time, start, stop, pre, cache=None) -> Segment:
    """Prepared segment [start, stop) of the arrays."""
    return prepare(force[start:stop], acceleration[start:stop], sample_rate, start_time + start / sample_rate, pre,
                   cache=cache)


def early_ready(seg: Segment) -> bool:
    """Whether the segment holds a complete first pulse and a second one past its peak (the early answer)."""
    p = seg.pulses
    return len(p) >= 2 and p[0].complete and (
        p[1].complete or seg.force[-1] < trigger.PAST_PEAK_FRACTION * seg.force[p[1].peak])


def early_cut(force, acceleration, sample_rate, start_time, start, ends, pre, cache=None) -> Segment | None:
    """The segment up to the first event after which the early answer is possible (None if never)."""
    for end in ends:
        seg = segment_of(force, acceleration, sample_rate, start_time, start, end + 1, pre, cache)
        if early_ready(seg):
            return seg
    return None


def segment_onset(seg: Segment, pulse: PulseSpan) -> tuple[float, float]:
    """Sub-sample onset and its standard error [samples] of a pulse of the segment (cached)."""
    k = next((i for i, p in enumerate(seg.pulses) if p.first == pulse.first), 0)
    earliest = seg.pulses[k - 1].end if k > 0 else 0
    key = ("onset", pulse.zero, pulse.first, pulse.peak, earliest, seg.noise_force)
    if key not in seg.onset_cache:
        seg.onset_cache[key] = onset_index(seg.force, pulse, seg.noise_force, earliest=earliest)
    return seg.onset_cache[key]


def segment_separation(seg: Segment, pulse: PulseSpan) -> tuple[float, float]:
    """Sub-sample separation (end of contact) and its standard error [samples] of a complete pulse (cached)."""
    k = next((i for i, p in enumerate(seg.pulses) if p.first == pulse.first), 0)
    latest = seg.pulses[k + 1].zero if k + 1 < len(seg.pulses) else seg.force.size - 1
    scale = float(np.max(np.abs(seg.force)))
    key = ("separation", pulse.first, pulse.peak, pulse.end, latest, seg.noise_force, scale)
    if key not in seg.onset_cache:
        seg.onset_cache[key] = separation_index(seg.force, pulse, seg.noise_force, latest=latest,
                                                force_scale=scale)
    return seg.onset_cache[key]


def edges(seg: Segment, pulses) -> tuple[np.ndarray, np.ndarray]:
    """Onsets of ``pulses`` and their standard errors [samples]."""
    pairs = [segment_onset(seg, p) for p in pulses]
    return np.array([p[0] for p in pairs]), np.array([p[1] for p in pairs])


def extrema(seg: Segment) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """Turning points of the force in every pulse: (sub-sample times [samples], standard errors [samples],
    whether each lies in sustained contact (stage B), samples between the first and last of those).

    Stage B is the first pulse that lasts longer than ``SUSTAINED_FACTOR`` times the longest bounce before it
    (:func:`~impactometer.signals.stage_b.sustained_index`). The force is smoothed over ``1/SMOOTH_PER_PULSE`` of
    the first pulse's duration to find the turning points (:func:`~impactometer.signals.extrema.turning_points`),
    which a cubic then places to a fraction of a sample (:func:`~impactometer.signals.extrema.vertex`).
    """
    sustained = sustained_index(seg.pulses, size=seg.force.size, factor=SUSTAINED_FACTOR)
    first = seg.pulses[0]
    width = max(((first.end if first.complete else seg.force.size) - first.zero) // SMOOTH_PER_PULSE, 1)
    times, stds, stage = [], [], []
    most = vertex_reach(seg.sample_rate)
    for k, pulse in enumerate(seg.pulses):
        hi = pulse.end if pulse.complete else seg.force.size
        key = ("extrema", pulse.zero, hi, width, seg.noise_force)
        if key not in seg.onset_cache:
            found = []
            for centre, sign, swing in turning_points(seg.force, pulse.zero, hi, seg.noise_force, width):
                # the samples the vertex fit may read: a key that changes until they have all arrived
                reach = min(seg.force.size, centre + most + smoothing_margin(width, most))
                point = ("vertex", centre, sign, round(swing, 6), width, seg.noise_force, reach)
                if point not in seg.onset_cache:
                    seg.onset_cache[point] = vertex(seg.force, centre, sign, swing, seg.noise_force, width, most)
                if seg.onset_cache[point] is not None:
                    found.append(seg.onset_cache[point][:2])
            seg.onset_cache[key] = found
        for t, std in seg.onset_cache[key]:
            times.append(t)
            stds.append(std)
            stage.append(k == sustained)
    stage_arr = np.array(stage, dtype=bool)
    inside = np.array(times)[stage_arr] if stage_arr.any() else np.zeros(0)
    span = int(inside[-1] - inside[0]) if inside.size > 1 else 0
    return np.array(times), np.array(stds), stage_arr, span


def single_contact(seg: Segment) -> bool:
    """Whether the segment holds one contact that has not ended: the mass never left the rod (no rebound, stage B
    from first contact, as a heavy mass on a soft charge does), so the force's turning points are all there is."""
    return len(seg.pulses) == 1 and not seg.pulses[0].complete


def need_pulses(seg: Segment, needed: int, what: str) -> None:
    complete = [p for p in seg.pulses if p.complete]
    if not seg.pulses:
        raise no_impact(seg.force, seg.noise_force)
    if len(complete) < needed:
        last = seg.pulses[-1]
        span = (last.first - seg.pulses[0].first) / max(len(seg.pulses) - 1, 1) if len(seg.pulses) > 1 else None
        more = "" if span is None else (f"; about {span / seg.sample_rate * 1e3 * (needed - len(complete)):.1f} "
                                        "ms more signal is needed")
        raise IdentificationError(f"{what} needs {needed} complete contact pulses, the record holds "
                                  f"{len(complete)} (it ends at {seg.time_of(seg.force.size - 1):.6g} s){more}")


def check_velocity(velocity: float, source: str) -> None:
    """IdentificationError unless an impact velocity is positive (the mass falls onto the rod)."""
    if not (math.isfinite(velocity) and velocity > 0.0):
        raise IdentificationError(f"{source} give an impact velocity of {float(velocity):.4g} m/s, not a falling "
                                  "mass; the pulses found are not contact separations of a falling mass")


def second_peak(seg: Segment) -> int | None:
    """Sample of the second force peak of eqs. (3)-(5) (None while there is none): the peak of a complete second
    pulse, or the first peak of a second pulse that runs into sustained contact (stage B)."""
    if len(seg.pulses) < 2 or not seg.pulses[0].complete:
        return None
    detect, _ = detection_levels(seg.noise_force, float(np.max(seg.force)))
    return first_peak(seg.force, seg.pulses[1], detect)
