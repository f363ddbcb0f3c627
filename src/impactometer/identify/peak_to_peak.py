"""Peak-to-peak identification of the impacting mass M1 and impact velocity V0 (paper section 4).

Two variants: ``paper`` (eqs. (3)-(5) as published) and ``robust`` (default; zero relative displacement at every
contact onset, generalised least squares with propagated noise, an early and a final answer). Both work on the
same prepared segment: the first impact found by the trigger, offsets removed with the pre-trigger samples.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from ..errors import IdentificationError, RecordingError, shown
from ..recording import START_TIME_LIMIT, Recording, check_sample_rate
from . import trigger
from .early import solve_early
from .onsets import onset_index
from .plausibility import answer_warnings, check_segment
from .pulses import PulseSpan, detect_pulses, detection_levels, first_peak, noise_std
from .result import Identification
from .robust import MIN_ONSET_ROWS, Kinematics, combine, solve_onsets

GRAVITY = 9.81
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
    #: (zero, first, peak, earliest, noise) of a pulse -> its onset and standard error [samples], shared by segments
    #: cut from the same data with the same start (the early and the final answer, successive streaming estimates)
    onset_cache: dict = field(default_factory=dict, compare=False)

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


def check_options(variant: Any, gravity: Any, start_time: Any, *,
                  error: type[Exception] = IdentificationError) -> tuple[str, float, float]:
    """The options the batch and the streaming identification share, checked: variant, gravity [m/s²] within
    [0, 100], start time [s]; ``error`` naming the option otherwise."""
    if not isinstance(variant, str) or variant not in VARIANT_SOLVERS:
        raise error(f"variant must be one of {sorted(VARIANT_SOLVERS)}, got {shown(variant)}")
    for name, value, low, high, unit in (("gravity", gravity, 0.0, 100.0, "m/s²"),
                                         ("start_time", start_time, -START_TIME_LIMIT, START_TIME_LIMIT, "s")):
        if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) \
                or not low <= value <= high:
            raise error(f"{name} must be a number within [{low:g}, {high:g}] [{unit}], got {shown(value)}")
    return variant, float(gravity), float(start_time)


def run_trigger(force: np.ndarray, sample_rate: float, *, floor: float) -> np.ndarray:
    """Trigger events (code, sample index) of a record, up to the end of its first impact."""
    fstate, istate = trigger.new_state()
    events = np.empty((3 * TRIGGER_BLOCK + 2, 2), dtype=np.int64)
    quiet, longest = max(int(QUIET_TIME * sample_rate), 1), max(int(MAX_DURATION * sample_rate), 1)
    found = [np.empty((0, 2), dtype=np.int64)]
    for start in range(0, force.size, TRIGGER_BLOCK):
        n = trigger.run_trigger(force[start:start + TRIGGER_BLOCK], fstate, istate, floor, quiet, longest, events)
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
    if step <= 1e-9 * float(values[-1] - values[0]) or not np.allclose(
            np.round((values - values[0]) / step) * step, values - values[0], rtol=0, atol=1e-3 * step):
        return 0.0
    return step


def prepare(force: np.ndarray, acceleration: np.ndarray, sample_rate: float, start_time: float,
            pre: int, *, cache: dict | None = None) -> Segment:
    """Offsets and noise from the first ``pre`` samples (less the guard), then the pulses of the impact."""
    n_pre = pre - GUARD_SAMPLES
    if n_pre >= MIN_PRE_SAMPLES:
        f0, a0 = float(np.mean(force[:n_pre])), float(np.mean(acceleration[:n_pre]))
        sf, sa = float(np.std(force[:n_pre])), float(np.std(acceleration[:n_pre]))
    else:
        n_pre, f0, a0 = 0, 0.0, 0.0
        sf, sa = noise_std(force), noise_std(acceleration)
    # resolution floor: quantisation noise (step/√12), and rounding of exact (simulated) data
    sf = max(sf, quantum(force) / np.sqrt(12.0), 1e-6 * float(np.max(np.abs(force))))
    sa = max(sa, quantum(acceleration) / np.sqrt(12.0), 1e-6 * float(np.max(np.abs(acceleration))))
    f = force - f0
    a = acceleration - a0
    pulses = detect_pulses(f, sf, start=max(n_pre, 0))  # nothing before the pre-trigger statistics' end
    return Segment(f, a, sample_rate, start_time, sf, sa, max(n_pre, 0), pulses, {} if cache is None else cache)


def solve(seg: Segment, variant: str, gravity: float, *, early: Identification | None = None,
          contact_phase: bool = False) -> Identification:
    """Identify from a prepared segment with the named variant (``contact_phase``: see :func:`solve_robust`).

    The segment passes :func:`.plausibility.check_segment` first, so the batch and the streaming identification,
    their early and final answers, refuse the same data; the answer carries the warnings of
    :func:`.plausibility.answer_warnings`.
    """
    check_segment(seg)
    if variant == "robust":
        result = solve_robust(seg, gravity, early, contact_phase=contact_phase)
    else:
        result = VARIANT_SOLVERS[variant](seg, gravity, early)
    return replace(result, warnings=answer_warnings(seg, result, gravity))


def _need_pulses(seg: Segment, needed: int, what: str) -> None:
    complete = [p for p in seg.pulses if p.complete]
    if not seg.pulses:
        raise IdentificationError("no impact found: the contact force never leaves its noise "
                                  f"(noise {seg.noise_force:.3g} N); expected at least one contact pulse")
    if len(complete) < needed:
        last = seg.pulses[-1]
        span = (last.first - seg.pulses[0].first) / max(len(seg.pulses) - 1, 1) if len(seg.pulses) > 1 else None
        more = "" if span is None else (f"; about {span / seg.sample_rate * 1e3 * (needed - len(complete)):.1f} "
                                        "ms more signal is needed")
        raise IdentificationError(f"{what} needs {needed} complete contact pulses, the record holds "
                                  f"{len(complete)} (it ends at {seg.time_of(seg.force.size - 1):.6g} s){more}")


def solve_paper(seg: Segment, gravity: float, early=None) -> Identification:
    """Eqs. (3)-(5) of the reference paper and the momentum step for V0.

    t00 = first contact, t01/t11 = force peaks of the first two pulses; M1 = −∫Fc / ((V2(t11) − V2(t01)) −
    g·Δt) (eq. 4), V2 = ∫a2 from t00 (eq. 5), V0 = V2(t01) + ∫_{t00}^{t01}Fc/M1 − g·(t01 − t00).
    """
    peak2 = second_peak(seg)
    if peak2 is None:
        _need_pulses(seg, 2, "the paper variant")
        raise IdentificationError("the paper variant needs the second force peak: the second pulse has not yet "
                                  "fallen from a maximum")
    p1 = seg.pulses[0]
    t00, _ = segment_onset(seg, p1)
    kin = Kinematics(seg.force, seg.acceleration, 1.0 / seg.sample_rate, t00, gravity)
    tau, _, jf, _, _, va, _ = kin.at(np.array([p1.peak, peak2], dtype=float))
    denominator = (va[1] - va[0]) - gravity * (tau[1] - tau[0])
    impulse = jf[1] - jf[0]
    if not denominator < 0.0 or impulse <= 0.0:
        raise IdentificationError(f"the paper's eq. (4) has no positive mass here: ∫Fc = {impulse:.4g} N·s, "
                                  f"ΔV2 − gΔt = {denominator:.4g} m/s (expected < 0)")
    mass = -impulse / denominator
    velocity = va[0] + jf[0] / mass - gravity * tau[0]
    _check_velocity(velocity, "the paper's eqs. (3)-(5)")
    details: dict[str, Any] = {"noise_force_N": seg.noise_force, "noise_acceleration_m_s2": seg.noise_acceleration}
    caution = paper_caution(seg)
    if caution:
        details["caution"] = caution
    return Identification(mass=float(mass), velocity=float(velocity), available_at=seg.time_of(peak2),
                          t00=seg.time_of(t00), t01=seg.time_of(p1.peak), t11=seg.time_of(peak2),
                          variant="paper", details=details)


def _check_velocity(velocity: float, source: str) -> None:
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


#: noise, as a fraction of a channel's peak, above which the paper variant's answer carries a caution [-]
PAPER_NOISE_LIMIT = 0.005


def paper_caution(seg: Segment) -> str | None:
    """A caution when the paper's assumption of noise-free channels is visibly violated, else None."""
    force = seg.noise_force / max(float(np.max(np.abs(seg.force))), 1e-300)
    acceleration = seg.noise_acceleration / max(float(np.max(np.abs(seg.acceleration))), 1e-300)
    if max(force, acceleration) <= PAPER_NOISE_LIMIT:
        return None
    return (f"eqs. (3)-(5) read single samples at the force peaks and assume noise-free channels; here the noise "
            f"is {force:.1%} of the peak force and {acceleration:.1%} of the peak acceleration, so this answer "
            "may be far off (the robust variant accounts for the noise)")


