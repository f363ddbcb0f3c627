"""A recording: regularly sampled sensor channels of one drop test, in SI units, with metadata.

Conventions: ``contact_force`` [N] positive in compression; ``piston_acceleration`` [m/s²] positive downward
(the impact direction) and kinematic (gravity removed). Time 0 is first contact; ``start_time`` is the time of
the first sample (negative when pre-trigger samples are present). Metadata keys for known truth:
``mass_kg``, ``velocity_m_s``, ``pressure_gauge_Pa``; any other keys are kept as they are.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .errors import RecordingError

FORCE = "contact_force"
ACCELERATION = "piston_acceleration"
#: SI unit of the standard channels
CHANNEL_UNITS = {FORCE: "N", ACCELERATION: "m/s^2", "u1": "m", "u2": "m", "piston_displacement": "m",
                 "pressure_lower": "Pa", "pressure_upper": "Pa"}
TRUTH_KEYS = ("mass_kg", "velocity_m_s", "pressure_gauge_Pa")


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
        if isinstance(self.sample_rate, bool) or not isinstance(self.sample_rate, (int, float)) \
                or not math.isfinite(self.sample_rate) or self.sample_rate <= 0:
            raise RecordingError(f"{where}sample_rate must be a finite number > 0 [Hz], got {self.sample_rate!r}")
        if not isinstance(self.start_time, (int, float)) or not math.isfinite(self.start_time):
            raise RecordingError(f"{where}start_time must be a finite number [s], got {self.start_time!r}")
        if not isinstance(self.channels, dict) or not self.channels:
            raise RecordingError(f"{where}channels must be a non-empty mapping of name -> samples")
        length = None
        clean = {}
        for name, values in self.channels.items():
            try:
                arr = np.asarray(values, dtype=float)
            except (TypeError, ValueError):
                raise RecordingError(f"{where}channel {name!r} must hold numbers") from None
            if arr.ndim != 1 or arr.size == 0:
                raise RecordingError(f"{where}channel {name!r} must be a non-empty 1-D array, got shape {arr.shape}")
            bad = np.flatnonzero(~np.isfinite(arr))
            if bad.size:
                raise RecordingError(f"{where}channel {name!r} has a non-finite sample "
                                     f"({float(arr[bad[0]])!r}) at index "
                                     f"{int(bad[0])}; expected finite numbers")
            if length is not None and arr.size != length:
                raise RecordingError(f"{where}channels must have equal lengths, got {arr.size} samples in "
                                     f"{name!r} and {length} before")
            length = arr.size
            clean[name] = arr
        object.__setattr__(self, "channels", clean)
        if not isinstance(self.metadata, dict):
            raise RecordingError(f"{where}metadata must be a mapping, got {type(self.metadata).__name__}")

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
