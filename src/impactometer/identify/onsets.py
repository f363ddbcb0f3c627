"""Contact onsets located to a fraction of a sample by fitting the foot of each rising force edge."""

from __future__ import annotations

import numpy as np

from .pulses import PulseSpan

#: exponents of the power-law foot F = A·(t - t0)^p tried (1: linear, 1.5: Hertz/Hunt-Crossley)
FOOT_EXPONENTS = (1.0, 1.25, 1.5, 1.75, 2.0, 2.5)
#: the foot is fitted up to this fraction of the pulse's peak force
FOOT_TOP = 0.1
#: smallest standard error of an onset [samples] (the foot is never exactly a power law)
MIN_STD = 0.1
#: onset grid resolution [samples]: a coarse scan over all foot models, then a fine one around the best
COARSE_STEP, GRID_STEP = 0.25, 1.0 / 32.0


def _fit_sse(t, f, t0_grid, exponent):
    """Residual sum of squares of the best F = H(t-t0)·model over ``t0_grid`` for one foot family."""
    s = t[None, :] - t0_grid[:, None]
    on = s > 0.0
    if exponent is None:  # jump + line: F = J + S·(t - t0) after t0
        c0 = on.astype(float)
        c1 = np.where(on, s, 0.0)
        g00, g01, g11 = (c0 * c0).sum(1), (c0 * c1).sum(1), (c1 * c1).sum(1)
        r0, r1 = (c0 * f).sum(1), (c1 * f).sum(1)
        det = g00 * g11 - g01 ** 2
        det = np.where(det > 1e-12, det, np.inf)
        jump = (g11 * r0 - g01 * r1) / det
        slope = (g00 * r1 - g01 * r0) / det
        bad = jump < 0.0
        model = jump[:, None] * c0 + slope[:, None] * c1
        sse = ((f[None, :] - model) ** 2).sum(1)
        return np.where(bad, np.inf, sse)
    m = np.where(on, np.abs(s) ** exponent, 0.0)
    mm = (m * m).sum(1)
    amp = np.where(mm > 0, (m * f).sum(1) / np.where(mm > 0, mm, 1.0), 0.0)
    return ((f[None, :] - amp[:, None] * m) ** 2).sum(1)


def onset_index(force: np.ndarray, span: PulseSpan, noise: float, *, earliest: int = 0) -> tuple[float, float]:
    """Sub-sample onset of a pulse and its standard error, both in samples.

    Fits the foot of the rising edge (from two samples before the last zero-consistent sample up to
    ``FOOT_TOP`` of the peak) with a power law A·(t-t0)^p (p in ``FOOT_EXPONENTS``) and with a jump plus a line
    (the signature of viscous contact damping), each zero before t0; the family and t0 with the least squares,
    penalised by 2σ² per extra parameter, win. The onset is the centre of the t0 interval where the squares
    stay within σ² of the minimum and its standard error half that interval's width, at least the
    resolution of a jump (1/√12 sample). The search never starts before sample ``earliest`` (the end of the
    previous pulse).
    """
    f_all = np.asarray(force, dtype=float)
    sigma = max(float(noise), 1e-12)
    top = max(FOOT_TOP * f_all[span.peak], 10.0 * sigma)
    stop = span.first
    while stop < span.peak and f_all[stop] < top:
        stop += 1
    stop = max(stop + 1, min(span.first + 3, span.peak + 1))
    # samples the edge needs to rise through the detection level: the onset may lie that far before it
    slope = max((f_all[stop - 1] - f_all[span.first]) / max(stop - 1 - span.first, 1), 1e-12)
    rise = int(min(np.ceil(f_all[span.first] / slope), 64))
    lo = max(min(span.zero, span.first - 2 * rise) - 2, earliest, 0)
    t = np.arange(lo, stop, dtype=float)
    f = f_all[lo:stop]
    families = [(p, 0) for p in FOOT_EXPONENTS] + [(None, 1)]

    def scan(grid, candidates):
        best = None
        for exponent, extra in candidates:
            sse = _fit_sse(t, f, grid, exponent) + 2.0 * sigma ** 2 * extra
            k = int(np.argmin(sse))
            if best is None or sse[k] < best[0][best[1]]:
                best = (sse, k, exponent, extra)
        return best

    def interval(grid, sse, k):
        # the contiguous run around the minimum where the squares stay within one scatter of it
        scatter2 = max(sigma ** 2, sse[k] / max(t.size - 3, 1))  # the noise, or the misfit of the foot model
        inside = sse <= sse[k] + scatter2
        lo_k = hi_k = k
        while lo_k > 0 and inside[lo_k - 1]:
            lo_k -= 1
        while hi_k < grid.size - 1 and inside[hi_k + 1]:
            hi_k += 1
        return lo_k, hi_k

    coarse = np.arange(lo, span.first + 1e-9, COARSE_STEP)
    sse, k, exponent, extra = scan(coarse, families)
    lo_k, hi_k = interval(coarse, sse, k)
    fine = np.arange(coarse[max(lo_k - 1, 0)], coarse[min(hi_k + 1, coarse.size - 1)] + 1e-9, GRID_STEP)
    sse, k, _, _ = scan(fine, [(exponent, extra)])
    lo_k, hi_k = interval(fine, sse, k)
    onset = 0.5 * (fine[lo_k] + fine[hi_k])
    std = max(0.5 * (fine[hi_k] - fine[lo_k]), MIN_STD)
    return float(onset), float(std)
