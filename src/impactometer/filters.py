"""Channel frequency class (CFC) filters of SAE J211-1 / ISO 6487 for impact-test channels.

A CFC filter is a 2-pole Butterworth low-pass run forward and then backward over the data (4 poles, no phase
shift). Its coefficients come from the standard's design equations, not from a generic Butterworth design at the
nominal frequency:

    ωd = 2π·CFC·2.0775 (J211; ISO 6487 uses 2π·CFC·1.25·5/3),  ωa = tan(ωd·T/2),  D = 1 + √2·ωa + ωa²
    a0 = ωa²/D,  a1 = 2·a0,  a2 = a0,  b1 = −2·(ωa² − 1)/D,  b2 = (−1 + √2·ωa − ωa²)/D
    y[n] = a0·x[n] + a1·x[n−1] + a2·x[n−2] + b1·y[n−1] + b2·y[n−2]

Before filtering, each end is padded with a point-symmetric (odd) reflection of the data about the end sample
(``pad_time``, 10 ms by default, at most the record length), so the filter starts and ends without a step; the
padding is removed afterwards.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
from scipy import signal

from .errors import ParameterError, RecordingError, shown
from .recording import Recording
from .validation import check_real, is_real


@dataclass(frozen=True, kw_only=True)
class ChannelClass:
    """Corridor frequencies of one CFC: flat to ``f_h`` [Hz], −4 dB limit at ``f_n`` [Hz], stop band [dB]."""

    cfc: int
    f_h: float
    f_n: float
    stop_band_db: float


#: CFC -> corridor (SAE J211-1 table 1 / ISO 6487 table 1)
CFC_CLASSES = {
    60: ChannelClass(cfc=60, f_h=60.0, f_n=100.0, stop_band_db=-30.0),
    180: ChannelClass(cfc=180, f_h=180.0, f_n=300.0, stop_band_db=-30.0),
    600: ChannelClass(cfc=600, f_h=600.0, f_n=1000.0, stop_band_db=-40.0),
    1000: ChannelClass(cfc=1000, f_h=1000.0, f_n=1650.0, stop_band_db=-40.0),
}
#: standard -> factor from CFC to the design frequency ωd/(2π)
DESIGN_FACTORS = {"J211": 2.0775, "ISO6487": 1.25 * 5.0 / 3.0}
#: the sample rate must be at least this multiple of f_n
MIN_RATE_OVER_FN = 6.0
DEFAULT_PAD_TIME = 0.010


def channel_class(cfc: int) -> ChannelClass:
    """The corridor of ``cfc``; the error lists the valid classes."""
    if not is_real(cfc) or cfc not in CFC_CLASSES:
        raise ParameterError(f"cfc must be one of {sorted(CFC_CLASSES)}, got {cfc!r}")
    return CFC_CLASSES[int(cfc)]


def cfc_coefficients(cfc: int, sample_rate: float, *, standard: str = "J211") -> tuple[np.ndarray, np.ndarray]:
    """Numerator and denominator (scipy convention) of the 2-pole CFC section.

    Parameters
    ----------
    cfc : {60, 180, 600, 1000}
        Channel frequency class.
    sample_rate : float
        Sample rate [Hz]; at least 6·f_n of the class.
    standard : {"J211", "ISO6487"}
        Which design equation for ωd.

    Returns
    -------
    b, a : ndarray
        ``[a0, a1, a2]`` and ``[1, −b1, −b2]`` of the standard's difference equation.
    """
    klass = channel_class(cfc)
    if not isinstance(standard, str) or standard not in DESIGN_FACTORS:
        raise ParameterError(f"standard must be one of {sorted(DESIGN_FACTORS)}, got {shown(standard)}")
    check_real("sample_rate", sample_rate, low=MIN_RATE_OVER_FN * klass.f_n,
               unit=f" Hz (6 x f_n) for CFC {klass.cfc}")
    period = 1.0 / float(sample_rate)
    wd = 2.0 * math.pi * klass.cfc * DESIGN_FACTORS[standard]
    wa = math.sin(wd * period / 2.0) / math.cos(wd * period / 2.0)
    den = 1.0 + math.sqrt(2.0) * wa + wa * wa
    a0 = wa * wa / den
    b1 = -2.0 * (wa * wa - 1.0) / den
    b2 = (-1.0 + math.sqrt(2.0) * wa - wa * wa) / den
    return np.array([a0, 2.0 * a0, a0]), np.array([1.0, -b1, -b2])


def cfc_filter(x, sample_rate: float, cfc: int, *, standard: str = "J211", pad_time: float = DEFAULT_PAD_TIME,
               axis: int = -1) -> np.ndarray:
    """Filter ``x`` with channel frequency class ``cfc`` (phaseless, forward and backward).

    Parameters
    ----------
    x : array_like
        Samples (any unit), at least 3 along ``axis``.
    sample_rate : float
        Sample rate [Hz].
    cfc : {60, 180, 600, 1000}
        Channel frequency class.
    standard : {"J211", "ISO6487"}
        Design equation for ωd.
    pad_time : float
        Odd reflection added at each end before filtering [s] (capped at the record length).
    axis : int
        Time axis.

    Returns
    -------
    ndarray
        Filtered samples, same shape as ``x``.
    """
    b, a = cfc_coefficients(cfc, sample_rate, standard=standard)
    x = np.asarray(x, dtype=float)
    if x.ndim == 0 or x.shape[axis] < 3:
        raise ParameterError(f"x must hold at least 3 samples along axis {axis}, got shape {x.shape}")
    if not np.all(np.isfinite(x)):
        raise ParameterError("x must hold finite samples only")
    check_real("pad_time", pad_time, low=0.0, unit=" [s]")
    pad = min(int(round(pad_time * sample_rate)), x.shape[axis] - 1)
    return signal.filtfilt(b, a, x, axis=axis, padtype="odd" if pad else None, padlen=pad)


def cfc_response(cfc: int, sample_rate: float, frequency, *, standard: str = "J211") -> np.ndarray:
    """Gain of the phaseless CFC filter (both passes) at ``frequency`` [Hz], as a plain ratio."""
    b, a = cfc_coefficients(cfc, sample_rate, standard=standard)
    _, h = signal.freqz(b, a, worN=np.asarray(frequency, dtype=float), fs=sample_rate)
    return np.abs(h) ** 2


def cfc_corridor(cfc: int, frequency) -> tuple[np.ndarray, np.ndarray]:
    """Lower and upper gain limits [dB] of the J211-1 corridor at ``frequency`` [Hz].

    Lower: −0.5 dB up to f_h, −1 dB at f_h, −4 dB at f_n (linear in log f between), no limit above f_n.
    Upper: +0.5 dB up to f_n, then falling 9 dB/octave, never below the stop-band level.
    """
    klass = channel_class(cfc)
    try:
        f = np.asarray(frequency, dtype=float)
    except (TypeError, ValueError):
        f = np.array(np.nan)
    if not np.all(np.isfinite(f) & (f >= 0.0)):
        raise ParameterError(f"frequency must be finite numbers >= 0 [Hz], got {shown(frequency)}")
    lower = np.full(f.shape, -np.inf)
    lower[f <= klass.f_h] = -0.5
    mid = (f > klass.f_h) & (f <= klass.f_n)
    lower[mid] = -1.0 - 3.0 * np.log(f[mid] / klass.f_h) / math.log(klass.f_n / klass.f_h)
    upper = np.where(f <= klass.f_n, 0.5, 0.5 - 9.0 * np.log2(np.maximum(f, klass.f_n) / klass.f_n))
    return lower, np.maximum(upper, klass.stop_band_db)


def filter_recording(recording: Recording, cfc: int, *, channels: Sequence[str] | None = None,
                     standard: str = "J211") -> Recording:
    """The recording with ``channels`` (default: all) CFC-filtered; metadata notes the class per channel."""
    if not isinstance(recording, Recording):
        raise ParameterError(f"recording must be a Recording, got {type(recording).__name__}")
    names = list(recording.channels) if channels is None else list(channels)
    missing = [name for name in names if name not in recording.channels]
    if missing:
        raise RecordingError(f"{recording.source}: cannot filter missing channel(s) {missing}; channels found: "
                             f"{sorted(recording.channels)}")
    filtered = dict(recording.channels)
    for name in names:
        filtered[name] = cfc_filter(recording.channels[name], recording.sample_rate, cfc, standard=standard)
    metadata = dict(recording.metadata)
    metadata["cfc"] = {**metadata.get("cfc", {}), **{name: int(cfc) for name in names}} \
        if isinstance(metadata.get("cfc"), dict) else {name: int(cfc) for name in names}
    return replace(recording, channels=filtered, metadata=metadata)
