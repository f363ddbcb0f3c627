"""Checks of an impact's data before an answer (refusals), and of the answer against what the data allow (warnings).

Refusals (:func:`check_segment`, run before every peak-to-peak answer): a record that begins inside the impact, a
constant acceleration over the impact (a dead accelerometer), a saturated force or acceleration channel.

Plausibility of an answer: an identification can pass its own checks and still give an answer that no drop test
can have: the channels
swapped, an acceleration in mm/s² read as m/s², a signal that is not an impact. The answer (M1, V0) is compared
with physical bounds and with the recorded force:

- velocity within the free-fall range of a drop test (:data:`impactometer.rig.VELOCITY_RANGE`); outside it, a
  unit slip (×1000, ×g) is named when undoing it gives a velocity within that range;
- mass within :data:`impactometer.rig.MASS_RANGE`, and large enough for the recorded impulse (the mass can at
  most reverse its velocity: ∫Fc dt ≤ M1·(2·V0 + g·τ) from first contact to any pulse end τ) and for the energy
  the piston took in the first pulse (∫Fc·v2 dt ≤ M1·V0²/2 + M1·g·u1, u1 the mass's travel);
- fit: relative standard errors of mass and velocity below :data:`RELATIVE_ERROR_LIMIT`; residuals far above the
  noise show here, since the robust fit scales its covariance by the reduced χ² of its equations (a reduced χ² on
  its own does not tell a wrong answer: a pad that keeps a set gives residuals hundreds of times the noise and
  an answer within 5 %);
- channels: a force channel that swings far below zero, as an acceleration does, while the acceleration channel
  never does, as a compressive contact force does, is recognised as a swap.

Every failed check gives one sentence; the sentences are the result's ``warnings`` (and the command line prints
them). The checks never change the answer; an answer that the recorded impulse contradicts outright (more than
:data:`IMPULSE_REFUSAL` times what it allows) is refused.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from ..constants import STANDARD_GRAVITY
from ..errors import IdentificationError, ParameterError
from ..rig import FREE_FALL_HEIGHTS, MASS_RANGE, PRESETS, VELOCITY_RANGE
from ..signals.pulses import detection_levels
from ..validation import check_real

#: the recorded impulse (energy) may exceed what the answer allows by this factor before a warning (noise,
#: offsets, the piston's gas and friction forces)
IMPULSE_SLACK, ENERGY_SLACK = 1.1, 1.25
#: a recorded impulse this many times what the answer allows contradicts the answer: it is refused, not warned of
IMPULSE_REFUSAL = 2.0
#: relative standard error of mass or velocity above which the answer is poorly determined
RELATIVE_ERROR_LIMIT = 0.25
#: a force channel dipping below zero by more than this fraction of its peak (and many noise σ) is suspect
SWING_FRACTION, SWING_SIGMAS = 0.05, 10.0
#: unit slips: factor by which the identified velocity comes out too large -> how it happens
VELOCITY_SLIPS = {1e3: "an acceleration in mm/s² read as m/s²", 1e-3: "an acceleration in m/s² read as mm/s²",
                  STANDARD_GRAVITY: "an acceleration in m/s² read as g",
                  1 / STANDARD_GRAVITY: "an acceleration in g read as m/s²"}
#: the unit the acceleration was in, for each slip of :data:`VELOCITY_SLIPS`
ACCELERATION_UNITS = {1e3: "mm/s^2", 1e-3: "m/s^2", STANDARD_GRAVITY: "m/s^2", 1 / STANDARD_GRAVITY: "g"}
#: how much better (in reduced χ²) an acceleration unit slip must fit to be named; as the better fit's reduced χ² is
#: taken as at least 1, a slip is looked for only where the answer's own reduced χ² reaches this
SLIP_GAIN = 25.0
#: unit slips: factor by which the identified mass comes out too large -> how it happens
MASS_SLIPS = {1e3: "a force in N read as kN", 1e-3: "a force in kN read as N"}


def check_segment(seg) -> None:
    """IdentificationError when the impact's data cannot give an answer: a record that begins inside the impact
    (:func:`check_first_contact`), a constant acceleration (a dead or disconnected accelerometer) or a saturated
    channel (:func:`check_clipping`).

    ``seg`` is a :class:`~.peak_to_peak.segment.Segment`; every answer, batch or streaming, early or final, passes this
    check first (see :func:`~.peak_to_peak.solve`).
    """
    check_first_contact(seg)
    a = seg.acceleration
    if a.size and float(np.ptp(a)) == 0.0:
        raise IdentificationError(f"piston_acceleration is constant ({float(a[0])!r} m/s² throughout the impact); "
                                  "expected a measured acceleration")
    check_clipping(seg)
    check_acceleration_sign(seg)


#: the piston and rod mass M2 [kg] a record's first pulse is compared with: the built-in stand's (peak-to-peak
#: identification does not know the stand)
ROD_MASS = PRESETS["drop-stand"].cylinder.piston_mass
#: the mass the first pulse pushes may differ from :data:`ROD_MASS` by this factor either way on a drop stand (the
#: gas and seal forces, another stand's rod) before a unit slip is looked for [-]
ROD_MASS_FACTOR = 2.5
#: the piston's velocity change over the first pulse's rise must exceed its noise this many times to be judged [-]
PUSH_SIGMAS = 8.0


def pushed_mass(seg) -> tuple[float, float, float] | None:
    """The mass [kg] the first contact pulse accelerates, from the piston's momentum balance over the pulse's rise:
    ∫Fc dt / Δv2 from the last sample at zero force to the peak, with the impulse [N·s] and Δv2 [m/s]; None where
    Δv2 is within ``PUSH_SIGMAS`` of its noise (or no pulse has risen).

    Over the short rise the gas and seal forces change little, so the contact force's impulse goes into the
    piston and rod: on the built-in stands the ratio is 4.0-5.7 kg for M2 = 4 kg (10-50 kg at 1-3 m/s, 100-400
    kPa). An acceleration in g read as m/s² makes it 9.81 times larger; an accelerometer mounted the other way,
    or one in the falling mass (a drop weight's striker, which the force slows), makes it negative.
    """
    if not seg.pulses:
        return None
    pulse = seg.pulses[0]
    lo, hi = max(pulse.zero, 0), pulse.peak
    if hi - lo < 2:
        return None
    dt = 1.0 / seg.sample_rate
    impulse = float(np.trapezoid(seg.force[lo:hi + 1], dx=dt))
    change = float(np.trapezoid(seg.acceleration[lo:hi + 1], dx=dt))
    noise = seg.noise_acceleration * dt * math.sqrt(hi - lo + 1)
    if not abs(change) > PUSH_SIGMAS * noise or not impulse > 0.0:
        return None
    return impulse / change, impulse, change


def check_acceleration_sign(seg) -> None:
    """IdentificationError when the first contact pulse slows the piston (:func:`pushed_mass` negative): an
    accelerometer mounted the other way, or a record of another machine, whose accelerometer rides on the falling
    mass (a drop weight's striker)."""
    found = pushed_mass(seg)
    if found is None or found[0] > 0.0:
        return
    mass, impulse, change = found
    what = (f"the contact force pushes with {impulse:.3g} N·s over its first rise while the acceleration channel "
            f"slows by {-change:.3g} m/s, as a mass of {-mass:.3g} kg that the contact brakes")
    if -mass <= ROD_MASS_FACTOR * ROD_MASS:
        raise IdentificationError(f"piston_acceleration reads the impact with the other sign: {what}, where it should "
                                  "speed the rod up; an accelerometer mounted the other way (pointing up): read it "
                                  "with --flip-acceleration (flip_acceleration=True); one in the falling mass (a drop "
                                  "weight's striker) reads so too, and such a record is not a drop on a gas-spring "
                                  "rod")
    raise IdentificationError(f"this record is not a drop on a gas-spring rod: {what} (an accelerometer in the falling "
                              "mass, a drop weight's striker); peak-to-peak identification needs the acceleration of "
                              "the rod the mass strikes (an accelerometer on the rod mounted the other way reads so "
                              "too: --flip-acceleration)")


def acceleration_unit_slip(seg) -> str | None:
    """A warning naming an acceleration unit slip that the piston's momentum balance shows (:func:`pushed_mass`
    :data:`ROD_MASS_FACTOR` times off the rod's mass and within that factor of a slip of
    :data:`VELOCITY_SLIPS`), or None."""
    found = pushed_mass(seg)
    if found is None or found[0] <= 0.0:
        return None
    mass = found[0]
    ratio = mass / ROD_MASS
    if 1.0 / ROD_MASS_FACTOR <= ratio <= ROD_MASS_FACTOR:
        return None
    for factor, text in VELOCITY_SLIPS.items():
        if 1.0 / ROD_MASS_FACTOR <= ratio * factor <= ROD_MASS_FACTOR:
            unit = ACCELERATION_UNITS[factor]
            return (f"the contact force's first rise speeds the piston as a mass of {mass:.3g} kg would, "
                    f"{ratio:.3g} times the {ROD_MASS:g} kg piston and rod of a drop stand: {text}? "
                    f"if so, state the acceleration's unit in the file (a column named 'acceleration [{unit}]') "
                    f"or read it with --acceleration-unit {unit}")
    return None


def check_first_contact(seg) -> None:
    """IdentificationError when a record without pre-trigger begins inside the first contact pulse.

    A record that starts at first contact (a DAQ without pre-trigger, a simulation) shows the force rise from
    zero; one whose trigger came late starts with the force already up, and first contact -- the instant every
    equation is referred to, and the momentum before it -- lies before the record: 1 ms late gave V0 4.5 % low,
    2 ms 22 %, 10 ms 87 %, with standard errors of a few tenths of a per cent. The first sample must therefore
    lie within the noise (the pulses' detection level) or below ``FIRST_SAMPLE_FRACTION`` of the pulse's peak: a
    contact that rises within a sample of the record's start, seen through a zero-phase anti-alias filter,
    starts at up to 3 % of its peak; on the pad stand a record 0.28 ms late starts at 4.4 % and gave V0 0.12 %
    (one standard error) low.
    """
    if seg.pre_samples or not seg.pulses:
        return
    first = seg.pulses[0]
    why = in_contact(float(seg.force[0]), seg.noise_force,
                     float(np.max(seg.force[:first.end if first.complete else seg.force.size])), "its first sample")
    if why:
        raise IdentificationError(why)


def in_contact(force: float, noise: float, peak: float, where: str) -> str | None:
    """Why a contact force of ``force`` [N] at ``where`` (the first sample of a record, or its t = 0) is not at
    rest -- above the pulses' detection level for the ``noise`` [N] and above ``FIRST_SAMPLE_FRACTION`` of the
    ``peak`` [N] -- and first contact came before it; None where it is at rest (:func:`check_first_contact`)."""
    detect, _ = detection_levels(noise, abs(peak))
    level = max(detect, FIRST_SAMPLE_FRACTION * peak)
    if force <= level:
        return None
    return (f"the record begins inside a contact pulse: contact_force is {force:.4g} N at {where}, "
            f"{force / peak:.1%} of the pulse's peak (at rest: at most {level:.3g} N), so first contact came before; "
            "expected a record that starts at rest, with a pre-trigger (the DAQ's trigger came late)")


#: a record without pre-trigger may start at most at this fraction of its first pulse's peak force [-]
FIRST_SAMPLE_FRACTION = 0.05
#: the unit symbol of each sensor channel, as messages print it
CHANNEL_SYMBOLS = {"contact_force": "N", "piston_acceleration": "m/s²"}


def flat_top(x: np.ndarray, noise: float, pulses, sign: int = 1) -> tuple[int, int, float, float] | None:
    """A channel clipped at its largest (``sign`` 1) or smallest (-1) value: (samples at that value from the first
    of them, that sample's index, the value, how many samples a peak of that curvature stays within the
    resolution), or None when the samples there look like a peak.

    A quantised peak may sit a few samples at one level: about 2·√(2(q + 2σ)/|x''|) samples for a quantum q, noise
    σ and the curvature x'' ≈ x_max·(π/T)² of a contact pulse of T samples (``pulses``, the force's; the whole record
    where the extreme lies in none, and then also a run that cuts a curve off, :func:`_cut_off`). A flat top twice
    that long, or the extreme reached in two different pulses to the last digit (for two samples or more in each),
    is a clipped channel. An extreme within 5 σ of zero is no top.
    """
    y = sign * np.asarray(x, dtype=float)
    top = float(np.max(y))
    if not top > 5.0 * noise:
        return None
    at_top = np.flatnonzero(y >= top - 1e-12 * abs(top))
    runs = np.split(at_top, np.flatnonzero(np.diff(at_top) != 1) + 1)
    # the longest run at the extreme (a channel clipped below the depth of several dips touches its rail for a
    # sample or two in the first ones: judged by the first run, 82 samples on the rail at 100 kHz went unseen)
    longest = max(runs, key=len)
    k, run = int(longest[0]), int(longest.size)

    def inside(p, i):
        return p.first <= i and (not p.complete or i < p.end)

    pulse = next((p for p in pulses if inside(p, k)), None)
    # pulses in which the extreme holds for two samples or more (single samples at one quantised level are chance)
    held = [int(r[0]) for r in runs if r.size >= 2]
    rails = sum(any(inside(p, i) for i in held) for p in pulses)
    length = y.size if pulse is None else (y.size if not pulse.complete else pulse.end) - pulse.zero
    curvature = top * (np.pi / max(length, 1)) ** 2
    near = y[max(k - 2 * run - 8, 0):k + 3 * run + 8]
    steps = np.diff(np.unique(near))
    quantum = float(steps.min()) if steps.size else 0.0
    expected = 2.0 * np.sqrt(2.0 * (quantum + 2.0 * noise) / curvature)
    if rails >= 2 or run >= max(3.0, 2.0 * expected):
        return run, k, sign * top, float(expected)
    if pulse is None and run >= 3 and _cut_off(y, k, run, top, noise + quantum):
        return run, k, sign * top, float(expected)
    return None


#: a flat run is cut off where the curve either side of it, extended, passes its level by this many noise σ [-]
CUT_SIGMAS = 8.0


def _cut_off(y: np.ndarray, k: int, run: int, top: float, scatter: float) -> bool:
    """Whether the flat run of ``run`` samples at ``top`` from sample ``k`` cuts a curve off: a parabola through
    as many samples either side of it rises, within the run, ``CUT_SIGMAS`` times ``scatter`` (noise plus
    quantum) above the run's level. A flight's slowly changing acceleration, quantised, holds one level for many
    samples and meets it flat; a clipped one meets its rail with the slope it had (the minimum clipped at 95 % in
    a flight at 100 kHz: 82 samples, V0 3.1 standard errors off, silently)."""
    if k - run < 0 or k + 2 * run > y.size:
        return False
    t = np.r_[np.arange(k - run, k), np.arange(k + run, k + 2 * run)].astype(float)
    centre = k + 0.5 * (run - 1)
    curve = np.polynomial.Polynomial.fit(t - centre, y[t.astype(int)], 2).convert()
    inside = np.linspace(-0.5 * (run - 1), 0.5 * (run - 1), max(run, 3))
    return float(np.max(curve(inside))) - top > CUT_SIGMAS * max(scatter, 1e-300)


def check_clipping(seg) -> None:
    """IdentificationError when a channel is saturated: the force at its largest value, the acceleration at its
    largest or smallest (:func:`flat_top`; an acceleration clipped at 80 % of its peak gave V0 10.6 % low, at 95 %
    1.3 % low, 9.5 standard errors, without a word)."""
    for name, x, noise, sign in (("contact_force", seg.force, seg.noise_force, 1),
                                 ("piston_acceleration", seg.acceleration, seg.noise_acceleration, 1),
                                 ("piston_acceleration", seg.acceleration, seg.noise_acceleration, -1)):
        found = flat_top(x, noise, seg.pulses, sign)
        if found is not None:
            run, k, level, expected = found
            extreme = "maximum" if sign > 0 else "minimum"
            raise IdentificationError(f"{name} is saturated: {run} samples sit at its {extreme} "
                                      f"{level:.6g} {CHANNEL_SYMBOLS[name]} from t = {seg.time_of(k):.6g} s (a peak "
                                      f"of that curvature stays about {expected:.1f} samples within the resolution); "
                                      "the channel was clipped, its range must be raised")


def _slip(value: float, low: float, high: float, slips: dict[float, str]) -> str:
    found = [f"{text} (×{factor:g})" for factor, text in slips.items() if low <= value / factor <= high]
    return f"; {' or '.join(found)} would give this" if found else ""


def _cumulative(x: np.ndarray, dt: float) -> np.ndarray:
    out = np.zeros_like(x)
    out[1:] = np.cumsum(0.5 * dt * (x[1:] + x[:-1]))
    return out


def check_answer(mass: float, velocity: float, *, force: np.ndarray | None = None, sample_rate: float = 1.0,
                 onset: float = 0.0, pulse_ends: Sequence[int] = (), gravity: float = STANDARD_GRAVITY,
                 noise_force: float = 0.0,
                 acceleration: np.ndarray | None = None,
                 noise_acceleration: float = 0.0, reduced_chi2: float | None = None,
                 mass_std: float | None = None, velocity_std: float | None = None) -> tuple[str, ...]:
    """Warnings (sentences) about an answer (mass [kg], velocity [m/s]) that the recorded signals make implausible.

    Parameters
    ----------
    force, acceleration : ndarray, optional
        Offset-free contact force [N] and piston acceleration [m/s²] (no force: the ranges only are checked; no
        acceleration: a force-only method).
    sample_rate : float
        [Hz].
    onset : float
        (Fractional) sample index of first contact.
    pulse_ends : list of int
        Sample indices where complete contact pulses end, in order.
    gravity : float
        [m/s²].
    noise_force, noise_acceleration : float
        Noise standard deviations [N], [m/s²].
    reduced_chi2 : float, optional
        Reduced chi-square of the fit (named in a precision warning).
    mass_std, velocity_std : float, optional
        Standard errors [kg], [m/s].
    """
    mass = check_real("mass", mass, error=ParameterError)
    velocity = check_real("velocity", velocity, error=ParameterError)
    out: list[str] = []
    low_v, high_v = VELOCITY_RANGE
    if not low_v <= velocity <= high_v:
        out.append(f"V0 = {velocity:.3g} m/s is outside the free-fall range of a drop test ({low_v:.2g}-"
                   f"{high_v:.3g} m/s, a fall of {FREE_FALL_HEIGHTS[0] * 1e3:g} mm to {FREE_FALL_HEIGHTS[1]:g} m)"
                   + _slip(velocity, low_v, high_v, VELOCITY_SLIPS if acceleration is not None else {}))
    if not MASS_RANGE[0] <= mass <= MASS_RANGE[1]:
        out.append(f"M1 = {mass:.3g} kg is outside the masses of a drop test ({MASS_RANGE[0]:g}-{MASS_RANGE[1]:g} kg)"
                   + _slip(mass, *MASS_RANGE, MASS_SLIPS))
    if force is None:
        return tuple(out)
    dt = 1.0 / sample_rate
    k0 = max(int(math.floor(onset)), 0)
    ends = [e for e in pulse_ends if k0 < e < force.size]
    if ends and mass > 0 and velocity > 0:
        impulse = _cumulative(force[k0:ends[-1] + 1], dt)
        taus = np.array([(e - onset) * dt for e in ends])
        recorded = impulse[np.array(ends) - k0]
        allowed = mass * (2.0 * velocity + gravity * taus)
        worst = int(np.argmax(recorded / allowed))
        if recorded[worst] > IMPULSE_SLACK * allowed[worst]:
            text = (f"the contact force carries {recorded[worst]:.3g} N·s within {taus[worst] * 1e3:.3g} ms of "
                    f"first contact; M1 = {mass:.3g} kg at V0 = {velocity:.3g} m/s can take at most "
                    f"{allowed[worst]:.3g} N·s (rebounding elastically): the mass or the velocity is too small")
            if recorded[worst] > IMPULSE_REFUSAL * allowed[worst]:
                raise IdentificationError(f"{text}, {recorded[worst] / allowed[worst]:.3g} times over: the answer "
                                          "is refused (the pulses found are not those of this method's model)")
            out.append(text)
        if acceleration is not None:
            out += _energy(mass, velocity, force[k0:ends[0] + 1], acceleration[k0:ends[0] + 1], dt, gravity)
    misfit = (f"; the residuals are {math.sqrt(reduced_chi2):.3g} times the noise" if reduced_chi2 is not None
              and reduced_chi2 > 4.0 else "")
    for name, value, std, unit in (("M1", mass, mass_std, "kg"), ("V0", velocity, velocity_std, "m/s")):
        if std is not None and math.isfinite(std) and value > 0 and std > RELATIVE_ERROR_LIMIT * value:
            out.append(f"{name} = {value:.3g} ± {std:.2g} {unit} is poorly determined (standard error "
                       f"{std / value:.0%} of the value{misfit})")
    if acceleration is not None:
        out += _swapped(force, acceleration, noise_force, noise_acceleration)
    return tuple(out)


def _energy(mass: float, velocity: float, force: np.ndarray, acceleration: np.ndarray, dt: float,
            gravity: float) -> list[str]:
    """The energy the piston took over the first pulse against what the mass can have given."""
    v2 = _cumulative(acceleration, dt)
    work = float(_cumulative(force * v2, dt)[-1])
    tau = (force.size - 1) * dt
    travel = velocity * tau + gravity * tau ** 2 / 2.0 - float(_cumulative(_cumulative(force, dt), dt)[-1]) / mass
    allowed = 0.5 * mass * velocity ** 2 + mass * gravity * max(travel, 0.0)
    if work > ENERGY_SLACK * allowed:
        return [f"the piston took {work:.3g} J in the first contact pulse, more than the {allowed:.3g} J an impact "
                f"of M1 = {mass:.3g} kg at V0 = {velocity:.3g} m/s brings: the mass or the velocity is too small"]
    return []


def _swapped(force: np.ndarray, acceleration: np.ndarray, noise_force: float, noise_acceleration: float) -> list[str]:
    """A force channel swinging below zero as an acceleration does, next to an acceleration that never does."""
    f_min, f_max = float(force.min()), float(force.max())
    a_min, a_max = float(acceleration.min()), float(acceleration.max())
    deep = -f_min > max(SWING_SIGMAS * noise_force, SWING_FRACTION * f_max)
    one_sided = a_max > 0 and -a_min <= max(5.0 * noise_acceleration, 0.01 * a_max)
    if deep and one_sided:
        return [f"the channels look swapped: the force swings to {f_min:.3g} N ({-f_min / f_max:.0%} of its peak) "
                f"below zero as an acceleration does, the acceleration never goes below zero as a compressive "
                "contact force does; check the channel assignment (--force-channel, --acceleration-channel)"]
    return []
