"""Contact pulses of a force signal (stage A) and the start of sustained contact (stage B)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import IdentificationError


@dataclass(frozen=True, kw_only=True)
class Pulse:
    """One contact pulse: onset, peak and end times [s], peak force [N], impulse ∫Fc dt [N·s]."""

    start: float
    peak_time: float
    end: float
    peak_force: float
    impulse: float
    sustained: bool = False


def contact_pulses(time: np.ndarray, force: np.ndarray, *, threshold: float = 0.0,
                   sustained_factor: float = 4.0) -> list[Pulse]:
    """Contact pulses of ``force`` [N] sampled at ``time`` [s]: runs where the force exceeds ``threshold`` [N].

    A pulse is marked ``sustained`` (stage B) when it lasts to the end of the record or lasts longer than
    ``sustained_factor`` times the first pulse; pulses after the first sustained one are not reported.
    """
    time = np.asarray(time, dtype=float)
    force = np.asarray(force, dtype=float)
    if time.shape != force.shape or time.ndim != 1 or time.size < 3:
        raise IdentificationError(f"time and force must be 1-D arrays of equal length >= 3, got shapes "
                                  f"{time.shape} and {force.shape}")
    above = force > threshold
    edges = np.diff(above.astype(np.int8))
    starts = list(np.flatnonzero(edges == 1) + 1)
    ends = list(np.flatnonzero(edges == -1) + 1)
    if above[0]:
        starts.insert(0, 0)
    if above[-1]:
        ends.append(force.size)
    pulses: list[Pulse] = []
    for i0, i1 in zip(starts, ends):
        segment = slice(max(i0 - 1, 0), min(i1 + 1, force.size))
        ipk = i0 + int(np.argmax(force[i0:i1]))
        t_start = time[max(i0 - 1, 0)]
        t_end = time[min(i1, force.size - 1)]
        first = pulses[0].end - pulses[0].start if pulses else None
        sustained = i1 == force.size or (first is not None and t_end - t_start > sustained_factor * first)
        pulses.append(Pulse(start=float(t_start), peak_time=float(time[ipk]), end=float(t_end),
                            peak_force=float(force[ipk]),
                            impulse=float(np.trapezoid(np.clip(force[segment], 0.0, None), time[segment])),
                            sustained=bool(sustained)))
        if sustained:
            break
    return pulses


def stage_b_start(pulses: list[Pulse]) -> float | None:
    """Start of sustained contact (stage B) [s], or None when the record has none."""
    return next((p.start for p in pulses if p.sustained), None)