def segment_onset(seg: Segment, pulse: PulseSpan) -> tuple[float, float]:
    """Sub-sample onset and its standard error [samples] of a pulse of the segment (cached)."""
    k = next((i for i, p in enumerate(seg.pulses) if p.first == pulse.first), 0)
    earliest = seg.pulses[k - 1].end if k > 0 else 0
    key = (pulse.zero, pulse.first, pulse.peak, earliest, seg.noise_force)
    if key not in seg.onset_cache:
        seg.onset_cache[key] = onset_index(seg.force, pulse, seg.noise_force, earliest=earliest)
    return seg.onset_cache[key]


def _onsets(seg: Segment, pulses) -> tuple[np.ndarray, np.ndarray]:
    pairs = [segment_onset(seg, p) for p in pulses]
    return np.array([p[0] for p in pairs]), np.array([p[1] for p in pairs])


def solve_robust(seg: Segment, gravity: float, early: Identification | None = None, *,
                 contact_phase: bool = False) -> Identification:
    """Zero relative displacement at every complete pulse's onset; GLS with propagated noise (module notes).

    With only two separated pulses the contact phase gives the answer (:mod:`early`). With ``contact_phase`` the
    onset answer is combined with the contact-phase fit of the first two pulses (best linear unbiased, with the
    shared acceleration noise): on the built-in stand at 5 % noise this lowers the velocity error by a third
    and leaves the mass error about as it is, at the price of depending on the contact-law family.
    """
    pulses = [p for p in seg.pulses if p.complete]
    if len(pulses) < 2 and early_ready(seg):  # the second pulse is past its peak: enough for the contact phase
        pulses = [pulses[0], replace(seg.pulses[1], end=seg.force.size)]
    _need_pulses(seg, 2 - (len(pulses) >= 2), "the robust variant")
    onsets, stds = _onsets(seg, pulses)
    kin = Kinematics(seg.force, seg.acceleration, 1.0 / seg.sample_rate, onsets[0], gravity, onset_std0=stds[0])
    common: dict[str, Any] = dict(
        t00=seg.time_of(onsets[0]), t01=seg.time_of(pulses[0].peak), t11=seg.time_of(pulses[1].peak),
        variant="robust", onsets=tuple(seg.time_of(o) for o in onsets),
        available_at=seg.time_of(min(pulses[-1].end, seg.force.size - 1)))
    noise = dict(noise_force=seg.noise_force, noise_acceleration=seg.noise_acceleration,
                 pre_samples=seg.pre_samples)
    if len(pulses) - 1 >= MIN_ONSET_ROWS:
        theta, cov, chi2, dof, sens = solve_onsets(kin, onsets[1:], stds[1:], **noise)
        rows = len(pulses) - 1
        if contact_phase:
            contact = solve_early(kin, pulses[:2], onsets[1], stds[1], **noise)
            theta, cov = combine((theta, cov, sens), (contact[0], contact[1], contact[4]),
                                 noise_acceleration=seg.noise_acceleration, pre_samples=seg.pre_samples,
                                 dt=kin.dt)
    else:
        theta, cov, chi2, dof, _ = solve_early(kin, pulses[:2], onsets[1], stds[1], **noise)
        rows = -1
    velocity, w = float(theta[0]), float(theta[1])
    if not (w > 0.0 and math.isfinite(w)) or not math.isfinite(velocity):
        raise IdentificationError(f"the onset equations give no positive mass (1/M1 = {w:.4g} 1/kg); the pulses "
                                  "found are not contact separations of a falling mass")
    _check_velocity(velocity, "the onset equations")
    mass = 1.0 / w
    return Identification(mass=mass, velocity=velocity, mass_std=float(np.sqrt(cov[1, 1])) / w ** 2,
                          velocity_std=float(np.sqrt(cov[0, 0])), early=early,
                          details={"onset_rows": rows, "chi2": chi2, "dof": dof, "noise_force_N": seg.noise_force,
                                   "noise_acceleration_m_s2": seg.noise_acceleration,
                                   "pre_trigger_samples": seg.pre_samples}, **common)


