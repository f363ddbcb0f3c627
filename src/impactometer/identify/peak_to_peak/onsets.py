"""Contact onsets and separations located to a fraction of a sample by fitting the foot of a force edge.

A contact that starts at T makes the force rise as F = A·s^p·(1 + q·s), s = t − T > 0, and zero before: p = 0 is a
jump (viscous damping), 1 a linear and 1.5 a Hertzian foot; q bends the foot further up the edge. The exponent p
is free (a grid of ``EXPONENTS``), A and q are linear and solved for at every trial T, and T is scanned on a grid
of a fraction of a sample. A separation is the same fit run backwards in time from the end of a pulse.

How far up the edge the fit reaches follows from the noise: far enough for the edge to rise ``FOOT_SIGMAS``
noise standard deviations (between ``FOOT_TOP_MIN`` and ``FOOT_TOP_MAX`` of the pulse's peak). The curvature term
q is used only when the fit reaches beyond ``CURVED_ABOVE`` of the peak (below that the power law alone is exact
for the common contact laws). The answer is the centre of the set of trial times whose squares lie within one
scatter of the minimum, and its standard error half the width of that set (at least ``MIN_STD``).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ...signals.extrema import GRID_STEP
from ...signals.pulses import PulseSpan, detection_levels

#: exponents p of the foot F = A·s^p·(1 + q·s) tried (0: a jump)
EXPONENTS = np.arange(0.0, 2.0001, 0.25)
#: the fit reaches up the edge until it has risen this many noise standard deviations ...
FOOT_SIGMAS = 25.0
#: ... but at least and at most these fractions of the pulse's peak force
FOOT_TOP_MIN, FOOT_TOP_MAX = 0.1, 0.4
#: the curvature term q is fitted when the fit reaches beyond this fraction of the peak
CURVED_ABOVE = 0.15
#: the fit reaches at most this many samples on either side of the first detected sample
FOOT_SPAN = 64
#: smallest standard error of an edge time [samples]: an anti-alias filter smooths a jump over about a sample
MIN_STD = 0.25
#: coarse scan step over the whole window [samples]; the fine one around the best is the sub-sample timers'
#: :data:`~impactometer.signals.extrema.GRID_STEP`
COARSE_STEP = 0.25


def _profile(t: np.ndarray, f: np.ndarray, grid: np.ndarray, curved: bool) -> np.ndarray:
    """Least squares of the best foot at each trial time of ``grid`` (minimum over the exponents and A, q)."""
    return _foot_profile(np.asarray(t, dtype=float), np.ascontiguousarray(f, dtype=float),
                         np.asarray(grid, dtype=float), bool(curved), EXPONENTS)


@njit(cache=True)
def _foot_profile(t: np.ndarray, f: np.ndarray, grid: np.ndarray, curved: bool,
                  exponents: np.ndarray) -> np.ndarray:
    """:func:`_profile` as a compiled loop: for every trial time and exponent the normal equations of A (and q)
    are summed over the samples, solved in closed form, and the least sum of squares kept."""
    ff = 0.0
    for i in range(f.size):
        ff += f[i] * f[i]
    best = np.full(grid.size, np.inf)
    for g in range(grid.size):
        for k in range(exponents.size):
            p = exponents[k]
            g11 = r1 = g12 = g22 = r2 = 0.0
            for i in range(t.size):
                s = t[i] - grid[g]
                if s <= 0.0:
                    continue
                b1 = 1.0 if p == 0.0 else s ** p
                g11 += b1 * b1
                r1 += b1 * f[i]
                if curved:
                    b2 = b1 * s
                    g12 += b1 * b2
                    g22 += b2 * b2
                    r2 += b2 * f[i]
            if not curved:
                if g11 > 0.0:
                    amp = r1 / g11
                    if amp > 0.0:
                        best[g] = min(best[g], ff - amp * r1)
                continue
            det = g11 * g22 - g12 * g12
            if not det > 1e-12 * max(g11 * g22, 1e-300):
                continue
            amp = (g22 * r1 - g12 * r2) / det
            bend = (g11 * r2 - g12 * r1) / det
            if amp > 0.0:
                sse = ff - 2.0 * (amp * r1 + bend * r2) + amp * amp * g11 + 2.0 * amp * bend * g12 \
                    + bend * bend * g22
                best[g] = min(best[g], sse)
    return best


def onset_index(force: np.ndarray, span: PulseSpan, noise: float, *, earliest: int = 0) -> tuple[float, float]:
    """Sub-sample onset of a pulse and its standard error, both in samples.

    ``span`` gives the last zero-consistent sample before the pulse, its first detected sample and its peak; the
    search never starts before sample ``earliest`` (the end of the previous pulse).
    """
    f_all = np.asarray(force, dtype=float)
    sigma = max(float(noise), 1e-12)
    peak = float(f_all[span.peak])
    top = min(max(FOOT_TOP_MIN * peak, FOOT_SIGMAS * sigma), FOOT_TOP_MAX * peak)
    stop = span.first
    while stop < min(span.peak, span.first + FOOT_SPAN) and f_all[stop] < top:
        stop += 1
    stop = max(stop + 1, min(span.first + 3, span.peak + 1))
    # samples the edge needs to rise through the detection level: the onset may lie that far before it
    slope = max((f_all[stop - 1] - f_all[span.first]) / max(stop - 1 - span.first, 1), 1e-12)
    rise = int(min(np.ceil(max(f_all[span.first], 0.0) / slope), 64))
    lo = max(min(span.zero, span.first - max(2 * rise, stop - span.first, 8)) - 2, earliest, 0,
             span.first - FOOT_SPAN)
    t = np.arange(lo, stop, dtype=float)
    f = f_all[lo:stop]
    curved = top > CURVED_ABOVE * peak
    coarse = np.arange(lo, span.first + 1e-9, COARSE_STEP)
    full = _profile(t, f, coarse, curved)
    k = int(np.argmin(full))
    fine = np.arange(coarse[max(k - 8, 0)], coarse[min(k + 8, coarse.size - 1)] + 1e-9, GRID_STEP)
    sse = _profile(t, f, fine, curved)
    k = int(np.argmin(sse))
    # trial times whose squares stay within one scatter (the noise, or the misfit of the foot model) of the least,
    # on both grids: the fine one spans two samples either side of the coarse minimum, a flat foot's set more
    scatter2 = max(sigma ** 2, sse[k] / max(t.size - 4, 1))
    within = np.r_[coarse[full <= sse[k] + scatter2], fine[sse <= sse[k] + scatter2]]
    first, last = float(within.min()), float(within.max())
    return float(0.5 * (first + last)), float(max(0.5 * (last - first), MIN_STD))


def separation_index(force: np.ndarray, span: PulseSpan, noise: float, *, latest: int | None = None,
                     force_scale: float | None = None) -> tuple[float, float]:
    """Sub-sample time where a complete pulse's force returns to zero, and its standard error [samples].

    The onset fit run backwards in time; the search never goes past sample ``latest`` (the start of the next
    pulse). ``force_scale`` [N] is the largest force, which sets the detection level as in
    :func:`~impactometer.signals.pulses.detect_pulses`.
    """
    f_all = np.asarray(force, dtype=float)
    n = f_all.size
    detect, _ = detection_levels(noise, float(np.max(np.abs(f_all))) if force_scale is None else force_scale)
    above = np.flatnonzero(f_all[span.peak:span.end] > detect)
    last = span.peak + (int(above[-1]) if above.size else 0)
    mirrored = PulseSpan(zero=n - 1 - span.end, first=n - 1 - last, peak=n - 1 - span.peak, end=-1)
    earliest = 0 if latest is None else n - 1 - int(latest)
    index, std = onset_index(f_all[::-1], mirrored, noise, earliest=earliest)
    return float(n - 1 - index), std
