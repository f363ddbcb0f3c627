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

from .pulses import PulseSpan, detection_levels

#: exponents p of the foot F = A·s^p·(1 + q·s) tried (0: a jump)
EXPONENTS = np.arange(0.0, 2.0001, 0.25)
#: the fit reaches up the edge until it has risen this many noise standard deviations ...
FOOT_SIGMAS = 25.0
#: ... but at least and at most these fractions of the pulse's peak force
FOOT_TOP_MIN, FOOT_TOP_MAX = 0.1, 0.4
#: the curvature term q is fitted when the fit reaches beyond this fraction of the peak
CURVED_ABOVE = 0.15
#: smallest standard error of an edge time [samples]: an anti-alias filter smooths a jump over about a sample
MIN_STD = 0.25
#: scan steps [samples]: coarse over the whole window, then fine around the best
COARSE_STEP, GRID_STEP = 0.25, 1.0 / 32.0


def _profile(t: np.ndarray, f: np.ndarray, grid: np.ndarray, curved: bool) -> np.ndarray:
    """Least squares of the best foot at each trial time of ``grid`` (minimum over the exponents and A, q)."""
    s = t[None, None, :] - grid[:, None, None]
    on = s > 0.0
    ss = np.where(on, s, 0.0)
    p = EXPONENTS[None, :, None]
    with np.errstate(divide="ignore", invalid="ignore"):
        b1 = np.where(on, np.where(p == 0.0, 1.0, ss ** p), 0.0)
    ff = float(f @ f)
    g11, r1 = (b1 * b1).sum(-1), (b1 * f).sum(-1)
    if not curved:
        amp = r1 / np.where(g11 > 0, g11, 1.0)
        return np.where((g11 > 0) & (amp > 0), ff - amp * r1, np.inf).min(1)
    b2 = b1 * ss
    g12, g22, r2 = (b1 * b2).sum(-1), (b2 * b2).sum(-1), (b2 * f).sum(-1)
    det = g11 * g22 - g12 ** 2
    ok = det > 1e-12 * np.maximum(g11 * g22, 1e-300)
    det = np.where(ok, det, 1.0)
    amp = (g22 * r1 - g12 * r2) / det
    bend = (g11 * r2 - g12 * r1) / det
    sse = ff - 2.0 * (amp * r1 + bend * r2) + amp * amp * g11 + 2.0 * amp * bend * g12 + bend * bend * g22
    return np.where(ok & (amp > 0), sse, np.inf).min(1)


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
    while stop < span.peak and f_all[stop] < top:
        stop += 1
    stop = max(stop + 1, min(span.first + 3, span.peak + 1))
    rise = stop - span.first
    lo = max(min(span.zero, span.first - max(2 * rise, 8)) - 2, earliest, 0)
    t = np.arange(lo, stop, dtype=float)
    f = f_all[lo:stop]
    curved = top > CURVED_ABOVE * peak
    coarse = np.arange(lo, span.first + 1e-9, COARSE_STEP)
    k = int(np.argmin(_profile(t, f, coarse, curved)))
    fine = np.arange(coarse[max(k - 8, 0)], coarse[min(k + 8, coarse.size - 1)] + 1e-9, GRID_STEP)
    sse = _profile(t, f, fine, curved)
    k = int(np.argmin(sse))
    # trial times whose squares stay within one scatter (the noise, or the misfit of the foot model) of the least
    scatter2 = max(sigma ** 2, sse[k] / max(t.size - 4, 1))
    inside = np.flatnonzero(sse <= sse[k] + scatter2)
    first, last = fine[inside[0]], fine[inside[-1]]
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
