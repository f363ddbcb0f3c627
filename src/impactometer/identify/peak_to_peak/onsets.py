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

from ..pulses import PulseSpan, detection_levels

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
#: scan steps [samples]: coarse over the whole window, then fine around the best
COARSE_STEP, GRID_STEP = 0.25, 1.0 / 32.0


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
    :func:`~impactometer.identify.pulses.detect_pulses`.
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


#: a turning point of the force must stand out by this many noise levels of the smoothed force [-]
TURN_SIGMAS = 5.0
#: the vertex fit reaches from a turning point until the force has moved this fraction of its swing [-]
VERTEX_DROP = 0.25
#: fewest and most samples on each side of a turning point in its vertex fit
VERTEX_HALF_MIN, VERTEX_HALF_MAX = 3, 128


def turning_points(force: np.ndarray, lo: int, hi: int, noise: float, width: int) -> list[tuple[int, int, float]]:
    """Alternating maxima and minima of the force between samples ``lo`` and ``hi``, starting with a maximum.

    The force is smoothed by a moving average of ``width`` samples; a turning point counts once the smoothed
    force has moved away from it by ``TURN_SIGMAS`` of its noise (σ/√width). Returns (sample, +1 for a maximum
    or −1 for a minimum, swing [N] from the previous turning point or from the start).
    """
    f = np.asarray(force[lo:hi], dtype=float)
    width = max(int(width), 1)
    if f.size < width + 2:
        return []
    x = np.convolve(f, np.ones(width) / width, mode="same")
    threshold = TURN_SIGMAS * max(float(noise), 1e-12) / np.sqrt(width)
    out: list[tuple[int, int, float]] = []
    sign, cand, last = 1, 0, float(x[0])
    half = width // 2
    for i in range(half, x.size - half):
        if sign * (x[i] - x[cand]) > 0:
            cand = i
        elif sign * (x[cand] - x[i]) > threshold and sign * (x[cand] - last) > threshold:
            out.append((lo + cand, sign, abs(float(x[cand]) - last)))
            last, sign, cand = float(x[cand]), -sign, i
    return out


@njit(cache=True)
def _vertex_profile(t: np.ndarray, y: np.ndarray, grid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Least squares of y(t) by F_E + a±·s² + c±·s³ (s = t − E, coefficients apart on each side of E) at every
    trial E of ``grid``: (sum of squared residuals, coefficients (F_E, a−, a+, c−, c+)) per trial."""
    sse = np.empty(grid.size)
    coef = np.empty((grid.size, 5))
    basis = np.zeros(5)
    for g in range(grid.size):
        gram = 1e-12 * np.eye(5)
        rhs = np.zeros(5)
        for i in range(t.size):
            s = t[i] - grid[g]
            basis[:] = 0.0
            basis[0] = 1.0
            side = 1 if s < 0.0 else 2
            basis[side] = s * s
            basis[side + 2] = s * s * s
            for j in range(5):
                rhs[j] += basis[j] * y[i]
                for k in range(5):
                    gram[j, k] += basis[j] * basis[k]
        c = np.linalg.solve(gram, rhs)
        coef[g] = c
        total = 0.0
        for i in range(t.size):
            s = t[i] - grid[g]
            side = 1 if s < 0.0 else 2
            r = y[i] - c[0] - c[side] * s * s - c[side + 2] * s * s * s
            total += r * r
        sse[g] = total
    return sse, coef


def vertex(force: np.ndarray, centre: int, sign: int, swing: float, noise: float,
           width: int = 1) -> tuple[float, float, float] | None:
    """Sub-sample time [samples], its standard error [samples] and the force [N] of a turning point.

    Where the overlap turns, the force of any contact law turns with zero slope, but its curvature may differ
    on the two sides (a hysteretic contact loads and unloads along different lines: a cusp-like peak). So the
    samples around ``centre`` -- out to where the force, smoothed over ``width`` samples, has moved
    ``VERTEX_DROP`` of the ``swing`` on each side -- are fitted with F = F_E + a±·s² + c±·s³, s = t − E, the
    coefficients on each side of E free; E is scanned like an onset. None where the window leaves the data or
    the best E is not a maximum (``sign`` = +1) or a minimum (−1) inside the window.
    """
    f = np.asarray(force, dtype=float)
    width = max(int(width), 1)
    lo_w, hi_w = max(centre - 8 * width - 64, 0), min(centre + 8 * width + 64, f.size)
    x = np.convolve(f[lo_w:hi_w], np.ones(width) / width, mode="same")
    c = centre - lo_w
    level, drop = x[c], VERTEX_DROP * abs(swing)
    left = right = VERTEX_HALF_MIN
    while left < VERTEX_HALF_MAX and c - left - 1 >= width // 2 and abs(x[c - left] - level) < drop:
        left += 1
    while right < VERTEX_HALF_MAX and c + right + 1 < x.size - width // 2 and abs(x[c + right] - level) < drop:
        right += 1
    if centre - left < 0 or centre + right >= f.size or c - left < width // 2 or c + right >= x.size - width // 2:
        return None
    t = np.arange(-left, right + 1, dtype=float)
    y = np.ascontiguousarray(f[centre - left:centre + right + 1], dtype=float)

    def profile(grid):
        return _vertex_profile(t, y, np.asarray(grid, dtype=float))

    step = max(1.0, float((left + right) // 64))
    coarse = np.arange(-(left // 2), right // 2 + 1e-9, step)
    full, _ = profile(coarse)
    k = int(np.argmin(full))
    fine = np.arange(coarse[max(k - 1, 0)], coarse[min(k + 1, coarse.size - 1)] + 1e-9, GRID_STEP * step)
    sse, coef = profile(fine)
    k = int(np.argmin(sse))
    if not (0 < k < fine.size - 1 or coarse[0] < fine[k] < coarse[-1]) or np.any(sign * coef[k, 1:3] > 0):
        return None
    scatter2 = max(float(noise) ** 2, float(sse[k]) / max(t.size - 6, 1))
    inside = coarse[full <= sse[k] + scatter2]
    inside_fine = fine[sse <= sse[k] + scatter2]
    first = min(inside.min(), inside_fine.min()) if inside.size else inside_fine.min()
    last = max(inside.max(), inside_fine.max()) if inside.size else inside_fine.max()
    return centre + float(fine[k]), max(0.5 * (last - first), GRID_STEP), float(coef[k, 0])
