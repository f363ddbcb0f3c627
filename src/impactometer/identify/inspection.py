"""What a recording holds, as ``impactometer inspect`` reports it: duration, rate, channels with their ranges and
noise, peak force, the contact pulses (stage A) and the start of sustained contact (stage B)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import IdentificationError, RecordingError
from ..recording import ACCELERATION, FORCE, TRUTH_KEYS, Recording
from ..signals.noise import robust_noise_std
from ..signals.pulses import Pulse
from ..signals.stage_b import SUSTAINED_FACTOR, stage_b_start, sustained_index
from .peak_to_peak.segment import check_channels, segment_bounds, segment_of


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
    pulses : Contact pulses (``signals.pulses.Pulse``), the last one ``sustained`` when it is stage B.
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

    def plot(self, recording: Recording, axes=None):
        """Figure of ``recording`` (the one inspected): contact force and piston acceleration vs time, the pulses
        shaded and their peaks marked (:func:`impactometer.plotting.recordings.plot_recording`; matplotlib imported
        lazily)."""
        from ..plotting.recordings import plot_recording

        return plot_recording(recording, self, axes=axes)

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


def _first_impact(recording: Recording):
    """The first impact as the identification cuts and prepares it (offsets, noise, contact pulses; see
    :mod:`.peak_to_peak.segment`) and the sample it starts at; (None, 0) where the record holds no impact."""
    force = recording.contact_force
    acceleration = recording.channels.get(ACCELERATION)
    try:
        f, a, fs = check_channels(force, np.zeros_like(force) if acceleration is None else acceleration,
                                  recording.sample_rate)
        start, stop, _, pre = segment_bounds(f, fs)
        return segment_of(f, a, fs, recording.start_time, start, stop, pre, {}), start
    except IdentificationError:
        return None, 0


def inspect_recording(recording: Recording) -> Inspection:
    """Duration, rate, channels with ranges and noise, peak force, contact pulses and stage B of ``recording``.

    The contact pulses are those of the first impact as the identification finds them (:mod:`.peak_to_peak.segment`:
    the noise-aware detector of :mod:`impactometer.signals.pulses` on the force less its pre-trigger offset, at the
    noise the identification estimates, ringing left out), so that both report the same pulses.
    """
    if not isinstance(recording, Recording):
        raise RecordingError(f"recording must be a Recording, got {type(recording).__name__}")
    channels = {name: ChannelSummary(unit=recording.unit(name), minimum=float(x.min()), maximum=float(x.max()),
                                     noise=robust_noise_std(x)) for name, x in recording.channels.items()}
    pulses: list = []
    peak = peak_time = None
    offset = 0.0
    if FORCE in recording.channels:
        force = recording.contact_force
        dt = 1.0 / recording.sample_rate

        def t(i: int) -> float:  # as Recording.time gives it, without the array
            return recording.start_time + i / recording.sample_rate

        seg, start = _first_impact(recording)
        if seg is not None:
            offset = float(force[start] - seg.force[0])
        else:
            before = force[:_samples_before_contact(recording)]
            offset = float(np.median(before)) if before.size >= MIN_OFFSET_SAMPLES else 0.0
        f = force - offset
        k = int(np.argmax(f))
        peak, peak_time = float(f[k]), t(k)
        spans = [] if seg is None else seg.pulses
        stage_b = sustained_index(spans, size=seg.force.size if seg is not None else 0, factor=SUSTAINED_FACTOR)
        for k, span in enumerate(spans[:None if stage_b is None else stage_b + 1]):
            stop = span.end if span.complete else seg.force.size - 1
            pulses.append(Pulse(start=t(start + span.zero), peak_time=t(start + span.peak), end=t(start + stop),
                                peak_force=float(seg.force[span.peak]),
                                impulse=float(np.trapezoid(seg.force[span.zero:stop + 1], dx=dt)),
                                sustained=k == stage_b))
    return Inspection(duration=recording.duration, sample_rate=recording.sample_rate,
                      start_time=recording.start_time, samples=len(recording), channels=channels, peak_force=peak,
                      peak_force_time=peak_time, force_offset=offset, pulses=pulses,
                      stage_b_start=stage_b_start(pulses),
                      truth={k: v for k in TRUTH_KEYS if (v := recording.truth(k)) is not None})
