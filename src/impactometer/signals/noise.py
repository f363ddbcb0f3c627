"""Noise estimators: the standard deviation σ of the white noise on a channel, three ways for three situations.

- :func:`quiet_noise_std` -- a quiet span (a pre-trigger: an offset plus white noise, nothing else). The sample
  standard deviation is then the most efficient σ; any slope, step or pulse in the span inflates it.
- :func:`robust_noise_std` -- a signal that holds the impact (smooth pulses, a few jumps). The median absolute
  second difference ignores the smooth signal and a few jumps, at the price of 2-3 times the scatter of the
  sample standard deviation on a quiet span.
- :func:`second_difference_noise_std` -- the compiled form for a kernel that sums squared second differences
  sample by sample (the trigger's warm-up, :mod:`.trigger`): the RMS of second differences, insensitive to a
  smooth rise but, unlike the median, not to jumps.

Second differences of white noise of variance σ² have variance 6σ² (1 + 4 + 1).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..errors import IdentificationError

#: variance of a second difference x[k+1] − 2·x[k] + x[k−1] of unit white noise [-]
SECOND_DIFFERENCE_VARIANCE = 6.0
#: median of |z| for a standard normal z (its 3rd quartile) [-]
GAUSSIAN_MAD = 0.6744897501960817


def quiet_noise_std(samples: np.ndarray, *, axis: int | None = None, ddof: int = 0):
    """Standard deviation of the white noise of a quiet span ``samples`` (offset plus white noise) [its units].

    The sample standard deviation (``numpy.std`` with ``axis`` and ``ddof``): use it on a pre-trigger, where
    nothing but the offset and the noise is recorded; on a span with a slope or a pulse use
    :func:`robust_noise_std`.
    """
    return np.std(samples, axis=axis, ddof=ddof)


def robust_noise_std(signal: np.ndarray) -> float:
    """Standard deviation of white noise on a smooth ``signal`` [signal units], pulses and a few jumps allowed.

    Median absolute second difference scaled for Gaussian noise (second differences of white noise have
    variance 6σ²); insensitive to the smooth signal and to a few jumps. Use it where no quiet span is known (a
    record without pre-trigger, the impact itself); on a quiet span :func:`quiet_noise_std` scatters less.
    """
    try:
        x = np.asarray(signal, dtype=float)
    except (TypeError, ValueError):
        raise IdentificationError("signal must be an array of numbers") from None
    if x.ndim > 1:
        raise IdentificationError(f"signal must be 1-D, got shape {x.shape}")
    if x.size < 3:
        return 0.0
    d2 = np.add(x[2:], x[:-2])  # one work array the size of the signal, whatever its length
    d2 -= x[1:-1]
    d2 -= x[1:-1]
    np.abs(d2, out=d2)
    middle = (d2.size - 1) // 2  # the median, by partitioning in place
    d2.partition((middle, d2.size // 2))
    median = 0.5 * (d2[middle] + d2[d2.size // 2])
    return float(median / (GAUSSIAN_MAD * np.sqrt(SECOND_DIFFERENCE_VARIANCE)))


@njit(cache=True)
def second_difference_noise_std(sum_squares, count):
    """Standard deviation of white noise from the sum ``sum_squares`` of ``count`` squared second differences
    [signal units] (compiled: a kernel accumulates the sum sample by sample).

    The RMS of the second differences over √6: efficient and blind to a smooth rise, but a jump in the span
    inflates it (:func:`robust_noise_std` is the robust form for a whole signal).
    """
    return np.sqrt(sum_squares / (SECOND_DIFFERENCE_VARIANCE * count))


#: mains frequencies [Hz] looked for in a pre-trigger
MAINS = (50.0, 60.0)
#: a mains hum is removed where its amplitude stands this many standard errors above zero (white noise alone
#: reaches it with a chance of about 4e-6 per frequency) [-]
HUM_SIGMAS = 5.0
#: fewest periods of the mains a pre-trigger must span for its hum to be extrapolated over the impact [-]
HUM_PERIODS = 0.8


def mains_hum(quiet: np.ndarray, sample_rate: float, size: int) -> np.ndarray | None:
    """The mains hum of a channel over ``size`` samples from the start of its quiet span ``quiet`` (a pre-trigger:
    offset, white noise and perhaps a hum), or None where the span shows none.

    The span is fitted with a constant and a sine and cosine at each mains frequency (:data:`MAINS`) it spans
    ``HUM_PERIODS`` of; the frequency whose fit leaves the least is taken where its amplitude stands
    ``HUM_SIGMAS`` standard errors above zero (the two coefficients against their covariance: a χ² of two degrees
    of freedom) and fits better than the other by as much (else none is taken). The hum, phase-locked to the
    mains, is extrapolated over the impact (a trend or a harmonic in the fit made that extrapolation from less
    than a period several times the hum itself): a hum of 0.2 % of the acceleration's peak at 50 Hz, left in, put
    M1 three standard errors off.
    """
    x = np.asarray(quiet, dtype=float)
    n = x.size
    time = np.arange(n) / float(sample_rate)
    found = []
    for frequency in MAINS:
        if n < HUM_PERIODS * sample_rate / frequency or n < 16:
            continue
        phase = 2.0 * np.pi * frequency * time
        design = np.column_stack([np.ones(n), np.sin(phase), np.cos(phase)])
        fit, *_ = np.linalg.lstsq(design, x, rcond=None)
        rest = x - design @ fit
        variance = float(rest @ rest) / max(n - design.shape[1], 1)
        if not variance > 0.0:
            continue
        cov = np.linalg.pinv(design.T @ design)[1:, 1:] * variance
        if float(fit[1:] @ np.linalg.solve(cov, fit[1:])) > HUM_SIGMAS ** 2:
            found.append((float(rest @ rest), variance, frequency, fit[1:]))
    found.sort(key=lambda item: item[0])
    # two mains frequencies that fit about as well cannot be told apart: the wrong one, extrapolated, doubles the hum
    if not found or (len(found) > 1 and (found[1][0] - found[0][0]) / found[0][1] < HUM_SIGMAS ** 2):
        return None
    _, _, frequency, (sine, cosine) = found[0]
    wave = 2.0 * np.pi * frequency * np.arange(size) / float(sample_rate)
    return sine * np.sin(wave) + cosine * np.cos(wave)
