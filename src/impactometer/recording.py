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

from .errors import RecordingError, UnitError, shown
from .rig.limits import MASS_RANGE, VELOCITY_RANGE
from .units import parse_quantity
from .validation import check_real, is_real

FORCE = "contact_force"
ACCELERATION = "piston_acceleration"
#: valve Z's opening [-] (0 closed, 1 fully open), a channel a model fit reads as an input where a record holds it
VALVE_OPENING = "valve_opening"
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
    return check_real(field, value, low=low, high=high, unit=" Hz", state_range=True, error=error)


def truth_value(key: str, value: Any, where: str = "") -> float:
    """A known-truth metadata value (a number, or a text such as ``"30"`` or ``"30 kg"``) in SI units.

    RecordingError naming ``where`` and the key unless it is a finite number within :data:`TRUTH_RANGES`.
    """
    dimension, low, high = TRUTH_RANGES[key]
    if type(value) is float and low <= value <= high:  # a number in SI units already (what the checks below keep)
        return value
    plain = value.item() if isinstance(value, np.generic) else value
    if not (is_real(plain) or isinstance(plain, str)):
        raise RecordingError(f"{where}metadata {key} must be a number, got {shown(plain)}")
    try:
        number = parse_quantity(plain, dimension, field=f"metadata {key}")
    except UnitError as exc:
        raise RecordingError(f"{where}{exc}") from None
    if not low <= number <= high:
        raise RecordingError(f"{where}metadata {key} must be within [{low:g}, {high:g}] {TRUTH_UNITS[key]}, got "
                             f"{shown(plain)}")
    return number


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
    finite = np.isfinite(arr)
    if not finite.all():
        bad = np.flatnonzero(~finite)
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
        if not is_real(self.start_time) or not abs(self.start_time) <= START_TIME_LIMIT:
            raise RecordingError(f"{where}start_time must be a number within ±{START_TIME_LIMIT:g} [s], got "
                                 f"{shown(self.start_time)}")
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
        if not isinstance(name, str):
            raise RecordingError(f"{self.source}: a channel name must be a str, got {shown(name)}; channels found: "
                                 f"{sorted(self.channels)}")
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

    @property
    def units_note(self) -> str | None:
        """One sentence naming the channels read in SI units because the file stated none
        (``metadata['units_assumed']``, as :func:`impactometer.io.read_recording` notes it), else None."""
        assumed = self.metadata.get("units_assumed")
        if not isinstance(assumed, dict) or not assumed:
            return None
        listed = ", ".join(f"{name!r} as {unit}" for name, unit in assumed.items())
        return (f"{self.source}: the file states no units for {listed}, read so; if they are in other units (ms, "
                f"kN, g), state them {unit_statement(self.source)}")

    def with_metadata(self, **changes: Any) -> Recording:
        """A copy with metadata keys added or replaced."""
        return replace(self, metadata={**self.metadata, **changes})

    @classmethod
    def from_time(cls, time, channels: dict[str, Any], *, metadata: dict[str, Any] | None = None,
                  source: str = "memory") -> Recording:
        """A recording from a regular time vector [s] instead of a sample rate.

        The time must increase strictly and stay within 5 % of a period of a regular grid.
        """
        rate, start = time_base(samples(time, "time", source, squeeze=True), source)
        recording = cls(sample_rate=rate, channels=channels, start_time=start, metadata=dict(metadata or {}),
                        source=source)
        if np.size(time) != len(recording):
            raise RecordingError(f"{source}: time has {np.size(time)} samples but the channels have "
                                 f"{len(recording)}; expected equal lengths")
        return recording


#: a time column is regular when no sample is further than this fraction of a period from the fitted grid
TIME_JITTER = 0.05
#: samples of a time column checked at a time
TIME_BLOCK = 1 << 20


def unit_statement(source: str) -> str:
    """Where a file of ``source``'s format states the unit of a channel."""
    if str(source).lower().endswith(".csv"):
        return "in brackets after each column name ('force [kN]'), or as 'channel_units' in the JSON sidecar"
    return "as a 'unit' (HDF5, MAT) or 'unit_string' (TDMS) attribute of each channel"


def time_base(t: np.ndarray, source: str, *, scale: float = 1.0) -> tuple[float, float]:
    """(sample rate [Hz], start time [s]) of a time column ``t`` (in units of ``scale`` seconds); refuses
    non-monotonic or irregular time."""
    if t.size < 2:
        raise RecordingError(f"{source}: time must have at least 2 samples, got {t.size}")
    for start in range(0, t.size, TIME_BLOCK):  # a block at a time: no temporaries the size of the column
        steps = np.diff(t[start:start + TIME_BLOCK + 1])
        if np.any(steps <= 0):
            i = start + int(np.flatnonzero(steps <= 0)[0])
            raise RecordingError(f"{source}: time must increase strictly; sample {i + 1} ({float(t[i + 1]) * scale!r} "
                                 f"s) does not follow sample {i} ({float(t[i]) * scale!r} s)")
    first, period = float(t[0]) * scale, float(t[-1] - t[0]) * scale / (t.size - 1)
    check_sample_rate(1.0 / period if period > 0 else math.inf, f"{source}: the sample rate of the time column")
    for start in range(0, t.size, TIME_BLOCK):
        block = t[start:start + TIME_BLOCK] * scale
        deviation = np.abs(block - (first + period * np.arange(start, start + block.size)))
        if deviation.max() > TIME_JITTER * period:
            i = int(np.argmax(deviation))
            raise RecordingError(f"{source}: time must be regularly sampled; sample {start + i} is "
                                 f"{deviation[i]:.3g} s off the grid of period {period:.6g} s (tolerance "
                                 f"{TIME_JITTER:g} period)")
    return 1.0 / period, first