VARIANT_SOLVERS = {"robust": solve_robust, "paper": solve_paper}


def _segment_bounds(force: np.ndarray, sample_rate: float) -> tuple[int, int, list[int], int]:
    """First impact: (start, stop) sample indices of its segment and the pulse-end indices in it."""
    events = run_trigger(force, sample_rate, floor=TRIGGER_FLOOR)
    trig = [int(i) for c, i in events if c == trigger.EVENT_TRIGGER]
    if not trig:
        raise IdentificationError("no impact found: the contact force never leaves its noise; expected at least "
                                  "one contact pulse")
    if trig[0] <= trigger.WARM_SAMPLES:  # fired at the first chance: no quiet history before the impact
        return 0, _first_close(events, trig[0], force.size), _pulse_ends(events, trig[0], force.size), 0
    start = max(trig[0] - PRE_SAMPLES, 0)
    stop = _first_close(events, trig[0], force.size)
    return start, stop, _pulse_ends(events, trig[0], stop), trig[0] - start


def _first_close(events, trig: int, size: int) -> int:
    closes = [int(i) for c, i in events if c == trigger.EVENT_CLOSE and i > trig]
    return closes[0] + 1 if closes else size


def _pulse_ends(events, trig: int, stop: int) -> list[int]:
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


def early_answer(cut: Segment | None, gravity: float) -> Identification | None:
    """The robust answer from the data up to the second pulse, or None when that data allows none."""
    if cut is None:
        return None
    try:
        return solve(cut, "robust", gravity)
    except IdentificationError:
        return None


