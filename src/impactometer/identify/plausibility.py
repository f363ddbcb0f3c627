"""Checks of an impact's data before an answer (refusals), and of the answer against what the data allow (warnings).

Refusals (:func:`check_segment`, run before every peak-to-peak answer): a constant acceleration over the impact
(a dead accelerometer), a saturated force channel.

Plausibility of an answer: an identification can pass its own checks and still give an answer that no drop test
can have: the channels
swapped, an acceleration in mm/s² read as m/s², a signal that is not an impact. The answer (M1, V0) is compared
with physical bounds and with the recorded force:

- velocity within the free-fall range of a drop test (:data:`impactometer.stands.VELOCITY_RANGE`); outside it, a
  unit slip (×1000, ×g) is named when undoing it gives a velocity within that range;
- mass within :data:`impactometer.stands.MASS_RANGE`, and large enough for the recorded impulse (the mass can at
  most reverse its velocity: ∫Fc dt ≤ M1·(2·V0 + g·τ) from first contact to any pulse end τ) and for the energy
  the piston took in the first pulse (∫Fc·v2 dt ≤ M1·V0²/2 + M1·g·u1, u1 the mass's travel);
- fit: relative standard errors of mass and velocity below :data:`RELATIVE_ERROR_LIMIT`; residuals far above the
  noise show here, since the robust fit scales its covariance by the reduced χ² of its equations (a reduced χ² on
  its own does not tell a wrong answer: a pad that keeps a set gives residuals hundreds of times the noise and
  an answer within 5 %);
- channels: a force channel that swings far below zero, as an acceleration does, while the acceleration channel
  never does, as a compressive contact force does, is recognised as a swap.

Every failed check gives one sentence; the sentences are the result's ``warnings`` (and the command line prints
them). The checks never change the answer.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from ..constants import STANDARD_GRAVITY
from ..errors import IdentificationError, ParameterError
from ..stands import FREE_FALL_HEIGHTS, MASS_RANGE, VELOCITY_RANGE
from ..validation import check_real

#: the recorded impulse (energy) may exceed what the answer allows by this factor before a warning (noise,
#: offsets, the piston's gas and friction forces)
IMPULSE_SLACK, ENERGY_SLACK = 1.1, 1.25
#: relative standard error of mass or velocity above which the answer is poorly determined
RELATIVE_ERROR_LIMIT = 0.25
#: a force channel dipping below zero by more than this fraction of its peak (and many noise σ) is suspect
SWING_FRACTION, SWING_SIGMAS = 0.05, 10.0
#: unit slips: factor by which the identified velocity comes out too large -> how it happens
VELOCITY_SLIPS = {1e3: "an acceleration in mm/s² read as m/s²", 1e-3: "an acceleration in m/s² read as mm/s²",
                  STANDARD_GRAVITY: "an acceleration in m/s² read as g",
                  1 / STANDARD_GRAVITY: "an acceleration in g read as m/s²"}
#: how much better (in reduced χ²) an acceleration unit slip must fit to be named; as the better fit's reduced χ² is
#: taken as at least 1, a slip is looked for only where the answer's own reduced χ² reaches this
SLIP_GAIN = 25.0
#: unit slips: factor by which the identified mass comes out too large -> how it happens
MASS_SLIPS = {1e3: "a force in N read as kN", 1e-3: "a force in kN read as N"}


def check_segment(seg) -> None:
    """IdentificationError when the impact's data cannot give an answer: a constant acceleration (a dead or
    disconnected accelerometer) or a saturated force channel (:func:`check_clipping`).

    ``seg`` is a :class:`~.peak_to_peak.Segment`; every answer, batch or streaming, early or final, passes this
    check first (see :func:`~.peak_to_peak.solve`).
    """
    a = seg.acceleration
    if a.size and float(np.ptp(a)) == 0.0:
        raise IdentificationError(f"piston_acceleration is constant ({float(a[0])!r} m/s² throughout the impact); "
                                  "expected a measured acceleration")
    check_clipping(seg)


def check_clipping(seg) -> None:
    """IdentificationError when the force channel is saturated.

    A quantised peak may sit a few samples at one level: about 2·√(2(q + 2σ)/|F''|) samples for a quantum q, noise
    σ and the curvature F'' ≈ Fmax·(π/T)² of a pulse of T samples. A flat top twice that long, or the maximum
    reached in two different pulses to the last digit, is a clipped channel.
    """
    f = seg.force
    fmax = float(np.max(f))
    at_max = np.flatnonzero(f >= fmax - 1e-12 * abs(fmax))
    k = int(at_max[0])
    run = int(np.argmax(np.diff(np.r_[at_max, -2]) != 1)) + 1
    pulse = next((p for p in seg.pulses if p.first <= k and (not p.complete or k < p.end)), None)
    rails = sum(any(p.first <= i and (not p.complete or i < p.end) for i in at_max) for p in seg.pulses)
    if pulse is None or fmax <= 0:
        return
    length = (f.size if not pulse.complete else pulse.end) - pulse.zero
    curvature = fmax * (np.pi / max(length, 1)) ** 2
    near = f[max(k - 2 * run - 8, 0):k + 3 * run + 8]
    steps = np.diff(np.unique(near))
    quantum = float(steps.min()) if steps.size else 0.0
    expected = 2.0 * np.sqrt(2.0 * (quantum + 2.0 * seg.noise_force) / curvature)
    if rails >= 2 or run >= max(3.0, 2.0 * expected):
        raise IdentificationError(f"contact_force is saturated: {run} samples sit at its maximum {fmax:.6g} N from "
                                  f"t = {seg.time_of(k):.6g} s (a peak of that curvature stays about "
                                  f"{expected:.1f} samples within the resolution); the force channel was "
                                  "clipped, its range must be raised")


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
            out.append(f"the contact force carries {recorded[worst]:.3g} N·s within {taus[worst] * 1e3:.3g} ms of "
                       f"first contact; M1 = {mass:.3g} kg at V0 = {velocity:.3g} m/s can take at most "
                       f"{allowed[worst]:.3g} N·s (rebounding elastically): the mass or the velocity is too small")
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
