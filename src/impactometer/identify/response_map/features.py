"""Feature sets of the response map: a contact-force signal -> m characteristic numbers (paper section 5).

A feature set is registered by name in :data:`FEATURE_SETS`. Each one turns force histories sampled at a common
time vector (t = 0 at first contact, t00 of the paper) into ``m`` positive numbers, and declares when its data is
complete (``available_at`` [s] after first contact): an on-line identification cannot answer earlier.

- ``peaks``: amplitudes of the first two contact-force peaks [N] (the paper's first choice);
- ``max-impulse``: the maximum force [N] and the impulse ∫Fc dt [N·s] over the window [t00, t00 + T]
  (the paper's second choice; ``window`` = T);
- ``impulse-profile``: impulses over [t00, t00 + j·T/6], j = 1..6 -- six low-noise numbers for two unknowns
  (eq. (6) with m > n), the most robust to sensor noise.

Adding a set: write ``extract(time, forces, **params) -> (values (n, m), available_at (n,))`` with NaN rows for
signals that do not give the features, and register a :class:`FeatureSet`.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numba import njit

from ...errors import ParameterError, ResponseMapError, shown
from ...validation import check_real

#: every extractor takes ``time`` ((samples,) array: sample instants [s], t = 0 at first contact) and ``forces``
#: ((n, samples) or (samples,) array: contact force [N])
SIGNALS = "time [s] (t = 0 at first contact), forces [N] of shape (n, samples) or (samples,)"


@dataclass(frozen=True, kw_only=True)
class FeatureSet:
    """A named way of reducing a force signal to characteristic numbers.

    Attributes
    ----------
    name : Registry name.
    labels : Name of each feature.
    units : SI unit of each feature.
    defaults : Parameter name -> default value (SI).
    limits : Parameter name -> (low, high) admissible range (SI).
    extract : ``extract(time, forces, **params) -> (values (n, m), available_at (n,))``.
    description : One line for ``map info``.
    """

    name: str
    labels: tuple[str, ...]
    units: tuple[str, ...]
    defaults: Mapping[str, float]
    limits: Mapping[str, tuple[float, float]]
    extract: Callable[..., tuple[np.ndarray, np.ndarray]] = field(repr=False)
    description: str = ""

    @property
    def size(self) -> int:
        """Number of features m."""
        return len(self.labels)

    def params(self, given: Mapping[str, Any] | None = None) -> dict[str, float]:
        """Defaults completed by ``given``; unknown names and out-of-range values raise ParameterError."""
        given = dict(given or {})
        unknown = sorted(set(given) - set(self.defaults))
        if unknown:
            raise ParameterError(f"feature set {self.name!r}: unknown parameter(s) {unknown}; expected "
                                 f"{sorted(self.defaults)}")
        out = dict(self.defaults)
        for key, value in given.items():
            low, high = self.limits[key]
            out[key] = check_real(f"feature set {self.name!r}: {key}", value, low=low, high=high, state_range=True)
        return out


def _check_signals(time, forces) -> tuple[np.ndarray, np.ndarray]:
    time = np.asarray(time, dtype=float)
    forces = np.asarray(forces, dtype=float)
    if forces.ndim == 1:
        forces = forces[None, :]
    if time.ndim != 1 or forces.ndim != 2 or forces.shape[1] != time.size or time.size < 3:
        raise ParameterError(f"time must be 1-D and forces (n, samples) with samples = len(time) >= 3, got shapes "
                             f"{time.shape} and {forces.shape}")
    if not np.all(np.isfinite(time)) or np.any(np.diff(time) <= 0):
        raise ParameterError("time must be finite and strictly increasing [s]")
    if time[-1] < 0 or time[0] > 0:
        raise ResponseMapError(f"the record must contain first contact (t = 0); it covers [{time[0]:g}, "
                               f"{time[-1]:g}] s")
    return time, forces


def _windowed(time, forces, window: float, name: str) -> tuple[np.ndarray, np.ndarray, float, int]:
    """Checked signals, sample period [s] and first-contact index of a feature set that needs ``window`` [s]."""
    time, forces = _check_signals(time, forces)
    dt = float(np.median(np.diff(time)))
    if time[-1] < window - 0.5 * dt:
        raise ResponseMapError(f"the record covers {time[-1] * 1e3:.3g} ms after first contact; feature set "
                               f"{name!r} with window {window * 1e3:.3g} ms needs at least that long")
    return time, forces, dt, int(np.searchsorted(time, 0.0))


def smoothed(forces: np.ndarray, smoothing: float, dt: float) -> np.ndarray:
    """Savitzky-Golay (quadratic) smoothing over ``smoothing`` [s] along the last axis; peaks keep their height.

    The same smoothing is applied to the map's signals and to the measurement, so what bias remains cancels.
    """
    samples = int(round(smoothing / dt)) | 1
    if samples < 5:
        return forces
    from scipy.signal import savgol_filter

    return savgol_filter(forces, min(samples, forces.shape[-1] - (1 - forces.shape[-1] % 2)), 2, axis=-1,
                         mode="interp")


def _refined_peak(y: np.ndarray, idx: np.ndarray, low: int, high: int) -> np.ndarray:
    """Parabolic refinement of the sampled maxima ``y[r, idx[r]]`` (rows), within samples [low, high)."""
    rows = np.arange(y.shape[0])
    peak = y[rows, idx]
    inner = (idx > low) & (idx < high - 1)
    i = idx[inner]
    r = rows[inner]
    y0, y1, y2 = y[r, i - 1], y[r, i], y[r, i + 1]
    curvature = y0 - 2.0 * y1 + y2
    with np.errstate(divide="ignore", invalid="ignore"):
        delta = np.where(curvature < 0, 0.5 * (y0 - y2) / curvature, 0.0)
    peak[inner] = y1 - 0.25 * (y0 - y2) * np.clip(delta, -0.5, 0.5)
    return peak


def max_impulse(time, forces, *, window: float = 0.02, smoothing: float = 5e-4) -> tuple[np.ndarray, np.ndarray]:
    """Maximum contact force [N] and impulse ∫Fc dt [N·s] over [0, ``window``] after first contact.

    Parameters
    ----------
    time, forces : see :data:`SIGNALS`.
    window : float
        Integration window T [s].
    smoothing : float
        Length of the quadratic Savitzky-Golay smoothing applied before taking the maximum [s] (0: none).

    Returns
    -------
    values : (n, 2) array
        Maximum force [N], impulse [N·s].
    available_at : (n,) array
        ``window`` [s]: the features are complete T after first contact.
    """
    time, forces, dt, i0 = _windowed(time, forces, window, "max-impulse")
    i1 = int(np.searchsorted(time, window + 0.5 * dt, side="right"))
    if i1 - i0 < 2:
        raise ResponseMapError(f"window {window!r} s holds fewer than 2 samples; expected a window of several "
                               f"sample periods ({dt:g} s)")
    part = smoothed(forces[:, :i1], smoothing, dt)[:, i0:]
    peak = _refined_peak(part, np.argmax(part, axis=1), 0, part.shape[1])
    impulse = np.trapezoid(forces[:, i0:i1], time[i0:i1], axis=1)
    return np.column_stack([peak, impulse]), np.full(forces.shape[0], float(window))


PROFILE_COUNT = 6


def impulse_profile(time, forces, *, window: float = 0.02) -> tuple[np.ndarray, np.ndarray]:
    """Impulses ∫Fc dt [N·s] from first contact to j·T/6, j = 1..6 (T = ``window``).

    Integrals average the sensor noise out, and six of them over-determine mass and velocity (eq. (6) of the paper
    with m = 6 > n = 2), which makes the identification far less sensitive to noise than two force maxima.

    Parameters
    ----------
    time, forces : see :data:`SIGNALS`.
    window : float
        Longest integration window T [s].

    Returns
    -------
    values : (n, 6) array
        The impulses [N·s].
    available_at : (n,) array
        ``window`` [s].
    """
    time, forces, dt, i0 = _windowed(time, forces, window, "impulse-profile")
    ends = [int(np.searchsorted(time, window * j / PROFILE_COUNT + 0.5 * dt, side="right"))
            for j in range(1, PROFILE_COUNT + 1)]
    if ends[0] - i0 < 2:
        raise ResponseMapError(f"window {window!r} s is too short: T/{PROFILE_COUNT} must hold at least 2 samples "
                               f"({dt:g} s apart)")
    cumulative = np.concatenate([np.zeros((forces.shape[0], 1)),
                                 np.cumsum(0.5 * (forces[:, i0 + 1:] + forces[:, i0:-1]) * np.diff(time[i0:]),
                                           axis=1)], axis=1)
    return cumulative[:, [e - 1 - i0 for e in ends]], np.full(forces.shape[0], float(window))


@njit(cache=True)
def _two_pulses(forces, i0, min_samples, fraction, out_index, out_end):
    """Indices of the maxima of the first two contact pulses and of the end of the second (-1: not found).

    Pulse 1 starts at ``i0``; a pulse ends when the force falls below ``fraction`` of its running maximum (not
    before ``min_samples``), pulse 2 also when it has fallen below its running maximum by ``fraction`` of the first
    peak (its first peak, where it runs into sustained contact); pulse 2 starts when the force rises above
    ``2·fraction`` of the first peak.
    """
    n, samples = forces.shape
    for r in range(n):
        f = forces[r]
        out_index[r, 0] = -1
        out_index[r, 1] = -1
        out_end[r] = -1
        state = 0
        best = -np.inf
        ibest = i0
        start = i0
        peak1 = 0.0
        for k in range(i0, samples):
            x = f[k]
            if state == 0 or state == 2:
                if x > best:
                    best = x
                    ibest = k
                # pulse 1 ends when the force falls to ``fraction`` of its maximum; pulse 2 also at its first
                # peak, once the force has fallen below it by ``fraction`` of the first peak: a second contact that
                # runs into sustained contact (stage B) has its peak at the end of the rebound part, as in the
                # paper variant's t11
                ended = x < fraction * best or (state == 2 and x < best - fraction * peak1)
                if k - start >= min_samples and best > 0 and ended:
                    out_index[r, state // 2] = ibest
                    if state == 2:
                        out_end[r] = k
                        break
                    peak1 = best
                    state = 1
            elif x > 2.0 * fraction * peak1:
                state = 2
                best = x
                ibest = k
                start = k


def peaks(time, forces, *, fraction: float = 0.05, min_duration: float = 5e-4,
          smoothing: float = 5e-4) -> tuple[np.ndarray, np.ndarray]:
    """Amplitudes of the first two contact-force peaks [N] (stage A; the second one the first peak of a contact
    that runs into stage B).

    Parameters
    ----------
    time, forces : see :data:`SIGNALS`.
    fraction : float
        A pulse ends when the force falls below this fraction of its maximum; the next one starts above twice this
        fraction of the first peak (hysteresis against noise) [-].
    min_duration : float
        Shortest pulse [s]; shorter dips are not taken as the end of a pulse.
    smoothing : float
        Length of the quadratic Savitzky-Golay smoothing applied before the search [s] (0: none).

    Returns
    -------
    values : (n, 2) array
        First and second peak force [N]; NaN where the record does not hold two complete pulses.
    available_at : (n,) array
        End of the second pulse [s] (its peak is known only then); NaN where not found.
    """
    time, forces = _check_signals(time, forces)
    dt = float(np.median(np.diff(time)))
    i0 = int(np.searchsorted(time, 0.0))
    forces = smoothed(forces, smoothing, dt)
    index = np.empty((forces.shape[0], 2), dtype=np.int64)
    end = np.empty(forces.shape[0], dtype=np.int64)
    _two_pulses(forces, i0, max(1, int(round(min_duration / dt))), fraction, index, end)
    values = np.full((forces.shape[0], 2), np.nan)
    ok = end >= 0
    for j in range(2):
        if ok.any():
            values[ok, j] = _refined_peak(forces[ok], index[ok, j], i0, forces.shape[1])
    available = np.where(ok, time[np.clip(end, 0, None)], np.nan)
    return values, available


#: feature-set name -> FeatureSet
FEATURE_SETS: dict[str, FeatureSet] = {
    "peaks": FeatureSet(name="peaks", labels=("first_peak", "second_peak"), units=("N", "N"),
                        defaults={"fraction": 0.05, "min_duration": 5e-4, "smoothing": 5e-4},
                        limits={"fraction": (1e-3, 0.5), "min_duration": (0.0, 0.05), "smoothing": (0.0, 0.01)},
                        extract=peaks,
                        description="amplitudes of the first two contact-force peaks"),
    "max-impulse": FeatureSet(name="max-impulse", labels=("max_force", "impulse"), units=("N", "N*s"),
                              defaults={"window": 0.02, "smoothing": 5e-4},
                              limits={"window": (1e-4, 1.0), "smoothing": (0.0, 0.01)}, extract=max_impulse,
                              description="maximum contact force and impulse over a window T after first contact"),
    "impulse-profile": FeatureSet(name="impulse-profile",
                                  labels=tuple(f"impulse_{j}" for j in range(1, PROFILE_COUNT + 1)),
                                  units=("N*s",) * PROFILE_COUNT, defaults={"window": 0.02},
                                  limits={"window": (1e-4, 1.0)}, extract=impulse_profile,
                                  description=f"impulses from first contact to j·T/{PROFILE_COUNT}, "
                                              f"j = 1..{PROFILE_COUNT}"),
}


def get_feature_set(name: str) -> FeatureSet:
    """The registered feature set ``name``; the error lists the valid names."""
    if not isinstance(name, str) or name not in FEATURE_SETS:
        raise ParameterError(f"features must be one of {sorted(FEATURE_SETS)}, got {shown(name)}")
    return FEATURE_SETS[name]


def extract_batch(time, forces, name: str = "max-impulse",
                  params: Mapping[str, Any] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Features of many force histories: ``(values (n, m), available_at (n,))`` with NaN rows where not found."""
    fs = get_feature_set(name)
    return fs.extract(time, forces, **fs.params(params))


