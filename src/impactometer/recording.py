"""A recording: regularly sampled sensor channels of one drop test, in SI units, with metadata.

Conventions: ``contact_force`` [N] positive in compression; ``piston_acceleration`` [m/s²] positive downward
(the impact direction) and kinematic (gravity removed). Time 0 is first contact; ``start_time`` is the time of
the first sample (negative when pre-trigger samples are present). Metadata keys for known truth:
``mass_kg``, ``velocity_m_s``, ``pressure_gauge_Pa``; any other keys are kept as they are.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from .errors import RecordingError, UnitError
from .stands import MASS_RANGE, VELOCITY_RANGE
from .units import parse_quantity

FORCE = "contact_force"
ACCELERATION = "piston_acceleration"
#: SI unit of the standard channels
CHANNEL_UNITS = {FORCE: "N", ACCELERATION: "m/s^2", "u1": "m", "u2": "m", "piston_displacement": "m",
                 "pressure_lower": "Pa", "pressure_upper": "Pa"}
TRUTH_KEYS = ("mass_kg", "velocity_m_s", "pressure_gauge_Pa")
#: known-truth key -> SI unit, and (dimension, lowest, highest value) [SI]
TRUTH_UNITS = {"mass_kg": "kg", "velocity_m_s": "m/s", "pressure_gauge_Pa": "Pa"}
TRUTH_RANGES = {"mass_kg": ("mass", 0.0, MASS_RANGE[1]), "velocity_m_s": ("velocity", 0.0, VELOCITY_RANGE[1]),
                "pressure_gauge_Pa": ("pressure", 0.0, 1e8)}
#: largest magnitude of a sample of any channel (SI units: a force of 1e15 N, a pressure of 1e15 Pa, ...)
SAMPLE_LIMIT = 1e15
#: largest magnitude of the time of a recording's first sample [s] (a clock time since 1970 fits)
START_TIME_LIMIT = 1e10
#: sample rates a recording may have [Hz], from a slow logger to a fast transient recorder
SAMPLE_RATE_RANGE = (1.0, 1e8)


def check_sample_rate(value: Any, field: str = "sample_rate", *, error: type[Exception] = RecordingError) -> float:
    """``value`` as a sample rate [Hz] within :data:`SAMPLE_RATE_RANGE`; ``error`` naming ``field`` otherwise."""
    low, high = SAMPLE_RATE_RANGE
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) \
            or not math.isfinite(value) or not low <= value <= high:
        shown = float(value) if isinstance(value, (np.integer, np.floating)) else value
        raise error(f"{field} must be a number within [{low:g}, {high:g}] Hz, got {shown!r}")
    return float(value)


def truth_value(key: str, value: Any, where: str = "") -> float:
    """A known-truth metadata value (a number, or a text such as ``"30"`` or ``"30 kg"``) in SI units.

    RecordingError naming ``where`` and the key unless it is a finite number within :data:`TRUTH_RANGES`.
    """
    dimension, low, high = TRUTH_RANGES[key]
    shown = value.item() if isinstance(value, np.generic) else value
    if isinstance(shown, bool) or not isinstance(shown, (int, float, str)):
        raise RecordingError(f"{where}metadata {key} must be a number, got {_short(shown)}")
    try:
        number = parse_quantity(shown, dimension, field=f"metadata {key}")
    except UnitError as exc:
        raise RecordingError(f"{where}{exc}") from None
    if not low <= number <= high:
        raise RecordingError(f"{where}metadata {key} must be within [{low:g}, {high:g}] {TRUTH_UNITS[key]}, got "
                             f"{_short(shown)}")
    return number


def _short(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def samples(values: Any, name: str, source: str, *, squeeze: bool = False) -> np.ndarray:
    """``values`` as a non-empty 1-D float array of finite samples; a RecordingError naming ``source`` otherwise.

    With ``squeeze``, a row or column vector (e.g. MATLAB's n×1) is accepted as 1-D.
    """
    try:
        arr = np.asarray(values, dtype=float)
    except (TypeError, ValueError):
        raise RecordingError(f"{source}: channel {name!r} must hold numbers") from None
    if squeeze and arr.ndim > 1 and sum(s > 1 for s in arr.shape) <= 1:
        arr = arr.reshape(-1)
    if arr.ndim != 1 or arr.size == 0:
        raise RecordingError(f"{source}: channel {name!r} must be a non-empty 1-D array, got shape {arr.shape}")
    bad = np.flatnonzero(~np.isfinite(arr))
    if bad.size:
        raise RecordingError(f"{source}: channel {name!r} has a non-finite sample ({float(arr[bad[0]])!r}) at "
                             f"index {int(bad[0])}; expected finite numbers")
    if arr.size and max(float(arr.max()), -float(arr.min())) > SAMPLE_LIMIT:
        i = int(np.argmax(np.abs(arr) > SAMPLE_LIMIT))
        raise RecordingError(f"{source}: channel {name!r} has a sample of {float(arr[i]):.3g} at index {i}; expected "
                             f"magnitudes up to {SAMPLE_LIMIT:g} (SI units)")
    return arr


@dataclass(frozen=True, kw_only=True)
class Recording:
    """Regularly sampled channels of one test.

    Attributes
    ----------
    sample_rate : Sample rate [Hz].
    channels : Channel name -> samples (1-D float arrays of equal length, SI units).
    start_time : Time of the first sample relative to first contact [s].
    metadata : Free metadata; truth keys ``mass_kg``, ``velocity_m_s``, ``pressure_gauge_Pa``.
    source : Where the data came from (file name or ``simulation``).
    """

    sample_rate: float
    channels: dict[str, np.ndarray]
    start_time: float = 0.0
    metadata: dict[str, Any] = field(default_factory=dict)
    source: str = "memory"

    def __post_init__(self) -> None:
        where = f"{self.source}: "
        object.__setattr__(self, "sample_rate", check_sample_rate(self.sample_rate, f"{where}sample_rate"))
        if isinstance(self.start_time, bool) or not isinstance(self.start_time, (int, float, np.integer, np.floating)) \
                or not abs(self.start_time) <= START_TIME_LIMIT:
            shown = float(self.start_time) if isinstance(self.start_time, np.generic) else self.start_time
            raise RecordingError(f"{where}start_time must be a number within ±{START_TIME_LIMIT:g} [s], got "
                                 f"{shown!r}")
        object.__setattr__(self, "start_time", float(self.start_time))
        if not isinstance(self.channels, dict) or not self.channels:
            raise RecordingError(f"{where}channels must be a non-empty mapping of name -> samples")
        length = None
        clean = {}
        for name, values in self.channels.items():
            arr = samples(values, name, self.source)
            if length is not None and arr.size != length:
                raise RecordingError(f"{where}channels must have equal lengths, got {arr.size} samples in "
                                     f"{name!r} and {length} before")
            length = arr.size
            clean[name] = arr
        object.__setattr__(self, "channels", clean)
        if not isinstance(self.metadata, dict):
            raise RecordingError(f"{where}metadata must be a mapping, got {type(self.metadata).__name__}")
        truth = {k: truth_value(k, v, where) for k, v in self.metadata.items() if k in TRUTH_KEYS and v is not None}
        if truth:
            object.__setattr__(self, "metadata", {**self.metadata, **truth})

    def __len__(self) -> int:
        return next(iter(self.channels.values())).size

    @property
    def time(self) -> np.ndarray:
        """Sample instants [s], t = 0 at first contact."""
        return self.start_time + np.arange(len(self)) / self.sample_rate

    @property
    def duration(self) -> float:
        """Time covered by the samples [s]."""
        return len(self) / self.sample_rate

    def channel(self, name: str) -> np.ndarray:
        """Samples of channel ``name``; the error lists the channels present."""
        if name not in self.channels:
            raise RecordingError(f"{self.source}: channel {name!r} is missing; channels found: {sorted(self.channels)}")
        return self.channels[name]

    @property
    def contact_force(self) -> np.ndarray:
        """Contact force [N], positive in compression."""
        return self.channel(FORCE)

    @property
    def piston_acceleration(self) -> np.ndarray:
        """Kinematic piston acceleration [m/s²], positive downward."""
        return self.channel(ACCELERATION)

    def truth(self, key: str) -> float | None:
        """A known-truth metadata value (``mass_kg``, ``velocity_m_s``, ``pressure_gauge_Pa``) or None."""
        value = self.metadata.get(key)
        return None if value is None else float(value)

    def unit(self, name: str) -> str:
        """SI unit of channel ``name`` (standard channels, else as noted in ``metadata['channel_units']``)."""
        self.channel(name)
        noted = self.metadata.get("channel_units")
        if name in CHANNEL_UNITS:
            return CHANNEL_UNITS[name]
        return str(noted.get(name, "")) if isinstance(noted, dict) else ""

    def with_metadata(self, **changes: Any) -> Recording:
        """A copy with metadata keys added or replaced."""
        return replace(self, metadata={**self.metadata, **changes})

    @classmethod
    def from_time(cls, time, channels: dict[str, Any], *, metadata: dict[str, Any] | None = None,
                  source: str = "memory") -> Recording:
        """A recording from a regular time vector [s] instead of a sample rate.

        The time must increase strictly and stay within 5 % of a period of a regular grid.
        """
        from .io.channels import time_base

        rate, start = time_base(time, None, source)
        recording = cls(sample_rate=rate, channels=channels, start_time=start, metadata=dict(metadata or {}),
                        source=source)
        if np.size(time) != len(recording):
            raise RecordingError(f"{source}: time has {np.size(time)} samples but the channels have "
                                 f"{len(recording)}; expected equal lengths")
        return recording

    @classmethod
    def read(cls, path, **options: Any) -> Recording:
        """Read a lab file; see :func:`impactometer.io.read_recording` for the options."""
        from .io import read_recording

        return read_recording(path, **options)

    def write(self, path, *, overwrite: bool = False):
        """Write to ``path`` in the format of its extension; see :func:`impactometer.io.write_recording`."""
        from .io import write_recording

        return write_recording(self, path, overwrite=overwrite)

    def plot(self, axes=None, *, inspection: Inspection | None = None):
        """Force and acceleration vs time with the contact pulses marked; returns the figure."""
        from .plotting.recordings import plot_recording

        return plot_recording(self, axes, inspection=inspection)


@dataclass(frozen=True, kw_only=True)
class ChannelSummary:
    """Range and white-noise estimate of one channel, in its SI unit."""

    unit: str
    minimum: float
    maximum: float
    noise: float


@dataclass(frozen=True, kw_only=True)
class Inspection:
    """What ``impactometer inspect`` reports about a recording.

    Attributes
    ----------
    duration, sample_rate, start_time : Record length [s], sample rate [Hz], time of the first sample [s].
    channels : Channel name -> :class:`ChannelSummary`.
    peak_force, peak_force_time : Largest contact force [N] and when [s] (None without a force channel).
    force_offset : Offset removed before pulse detection [N] (median of the pre-trigger samples, else 0).
    pulses : Contact pulses (``identify.pulses.Pulse``), the last one ``sustained`` when it is stage B.
    stage_b_start : Start of sustained contact [s] or None.
    truth : Known-truth metadata present in the recording.
    """

    duration: float
    sample_rate: float
    start_time: float
    samples: int
    channels: dict[str, ChannelSummary]
    peak_force: float | None
    peak_force_time: float | None
    force_offset: float
    pulses: list
    stage_b_start: float | None
    truth: dict[str, float]

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready mapping (SI units, keys suffixed with the unit)."""
        return {"duration_s": self.duration, "sample_rate_Hz": self.sample_rate, "start_time_s": self.start_time,
                "samples": self.samples,
                "channels": {name: {"unit": c.unit, "min": c.minimum, "max": c.maximum, "noise": c.noise}
                             for name, c in self.channels.items()},
                "peak_force_N": self.peak_force, "peak_force_time_s": self.peak_force_time,
                "force_offset_N": self.force_offset,
                "pulses": [{"start_s": p.start, "peak_time_s": p.peak_time, "end_s": p.end,
                            "peak_force_N": p.peak_force, "impulse_Ns": p.impulse, "sustained": p.sustained}
                           for p in self.pulses],
                "stage_b_start_s": self.stage_b_start, "truth": dict(self.truth)}


#: a pulse lasting longer than this multiple of the first pulse is sustained contact (stage B)
SUSTAINED_FACTOR = 4.0
#: fewest pre-trigger samples from which the force offset is estimated
MIN_OFFSET_SAMPLES = 10


def _samples_before_contact(recording: Recording) -> int:
    """Number of samples at t < 0 (the pre-trigger), without forming the time array."""
    n = int(np.clip(np.ceil(-recording.start_time * recording.sample_rate), 0, len(recording)))
    while n > 0 and recording.start_time + (n - 1) / recording.sample_rate >= 0:
        n -= 1
    while n < len(recording) and recording.start_time + n / recording.sample_rate < 0:
        n += 1
    return n


def inspect_recording(recording: Recording) -> Inspection:
    """Duration, rate, channels with ranges and noise, peak force, contact pulses and stage B of ``recording``.

    Pulses come from the noise-aware detector of :mod:`impactometer.identify.pulses` (detection at 5 σ of the
    estimated white noise, release at 2 σ), on the force minus its pre-trigger median.
    """
    from .identify.pulses import Pulse, detect_pulses, noise_std, stage_b_start

    if not isinstance(recording, Recording):
        raise RecordingError(f"recording must be a Recording, got {type(recording).__name__}")
    channels = {name: ChannelSummary(unit=recording.unit(name), minimum=float(x.min()), maximum=float(x.max()),
                                     noise=noise_std(x)) for name, x in recording.channels.items()}
    pulses: list = []
    peak = peak_time = None
    offset = 0.0
    if FORCE in recording.channels:
        f = recording.contact_force
        dt = 1.0 / recording.sample_rate

        def t(i: int) -> float:  # as Recording.time gives it, without the array
            return recording.start_time + i / recording.sample_rate

        before = f[:_samples_before_contact(recording)]
        offset = float(np.median(before)) if before.size >= MIN_OFFSET_SAMPLES else 0.0
        f = f - offset
        k = int(np.argmax(f))
        peak, peak_time = float(f[k]), t(k)
        for span in detect_pulses(f, channels[FORCE].noise):
            stop = span.end if span.complete else f.size - 1
            first = pulses[0].end - pulses[0].start if pulses else None
            sustained = not span.complete or (first is not None and t(stop) - t(span.zero) > SUSTAINED_FACTOR * first)
            pulses.append(Pulse(start=t(span.zero), peak_time=t(span.peak), end=t(stop),
                                peak_force=float(f[span.peak]),
                                impulse=float(np.trapezoid(f[span.zero:stop + 1], dx=dt)),
                                sustained=bool(sustained)))
            if sustained:
                break
    return Inspection(duration=recording.duration, sample_rate=recording.sample_rate,
                      start_time=recording.start_time, samples=len(recording), channels=channels, peak_force=peak,
                      peak_force_time=peak_time, force_offset=offset, pulses=pulses,
                      stage_b_start=stage_b_start(pulses),
                      truth={k: v for k in TRUTH_KEYS if (v := recording.truth(k)) is not None})
