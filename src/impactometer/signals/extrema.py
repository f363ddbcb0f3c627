"""Where a force peak is timed: the turning points (maxima and minima) of the contact force, to a fraction of a
sample, for the identification and for the controller.

At a turning point the overlap of the bodies turns, and with it the force of any contact law, with zero slope but
a curvature that may differ on the two sides (a hysteretic contact loads and unloads along different lines: a
cusp-like peak). Both timers therefore fit F = F_E + a±·(t − E)² (+ c±·(t − E)³ in the batch), the coefficients
free on each side of the vertex E, scan E for the least squares, and state as the timing's standard error half
the width of the set of E whose squares lie within one scatter (the noise variance, or the batch fit's own misfit
where larger) of the least. One sign convention: ``sign``
= +1 times a maximum, −1 a minimum, and a fit whose curvature on a side has the other sign is no such turning
point (:func:`wrong_curvature`, shared by both).

Two forms, because the two users hold different data:

- :func:`vertex` (batch, identification): the whole record is there, so the fit reaches out to where the force,
  smoothed, has moved ``VERTEX_DROP`` of the swing (up to ``VERTEX_HALF_MAX`` samples each side), carries a cubic
  term for that longer reach, and scans E on a sub-sample grid (``GRID_STEP``). :func:`turning_points` finds the
  turning points it times.
- :func:`ring_vertex` (in-loop, controller): compiled and called inside the controller's kernel at the sample
  that confirms an extremum, with only a ring buffer of the last samples; parabolas only, fitted from running
  power sums (one pass over the samples from at most ``MAX_HALF_WIDTH`` before the extremum to the newest), E on
  whole samples.

They agree within their stated errors on noisy cusps (``tests/test_signals.py``, the agreement test).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .pulses import HOLD

#: fine scan step of the sub-sample timers [samples]: the batch vertex here and the onsets and separations
#: (``identify.peak_to_peak.onsets``); the least standard error of a batch vertex
GRID_STEP = 1.0 / 32.0


@njit(cache=True, error_model="numpy")
def wrong_curvature(curvature, sign):
    """Whether a fitted ``curvature`` (a± of one side) rules out a turning point of ``sign`` (+1: a maximum, −1:
    a minimum): a maximum bends down on both sides (a± <= 0), a minimum up; zero (a flat side) fits both."""
    return sign * curvature > 0.0


# --------------------------------------------------------------------------------------------------------------
# batch: the identification's timer, with the whole record

#: a turning point of the force must stand out by this many noise levels of the smoothed force [-]
TURN_SIGMAS = 5.0
#: the vertex fit reaches from a turning point until the force has moved this fraction of its swing [-]
VERTEX_DROP = 0.25
#: fewest and most samples on each side of a turning point in its vertex fit (most: at up to ``VERTEX_RATE``)
VERTEX_HALF_MIN, VERTEX_HALF_MAX = 3, 128
#: the sample rate up to which the vertex fit reaches ``VERTEX_HALF_MAX`` samples; above it, the same time [Hz]
VERTEX_RATE = 50e3


def vertex_reach(sample_rate: float) -> int:
    """Most samples on each side of a turning point in its vertex fit at ``sample_rate`` [Hz]: ``VERTEX_HALF_MAX``
    up to ``VERTEX_RATE``, the same time span (2.56 ms) above it. Fixed in samples, the fit saw 128 µs at 1 MHz of
    turning points in stage B that are milliseconds wide: fewer of them were timed, with standard errors that
    left M1 and V0 five standard errors off."""
    return max(VERTEX_HALF_MAX, int(round(VERTEX_HALF_MAX * float(sample_rate) / VERTEX_RATE)))


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


def smoothing_margin(width: int, reach: int = VERTEX_HALF_MAX) -> int:
    """Samples on each side of a turning point that :func:`vertex` smooths over ``width`` samples for a fit that
    reaches up to ``reach`` samples (:func:`vertex_reach`): with ``reach`` the samples a vertex reads (a cache key
    of its answer)."""
    return 8 * width + 64 + max(int(reach) - VERTEX_HALF_MAX, 0)


def vertex(force: np.ndarray, centre: int, sign: int, swing: float, noise: float,
           width: int = 1, reach: int = VERTEX_HALF_MAX) -> tuple[float, float, float] | None:
    """Sub-sample time [samples], its standard error [samples] and the force [N] of a turning point.

    Where the overlap turns, the force of any contact law turns with zero slope, but its curvature may differ
    on the two sides (a hysteretic contact loads and unloads along different lines: a cusp-like peak). So the
    samples around ``centre`` -- out to where the force, smoothed over ``width`` samples, has moved
    ``VERTEX_DROP`` of the ``swing`` on each side, up to ``reach`` samples (:func:`vertex_reach`) -- are fitted
    with F = F_E + a±·s² + c±·s³, s = t − E, the coefficients on each side of E free; E is scanned like an onset.
    None where the window leaves the data or the best E is not a maximum (``sign`` = +1) or a minimum (−1) inside
    the window.
    """
    f = np.asarray(force, dtype=float)
    width = max(int(width), 1)
    margin = smoothing_margin(width, reach)
    lo_w, hi_w = max(centre - margin, 0), min(centre + margin, f.size)
    x = np.convolve(f[lo_w:hi_w], np.ones(width) / width, mode="same")
    c = centre - lo_w
    level, drop = x[c], VERTEX_DROP * abs(swing)
    left = right = VERTEX_HALF_MIN
    while left < reach and c - left - 1 >= width // 2 and abs(x[c - left] - level) < drop:
        left += 1
    while right < reach and c + right + 1 < x.size - width // 2 and abs(x[c + right] - level) < drop:
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
    if not (0 < k < fine.size - 1 or coarse[0] < fine[k] < coarse[-1]) \
            or wrong_curvature(coef[k, 1], sign) or wrong_curvature(coef[k, 2], sign):
        return None
    scatter2 = max(float(noise) ** 2, float(sse[k]) / max(t.size - 6, 1))
    inside = coarse[full <= sse[k] + scatter2]
    inside_fine = fine[sse <= sse[k] + scatter2]
    first = min(inside.min(), inside_fine.min()) if inside.size else inside_fine.min()
    last = max(inside.max(), inside_fine.max()) if inside.size else inside_fine.max()
    return centre + float(fine[k]), max(0.5 * (last - first), GRID_STEP), float(coef[k, 0])

# --------------------------------------------------------------------------------------------------------------
# in-loop: the controller's timer, with a ring buffer

#: least and largest reach of the parabolas fitted before a force extremum to time it [samples]
MIN_HALF_WIDTH = 8.0
MAX_HALF_WIDTH = 120.0
#: samples the vertex keeps on each side within its fit (an extremum is confirmed by the pulse detector's HOLD
#: samples beyond the confirmation level)
EDGE = HOLD + 1


@njit(cache=True, error_model="numpy")
def _side(s0, s1, s2, s3, s4, f0, f1, f2, apex):
    """Σ x², Σ x⁴ and Σ f·x² of one side from its power sums (Σ k^p, Σ f·k^p), x = k − apex."""
    x2 = s2 - 2.0 * apex * s1 + apex * apex * s0
    x4 = s4 - 4.0 * apex * s3 + 6.0 * apex * apex * s2 - 4.0 * apex ** 3 * s1 + apex ** 4 * s0
    fx2 = f2 - 2.0 * apex * f1 + apex * apex * f0
    return x2, x4, fx2


@njit(cache=True, error_model="numpy")
def _fit(n, f0, ff, left, right, sign):
    """Least squares of F_E + a±·x² given each side's (Σ x², Σ x⁴, Σ f·x²), a± fitting a turning point of
    ``sign`` (+1: a maximum, :func:`wrong_curvature`) or zero: its residual sum of squares."""
    best = ff - f0 * f0 / n  # both sides flat
    for use_left in (False, True):
        for use_right in (False, True):
            if not (use_left or use_right):
                continue
            l2, l4, lf = left if use_left else (0.0, 0.0, 0.0)
            r2, r4, rf = right if use_right else (0.0, 0.0, 0.0)
            if (use_left and l4 <= 0.0) or (use_right and r4 <= 0.0):
                continue
            ll = l2 / l4 if use_left else 0.0
            rr = r2 / r4 if use_right else 0.0
            denominator = n - ll * l2 - rr * r2
            if denominator <= 1e-9 * n:
                continue
            c0 = (f0 - ll * lf - rr * rf) / denominator
            if (use_left and wrong_curvature(lf - c0 * l2, sign)) \
                    or (use_right and wrong_curvature(rf - c0 * r2, sign)):
                continue  # a curvature of the wrong sign: not this extremum
            cost = ff - 2.0 * c0 * f0 + n * c0 * c0
            if use_left:
                cost -= (lf - c0 * l2) ** 2 / l4
            if use_right:
                cost -= (rf - c0 * r2) ** 2 / r4
            best = min(best, cost)
    return best


@njit(cache=True, error_model="numpy")
def ring_vertex(ring, at, count, sigma, sign, drop):
    """Sample count of the force extremum near ``at`` (``sign`` +1: a maximum, −1: a minimum, as :func:`vertex`
    takes it) and the standard error of that timing [samples], from the force samples in ``ring`` (sample count
    k at ``ring[k % ring.size]``, up to the newest, ``count``).

    The vertex E of F_E + a±·(t − E)², a curvature of its own on each side, of the extremum's sign or zero (a
    contact loads and unloads along different lines, so its turning points are cusps), fitted by least squares to
    the force samples from where it was last ``drop`` [N] away from the extremum before ``at`` (as the confirmation
    after it; at least MIN_HALF_WIDTH and as far as the confirmation came after it) to the newest, E scanned over
    them: the fit brackets the extremum on both sides, over a long stretch where it is flat. The standard error is
    half the width of the set of E whose squares lie within ``sigma``² [N²] (one noise variance) of the least, at
    least half a sample; where E sits within EDGE samples of the edge of the fit, the fit's length. One parabola
    through a cusp leans to its flatter side (13 samples on the first peak of the built-in pad)."""
    # back from ``at`` as far as the force had to move to confirm it (HOLD samples beyond ``drop``), and as far as
    # the confirmation came after it
    extreme = ring[int(at) % ring.size]
    oldest = max(count - ring.size + 1, 1.0, at - MAX_HALF_WIDTH)
    low, beyond = at, 0
    while low > oldest and beyond < HOLD:
        low -= 1.0
        beyond = beyond + 1 if abs(ring[int(low) % ring.size] - extreme) > drop else 0
    low = max(min(low, at - (count - at), at - MIN_HALF_WIDTH), oldest)
    size = int(count - low) + 1
    if size < 2 * EDGE + 3:
        return at, float(size)
    # power sums over the window, k counted from its start
    c = np.zeros((8, size + 1))
    ff = 0.0
    for j in range(size):
        f = ring[int(low + j) % ring.size]
        ff += f * f
        k = float(j)
        c[0, j + 1] = c[0, j] + 1.0
        c[1, j + 1] = c[1, j] + k
        c[2, j + 1] = c[2, j] + k * k
        c[3, j + 1] = c[3, j] + k ** 3
        c[4, j + 1] = c[4, j] + k ** 4
        c[5, j + 1] = c[5, j] + f
        c[6, j + 1] = c[6, j] + f * k
        c[7, j + 1] = c[7, j] + f * k * k
    n, f0 = c[0, size], c[5, size]
    # the apex keeps EDGE samples on each side: a side of one or two samples fits them exactly, whatever E is
    costs = np.full(size, np.inf)
    for i in range(EDGE, size - EDGE):
        apex = float(i)
        left = _side(c[0, i], c[1, i], c[2, i], c[3, i], c[4, i], c[5, i], c[6, i], c[7, i], apex)
        right = _side(c[0, size] - c[0, i], c[1, size] - c[1, i], c[2, size] - c[2, i], c[3, size] - c[3, i],
                      c[4, size] - c[4, i], c[5, size] - c[5, i], c[6, size] - c[6, i], c[7, size] - c[7, i], apex)
        costs[i] = _fit(n, f0, ff, left, right, sign)
    best = int(np.argmin(costs))
    if best <= EDGE or best >= size - 1 - EDGE:
        return low + best, float(size)
    within = 0
    for i in range(size):
        if costs[i] <= costs[best] + sigma * sigma:
            within += 1
    return low + best, max(0.5 * within, 0.5)
