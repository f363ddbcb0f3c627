"""An independent drop-stand simulator with pluggable pad laws, written without impactometer's model code.

Only the public :class:`impactometer.Recording` is used, to hand the record over. Axis down, SI. A mass M1 in free
flight hits the rod of a pneumatic cylinder (piston and rod M2) that rests at its top stop. The cylinder has a
lower chamber (full bore) and an upper chamber (annulus around the rod), both charged to p_atm + p0 with the piston
at the top stop and closed (no valve flow); the gas is adiabatic, p·V^γ constant from the piston's rest position,
where the charge has settled isothermally. Coulomb seal friction F_f·tanh(v2/v_s); push-only spring-damper stops
at the top and the bottom of the stroke. The numbers of :data:`PAD_STAND` are those of impactometer's built-in
pad stand, restated here; only the pad differs.

The pad is a plain-Python contact law with memory (:class:`PadLaw`): between two reversals of the compression rate
its force is a function of the compression alone, so the equations are integrated by scipy's LSODA from one
reversal to the next (a terminal event on the relative velocity), and the law's memory is updated at each
reversal. Laws: :class:`Elastic` (F = k·δ^n, no memory), :class:`Masing` (power-law backbone, unloading and
reloading by Masing's rule with their own exponent), :class:`PeakOriented` (reloading along a straight line towards
the previous maximum point, outside any Masing family) and :class:`PowerSet` (power-law loading with a plastic set
after each pulse and power-law unloading).

Sensors (:func:`record`): point samples at 50 kHz of the contact force [N] and the kinematic piston acceleration
[m/s²], the contact at a random phase within a sample period, white noise of a fraction of each channel's RMS after
contact, pre-trigger samples; the metadata state the charge pressure (not the mass or velocity).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

G = 9.80665
PATM = 101325.0


@dataclass(frozen=True)
class Stand:
    """The drop stand apart from the pad (SI units)."""

    piston_mass: float = 4.0          # M2 [kg]
    bore: float = 0.08                # [m]
    rod_diameter: float = 0.025       # [m]
    stroke: float = 0.20              # [m]
    lower_length: float = 0.20        # gas column below the piston at the top stop [m]
    upper_length: float = 0.02        # gas column above it [m]
    dead_lower: float = 2e-5          # [m³]
    dead_upper: float = 1e-5          # [m³]
    gamma: float = 1.4
    friction: float = 200.0           # Coulomb force [N]
    friction_scale: float = 0.01      # tanh smoothing velocity [m/s]
    stop_stiffness: float = 5e7       # [N/m]
    stop_damping: float = 2e3         # [N·s/m]
    gravity: float = G

    @property
    def area(self) -> float:
        return math.pi * self.bore ** 2 / 4

    @property
    def rod_area(self) -> float:
        return math.pi * self.rod_diameter ** 2 / 4

    def volumes(self, u2: float) -> tuple[float, float]:
        return (self.area * (self.lower_length - u2) + self.dead_lower,
                (self.area - self.rod_area) * (self.upper_length + u2) + self.dead_upper)


#: impactometer's built-in pad stand (``drop-stand-pad``), restated without its pad
PAD_STAND = Stand()


class PadLaw:
    """A compressive-only contact law with memory. ``force(δ)`` is the force [N] at compression δ [m] on the current
    branch; ``reverse(δ, direction)`` starts a new branch at a reversal of the compression rate (direction +1:
    compressing from now on, −1: releasing); ``reset()`` makes a fresh pad; ``energy(δ)`` is the elastic energy of
    a memory-free law [J] (for checks)."""

    def reset(self) -> None:
        pass

    def force(self, d: float) -> float:
        raise NotImplementedError

    def reverse(self, d: float, direction: int) -> None:
        pass


@dataclass
class Elastic(PadLaw):
    """F = k·δ^n (no hysteresis)."""

    k: float
    n: float = 1.0

    def force(self, d: float) -> float:
        return self.k * d ** self.n if d > 0.0 else 0.0

    def energy(self, d: float) -> float:
        return self.k * d ** (self.n + 1) / (self.n + 1) if d > 0.0 else 0.0


@dataclass
class Masing(PadLaw):
    """Backbone F = k·δ^n for a fresh pad; from a reversal (δr, Fr) the pad unloads along F = Fr − ku·(δr − δ)^m
    (zero below) and reloads from a reversal (δm, Fm) along F = Fm + ku·(δ − δm)^m until it meets the backbone
    (Masing's rule with its own exponent m: a loop of partial unloading and reloading closes at its maximum point).
    Once the force is zero the pad follows the opening: reloading then starts at the smallest compression reached
    (a fresh pad once the bodies have parted)."""

    k: float
    n: float
    ku: float
    m: float = 1.0
    mode: int = field(default=1, init=False)
    anchor: tuple[float, float] | None = field(default=None, init=False)

    def reset(self) -> None:
        self.mode, self.anchor = 1, None

    def backbone(self, d: float) -> float:
        return self.k * d ** self.n if d > 0.0 else 0.0

    def force(self, d: float) -> float:
        if d <= 0.0:
            return 0.0
        if self.anchor is None:
            return self.backbone(d)
        da, fa = self.anchor
        if self.mode > 0:
            return min(fa + self.ku * max(d - da, 0.0) ** self.m, self.backbone(d))
        return max(fa - self.ku * max(da - d, 0.0) ** self.m, 0.0)

    def reverse(self, d: float, direction: int) -> None:
        f = self.force(d)
        if direction < 0:
            self.mode, self.anchor = -1, (d, f)
        else:
            self.mode = 1
            self.anchor = None if d <= 0.0 else (d, f)


@dataclass
class PeakOriented(PadLaw):
    """Backbone F = k·δ^n; unloading F = Fr − ku·(δr − δ) (linear, zero below); reloading along the straight line
    from the reversal point (or the point where the force left zero) towards the largest (δ, F) reached so far, then
    the backbone (Clough's peak-oriented rule: no Masing family contains it)."""

    k: float
    n: float
    ku: float
    mode: int = field(default=1, init=False)
    turn: tuple[float, float] = field(default=(0.0, 0.0), init=False)
    peak: tuple[float, float] = field(default=(0.0, 0.0), init=False)

    def reset(self) -> None:
        self.mode, self.turn, self.peak = 1, (0.0, 0.0), (0.0, 0.0)

    def backbone(self, d: float) -> float:
        return self.k * d ** self.n if d > 0.0 else 0.0

    def force(self, d: float) -> float:
        if d <= 0.0:
            return 0.0
        dt, ft = self.turn
        dp, fp = self.peak
        if self.mode < 0:
            return max(ft - self.ku * (dt - d), 0.0)
        if dp <= 0.0 or d >= dp:
            return self.backbone(d)
        if ft <= 0.0:  # the force left zero where the unloading line reached it, or at the reversal if later
            dt = max(dt, dp - fp / self.ku)
        if d <= dt:
            return ft if ft > 0.0 else 0.0
        return ft + (fp - ft) * (d - dt) / (dp - dt)

    def reverse(self, d: float, direction: int) -> None:
        f = self.force(d)
        if direction < 0:
            if d > self.peak[0]:
                self.peak = (d, f)
            self.mode, self.turn = -1, (d, f)
        else:
            self.mode, self.turn = 1, (d, f)


@dataclass
class PowerSet(PadLaw):
    """Power-law loading F = k·δ^n beyond the deepest compression reached; a plastic set s = φ·δr that stays; from
    the deepest point (δr, Fr) unloading and reloading along F = Fr·((δ − s)/(δr − s))^mu (zero below s)."""

    k: float
    n: float
    set_fraction: float = 0.3
    mu: float = 2.0
    deepest: float = field(default=0.0, init=False)

    def reset(self) -> None:
        self.deepest = 0.0

    def force(self, d: float) -> float:
        if d <= 0.0:
            return 0.0
        if d >= self.deepest:
            return self.k * d ** self.n
        s = self.set_fraction * self.deepest
        if d <= s:
            return 0.0
        return self.k * self.deepest ** self.n * ((d - s) / (self.deepest - s)) ** self.mu

    def reverse(self, d: float, direction: int) -> None:
        if direction < 0 and d > self.deepest:
            self.deepest = d


@dataclass(frozen=True)
class Drop:
    """One drop: mass [kg], velocity at first contact [m/s], charge pressure above atmosphere [Pa]."""

    mass: float
    velocity: float
    pressure_gauge: float


class Simulation:
    """The drop integrated from first contact; ``states(t)`` and ``channels(t)`` sample it."""

    def __init__(self, stand: Stand, pad: PadLaw, drop: Drop, duration: float, *, rtol: float = 1e-9,
                 max_step: float = 2e-6) -> None:
        self.stand, self.pad, self.drop = stand, pad, drop
        s = stand
        charge = PATM + drop.pressure_gauge
        lower0, upper0 = s.volumes(0.0)

        def at_rest(u2: float) -> float:  # downward net force on the piston at rest, gas settled isothermally
            lo, up = s.volumes(u2)
            return s.piston_mass * s.gravity - self._gas(charge * lower0 / lo, charge * upper0 / up) \
                + self._stop(-u2, 0.0) - self._stop(u2 - s.stroke, 0.0)

        high = min(s.stroke, s.lower_length + s.dead_lower / s.area) * 0.999
        if at_rest(high) > 0.0:
            raise ValueError(f"pressure_gauge {drop.pressure_gauge} Pa cannot carry the piston")
        self.rest = brentq(at_rest, -1e-2, high, xtol=1e-15)
        lo, up = s.volumes(self.rest)
        self.p_lower0, self.p_upper0 = charge * lower0 / lo, charge * upper0 / up
        self.v_lower0, self.v_upper0 = lo, up
        pad.reset()
        self.segments: list = []
        y = np.array([self.rest, drop.velocity, self.rest, 0.0])
        t = 0.0
        while t < duration:
            sol = solve_ivp(self.rhs, (t, duration), y, method="LSODA", rtol=rtol, atol=[1e-12, 1e-9, 1e-12, 1e-9],
                            max_step=max_step, dense_output=True, events=self._reversal)
            if not sol.success:
                raise RuntimeError(sol.message)
            self.segments.append((t, sol.t[-1], sol.sol))
            if sol.status != 1:
                break
            t, y = sol.t[-1], sol.y[:, -1].copy()
            dd = self.relative_acceleration(y)
            pad.reverse(y[0] - y[2], 1 if dd > 0.0 else -1)
            # a step of 1 ns past the reversal, so that the event does not fire again at its own start
            t, y = t + 1e-9, y + 1e-9 * np.asarray(self.rhs(t, y))
            if len(self.segments) > 5000:
                raise RuntimeError("too many reversals")

    # forces -------------------------------------------------------------------------------------------------
    def _gas(self, p_lower: float, p_upper: float) -> float:
        s = self.stand
        return p_lower * s.area - p_upper * (s.area - s.rod_area) - PATM * s.rod_area

    def _stop(self, pen: float, rate: float) -> float:
        if pen <= 0.0:
            return 0.0
        f = self.stand.stop_stiffness * pen + self.stand.stop_damping * rate
        return f if f > 0.0 else 0.0

    def pressures(self, u2: float) -> tuple[float, float]:
        lo, up = self.stand.volumes(u2)
        g = self.stand.gamma
        return self.p_lower0 * (self.v_lower0 / lo) ** g, self.p_upper0 * (self.v_upper0 / up) ** g

    def forces(self, y) -> tuple[float, float]:
        """(contact force [N], piston acceleration [m/s²]) of state y = (u1, v1, u2, v2)."""
        u1, v1, u2, v2 = y
        s = self.stand
        fc = self.pad.force(u1 - u2)
        fp = self._gas(*self.pressures(u2))
        ff = s.friction * math.tanh(v2 / s.friction_scale) if s.friction > 0.0 else 0.0
        a2 = s.gravity + (fc - fp - ff + self._stop(-u2, -v2) - self._stop(u2 - s.stroke, v2)) / s.piston_mass
        return fc, a2

    def rhs(self, t, y):
        fc, a2 = self.forces(y)
        return [y[1], self.stand.gravity - fc / self.drop.mass, y[3], a2]

    def relative_acceleration(self, y) -> float:
        fc, a2 = self.forces(y)
        return self.stand.gravity - fc / self.drop.mass - a2

    def _reversal(self, t, y):
        return y[1] - y[3]

    _reversal.terminal = True  # type: ignore[attr-defined]

    # output -------------------------------------------------------------------------------------------------
    def states(self, t: np.ndarray) -> np.ndarray:
        """States (4, len(t)) at times t [s] (>= 0), each from its segment with that segment's pad memory."""
        t = np.asarray(t, dtype=float)
        out = np.empty((4, t.size))
        for i, (a, b, sol) in enumerate(self.segments):
            sel = (t >= a) & ((t < b) | (i == len(self.segments) - 1))
            if np.any(sel):
                out[:, sel] = sol(t[sel])
        return out

    def channels(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Contact force [N] and kinematic piston acceleration [m/s²] at times t [s] (zero before contact)."""
        t = np.asarray(t, dtype=float)
        force = np.zeros(t.size)
        accel = np.zeros(t.size)
        after = t >= 0.0
        self.pad.reset()  # replay the pad's memory segment by segment
        for i, (a, b, sol) in enumerate(self.segments):
            last = i == len(self.segments) - 1
            sel = np.flatnonzero(after & (t >= a) & ((t < b) | last))
            Y = sol(t[sel]) if sel.size else np.empty((4, 0))
            for j, k in enumerate(sel):
                force[k], accel[k] = self.forces(Y[:, j])
            if not last:
                y = sol(b)
                self.pad.reverse(y[0] - y[2], 1 if self.relative_acceleration(y) > 0.0 else -1)
        return force, accel

    def energy(self, y) -> float:
        """Kinetic + gravity + atmosphere + gas internal + elastic energy [J] (memory-free pad laws only)."""
        u1, v1, u2, v2 = y
        s = self.stand
        kinetic = 0.5 * self.drop.mass * v1 ** 2 + 0.5 * s.piston_mass * v2 ** 2
        potential = -s.gravity * (self.drop.mass * u1 + s.piston_mass * u2) - PATM * s.rod_area * u2
        lo, up = s.volumes(u2)
        pl, pu = self.pressures(u2)
        gas = (pl * lo + pu * up) / (s.gamma - 1.0)
        elastic = self.pad.energy(u1 - u2)  # type: ignore[attr-defined]
        for pen in (-u2, u2 - s.stroke):
            if pen > 0.0:
                elastic += 0.5 * s.stop_stiffness * pen ** 2
        return kinetic + potential + gas + elastic


def record(pad: PadLaw, drop: Drop, *, stand: Stand = PAD_STAND, seed: int = 0, noise: float = 0.05,
           duration: float = 0.05, pre_trigger: float = 0.02, sample_rate: float = 50e3,
           state_pressure: bool = True):
    """An :class:`impactometer.Recording` of one drop: contact force and piston acceleration, sampled at
    ``sample_rate`` [Hz] with the contact at a random phase, ``pre_trigger`` [s] before and ``duration`` [s] after
    it, white noise of ``noise`` × each channel's RMS after contact, the charge pressure in the metadata. The same
    arguments give the same record."""
    from impactometer.recording import Recording

    rng = np.random.default_rng(seed)
    phase = rng.uniform(0.0, 1.0 / sample_rate)
    n_pre = int(round(pre_trigger * sample_rate))
    n_post = int(round(duration * sample_rate))
    start = -n_pre / sample_rate + phase
    t = start + np.arange(n_pre + n_post) / sample_rate
    sim = Simulation(stand, pad, drop, float(t[-1]) + 1e-5)
    force, accel = sim.channels(t)
    post = t >= 0.0
    channels = {}
    for name, clean in (("contact_force", force), ("piston_acceleration", accel)):
        sigma = noise * math.sqrt(float(np.mean(clean[post] ** 2)))
        channels[name] = clean + rng.normal(0.0, sigma, clean.size) if sigma > 0 else clean
    metadata = {"pressure_gauge_Pa": drop.pressure_gauge} if state_pressure else {}
    return Recording(sample_rate=sample_rate, channels=channels, start_time=float(t[0]), metadata=metadata,
                     source="foreign stand")


#: the pads of the foreign records, each a function of a random generator
def draw_pad(kind: str, rng: np.random.Generator, reload_exponent: float = 1.0,
             loading_exponent: float | None = None) -> PadLaw:
    """A pad of ``kind`` (``masing``, ``peak-oriented``, ``power-set``) with parameters drawn around those of an
    elastomer pad like the built-in one (loading stiffness 5e5-1e6 N/m at 1 cm, unloading 1/e² times stiffer with
    e = 0.3-0.5): a loading exponent 1-1.1 for the pads that reload another way (``loading_exponent`` in its place
    where given, the other draws the same), 1.3-1.8 for the power-law pad."""
    k = rng.uniform(5e5, 1e6)
    stiffer = rng.uniform(0.3, 0.5) ** -2
    if kind in ("masing", "peak-oriented"):
        n = rng.uniform(1.0, 1.1)
        n = n if loading_exponent is None else loading_exponent
        k1 = k * 0.01 ** (1.0 - n)  # k at 1 cm
        if kind == "peak-oriented":
            return PeakOriented(k=k1, n=n, ku=k * stiffer)
        # the unloading curve's stiffness k·stiffer at 1 mm from its reversal
        return Masing(k=k1, n=n, ku=k * stiffer * 0.001 ** (1.0 - reload_exponent), m=reload_exponent)
    if kind == "power-set":
        n = rng.uniform(1.3, 1.8)
        return PowerSet(k=k * 0.01 ** (1.0 - n), n=n, set_fraction=rng.uniform(0.15, 0.4), mu=rng.uniform(1.5, 3.0))
    raise ValueError(f"pad kind must be masing, peak-oriented or power-set, got {kind!r}")


def draw_drop(rng: np.random.Generator) -> Drop:
    """M1 8-60 kg, V0 0.8-3.5 m/s, p0 100-380 kPa gauge (within the built-in stand's 0-400 kPa)."""
    return Drop(mass=rng.uniform(8.0, 60.0), velocity=rng.uniform(0.8, 3.5), pressure_gauge=rng.uniform(100e3, 380e3))


def foreign_case(kind: str, seed: int, *, reload_exponent: float = 1.0, noise: float = 0.05,
                 duration: float = 0.05, loading_exponent: float | None = None):
    """(record, drop, pad) of the foreign case ``seed`` of pad ``kind``: deterministic from the seed."""
    rng = np.random.default_rng([seed, sum(map(ord, kind))])
    pad = draw_pad(kind, rng, reload_exponent, loading_exponent)
    drop = draw_drop(rng)
    rec = record(pad, drop, seed=int(rng.integers(2**31)), noise=noise, duration=duration)
    return rec, drop, replace(pad)
