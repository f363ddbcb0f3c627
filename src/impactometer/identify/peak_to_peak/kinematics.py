"""Force and piston acceleration and their running integrals referred to the first contact t00, at any fractional
sample (the kinematics the rows of the robust peak-to-peak identification are written in)."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np


def cumulative_integrals(signal: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """First and second running integrals of a piecewise-linear ``signal`` from its first sample (exact)."""
    x = np.asarray(signal, dtype=float)
    first = np.zeros_like(x)
    second = np.zeros_like(x)
    first[1:] = np.cumsum(0.5 * dt * (x[1:] + x[:-1]))
    step2 = dt * first[:-1] + dt * dt * (x[:-1] / 3.0 + x[1:] / 6.0)
    second[1:] = np.cumsum(step2)
    return first, second


def integrals_at(signal, first, second, dt, index):
    """Value, first and second integrals at fractional sample ``index`` (piecewise-linear signal)."""
    index = np.asarray(index, dtype=float)
    i = np.clip(np.floor(index).astype(int), 0, signal.size - 2)
    s = (index - i) * dt
    x0 = signal[i]
    slope = (signal[i + 1] - x0) / dt
    value = x0 + slope * s
    v = first[i] + x0 * s + slope * s ** 2 / 2.0
    d = second[i] + first[i] * s + x0 * s ** 2 / 2.0 + slope * s ** 3 / 6.0
    return value, v, d


class KinematicsAt(NamedTuple):
    """Force, piston acceleration and their integrals from first contact t00 at given instants (arrays)."""

    tau: np.ndarray  #: time since first contact t00 [s]
    force: np.ndarray  #: contact force Fc [N]
    force_impulse: np.ndarray  #: JF = ∫Fc dt from t00 [N·s]
    force_double: np.ndarray  #: IF = ∫∫Fc dt² from t00 [N·s²]
    acceleration: np.ndarray  #: piston acceleration a2 [m/s²]
    velocity_change: np.ndarray  #: V2 = ∫a2 dt from t00 [m/s]
    displacement: np.ndarray  #: D2 = ∫∫a2 dt² from t00 [m]


class Kinematics:
    """Double integrals of force and piston acceleration referred to the first contact t00."""

    def __init__(self, force, acceleration, dt, t00_index, gravity, *, onset_std0=0.0):
        self.force, self.acceleration, self.dt, self.gravity = force, acceleration, dt, gravity
        self.t00 = float(t00_index)
        self.onset_std0 = float(onset_std0)  # standard error of t00 [samples]
        self.cf = cumulative_integrals(force, dt)
        self.ca = cumulative_integrals(acceleration, dt)
        self._f0 = integrals_at(force, *self.cf, dt, self.t00)
        self._a0 = integrals_at(acceleration, *self.ca, dt, self.t00)

    def at(self, index) -> KinematicsAt:
        """τ, Fc, JF, IF, a2, V2, D2 at fractional sample indices ``index``, integrals from t00."""
        index = np.asarray(index, dtype=float)
        tau = (index - self.t00) * self.dt
        f, jf, i_f = integrals_at(self.force, self.cf[0], self.cf[1], self.dt, index)
        a, va, da = integrals_at(self.acceleration, self.ca[0], self.ca[1], self.dt, index)
        jf, i_f = jf - self._f0[1], i_f - self._f0[2] - self._f0[1] * tau
        va, da = va - self._a0[1], da - self._a0[2] - self._a0[1] * tau
        return KinematicsAt(tau, f, jf, i_f, a, va, da)