def identify_arrays(force, acceleration, sample_rate: float, start_time: float = 0.0, *, variant: str = "robust",
                    gravity: float = GRAVITY, contact_phase: bool = False) -> Identification:
    """Identify M1 and V0 from contact force [N] and kinematic piston acceleration [m/s²] arrays.

    Parameters
    ----------
    force, acceleration : array_like
        Contact force [N] (positive in compression) and piston acceleration [m/s²] (down, gravity removed).
    sample_rate : float
        Sample rate [Hz].
    start_time : float
        Time of the first sample [s].
    variant : {"robust", "paper"}
        The robust method (default) or eqs. (3)-(5) of the reference paper.
    gravity : float
        Gravitational acceleration [m/s²].
    contact_phase : bool
        ``robust`` only: combine the onset equations with the contact-phase fit of the first two pulses
        (see :func:`solve_robust`).

    Returns
    -------
    Identification
        For ``robust`` with an ``early`` answer (data up to the end of the second pulse).

    Notes
    -----
    The first impact in the data is used: the trigger finds it, up to ``PRE_SAMPLES`` samples before it give the
    offsets and noise of both channels, and it ends after ``QUIET_TIME`` without contact or ``MAX_DURATION``.
    """
    variant, gravity, start_time = check_options(variant, gravity, start_time)
    f, a, fs = check_channels(force, acceleration, sample_rate)
    start, stop, ends, pre = _segment_bounds(f, fs)
    seg = segment_of(f, a, fs, float(start_time), start, stop, pre, {})
    early = None
    if variant == "robust":
        early = early_answer(early_cut(f, a, fs, float(start_time), start, ends, pre, seg.onset_cache), gravity)
    return solve(seg, variant, gravity, early=early, contact_phase=contact_phase)


def identify(recording: Recording, *, variant: str = "robust", gravity: float = GRAVITY,
             contact_phase: bool = False) -> Identification:
    """Identify M1 and V0 from a :class:`~impactometer.recording.Recording` (see :func:`identify_arrays`)."""
    if not isinstance(recording, Recording):
        raise IdentificationError(f"recording must be a Recording, got {type(recording).__name__}")
    channels = {}
    for name in ("contact_force", "piston_acceleration"):
        try:
            channels[name] = recording.channel(name)
        except RecordingError:
            raise IdentificationError(f"{recording.source}: channel {name!r} is missing; peak-to-peak needs "
                                      f"contact_force and piston_acceleration, found {sorted(recording.channels)}"
                                      ) from None
    return identify_arrays(channels["contact_force"], channels["piston_acceleration"], recording.sample_rate,
                           recording.start_time, variant=variant, gravity=gravity, contact_phase=contact_phase)