def recording_signal(recording) -> tuple[np.ndarray, np.ndarray]:
    """(time [s], contact force [N]) of a :class:`~impactometer.recording.Recording`, with the delay its
    anti-alias filter added (metadata ``anti_alias_delay_s``) taken out of the time base, so that fixed windows
    after first contact see the same part of the signal as in a simulation."""
    delay = check_real(f"{recording.source}: metadata anti_alias_delay_s",
                       recording.metadata.get("anti_alias_delay_s") or 0.0, low=0.0, unit=" [s]", state_range=True,
                       error=ResponseMapError)
    return recording.time - delay, recording.contact_force


def extract_features(time, force, name: str = "max-impulse",
                     params: Mapping[str, Any] | None = None) -> tuple[np.ndarray, float]:
    """Features of one force history [N] sampled at ``time`` [s]: ``(values (m,), available_at [s])``.

    Raises ResponseMapError when the signal does not give them (e.g. fewer than two usable peaks).
    """
    fs = get_feature_set(name)
    values, available = fs.extract(time, np.asarray(force, dtype=float).reshape(1, -1), **fs.params(params))
    if not np.all(np.isfinite(values)) or np.any(values[0] <= 0):
        detail = ("fewer than two usable peaks (two contact pulses separated by a drop below "
                  f"{fs.params(params).get('fraction', 0):g} of the peak)" if name == "peaks" else
                  f"non-positive features {values[0].tolist()}")
        raise ResponseMapError(f"feature set {name!r}: the force signal gives {detail}; expected a record of an "
                               "impact with positive contact force; try --features max-impulse or a longer record")
    return values[0], float(available[0])
