"""The mass from windows between equal-velocity instants, sample by sample (compiled; the controller's stage-B
refinement, :mod:`.estimator`).

Between two instants at which mass and piston have the same velocity, M1·∫(g − a2) dt = ∫Fc dt holds exactly,
whatever happens between them -- a flight, a collision, the mass oscillating on the contact element (the paper's
eq. 4) -- and at no other: a window cut elsewhere carries the relative velocity at its ends. The extremes of
compression are the extremes of the contact force, so the ends are the force's maxima (the peak of every pulse)
and, while the contact has not opened since the last maximum, its minima (a minimum at zero force is no such
instant: the bodies may be apart, or the contact element slack); in a sustained contact without oscillation an end
comes every ``COMMIT_TIME``. The sums run over every sample from first contact on, so the windows between a first
and a last end add up to one: the estimate is M1 = (ΣFc)/(Σ(g − a2)) between two ends, and only the timing of those
two ends and the sensor noise matter, not the ends between them.

An end timed δ samples late adds δ·(Fc − M1·(g − a2)) there to the window's force sum: the relative acceleration of
the bodies times M1, largest at a collision's peak (thousands of N per sample on the built-in pad) and ten times
smaller at the peaks of stage B. Each end is timed by the vertex of a parabola with a curvature of its own on each
side (:func:`~impactometer.signals.extrema.ring_vertex`, the in-loop form of the one turning-point timer), with the
timing's standard error from its least-squares curve, so each end has an error e_j = |Fc − M1·(g − a2)|·σ_t; the
estimate starts at the stored end that gives it the smallest variance
(e_first² + e_last² + n·(σ_F² + M1²·σ_a²)) / (Σ(g − a2))², which skips the collisions of stage A as soon as stage B
has a few ends of its own, and that variance is scaled up by the windows' own scatter about the estimate (their
reduced chi-square, where above 1).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..signals.extrema import MAX_HALF_WIDTH, ring_vertex
from ..signals.pulses import HOLD
from .state import END_SLOTS, MAX_ENDS, N_SUMS, N_WINDOWS, RING, End, Sums, Windows

#: samples either side of an end over which Fc and g − a2 there are averaged
AT_HALF_WIDTH = 2
#: an end is placed at least this often in sustained contact without force extrema [s]
COMMIT_TIME = 10e-3


@njit(cache=True, error_model="numpy")
def initial():
    """State before first contact: looking for the first force maximum, no estimate."""
    w = np.zeros(N_WINDOWS)
    w[Windows.LOOKING] = 1.0
    w[Windows.EXTREME] = -math.inf
    w[Windows.MASS] = math.nan
    w[Windows.STD] = math.inf
    return w


@njit(cache=True, error_model="numpy")
def _at(w, ring_count, count):
    """Mean Fc and g − a2 over the samples within AT_HALF_WIDTH of ``ring_count`` (those in the ring)."""
    low = max(ring_count - AT_HALF_WIDTH, count - RING + 2, 2.0)
    high = min(ring_count + AT_HALF_WIDTH, count)
    force = 0.0
    k = low
    while k <= high:
        force += w[Windows.FORCE_RING + int(k) % RING]
        k += 1.0
    first = Windows.SUMS_RING + (int(low - 1.0) % RING) * N_SUMS
    last = Windows.SUMS_RING + (int(high) % RING) * N_SUMS
    samples = high - low + 1.0
    return force / samples, (w[last + Sums.SHARED] - w[first + Sums.SHARED]) / samples


@njit(cache=True, error_model="numpy")
def _store_end(w, t, source, force_at, shared_at, timing, sigma_f, sigma_a):
    """An end at the running sums in slot ``source``; then the estimate from the stored ends."""
    slot = min(int(w[Windows.N_ENDS]), MAX_ENDS - 1)
    base = Windows.ENDS + slot * END_SLOTS
    for i in range(N_SUMS):
        w[base + i] = w[source + i]
    w[base + End.FORCE_AT] = force_at
    w[base + End.SHARED_AT] = shared_at
    w[base + End.TIMING] = timing
    w[Windows.N_ENDS] = slot + 1.0
    w[Windows.OPENED] = 0.0
    w[Windows.LAST_COMMIT] = t
    _estimate(w, sigma_f, sigma_a)


@njit(cache=True, error_model="numpy")
def _error(w, end, mass):
    """Standard error of the force sum that the timing of stored end ``end`` brings [N·samples]."""
    base = Windows.ENDS + end * END_SLOTS
    return abs(w[base + End.FORCE_AT] - mass * w[base + End.SHARED_AT]) * w[base + End.TIMING]


@njit(cache=True, inline="always", error_model="numpy")
def _noise(samples, mass, sigma_f, sigma_a):
    """Variance [N²·samples²] of Σ (Fc − M1·(g − a2)) over ``samples`` samples from the sensors' white noise."""
    return samples * (sigma_f * sigma_f + mass * mass * sigma_a * sigma_a)


@njit(cache=True, error_model="numpy")
def _estimate(w, sigma_f, sigma_a):
    """M1 and its standard error from the first end that gives the smallest variance to the newest."""
    last = int(w[Windows.N_ENDS]) - 1
    best_var, mass, first = math.inf, math.nan, -1
    lb = Windows.ENDS + last * END_SLOTS
    for j in range(last - 1):  # at least two windows, so that their scatter can check the estimate
        jb = Windows.ENDS + j * END_SLOTS
        shared = w[lb + Sums.SHARED] - w[jb + Sums.SHARED]
        if shared <= 0.0:
            continue
        m = (w[lb + Sums.FORCE] - w[jb + Sums.FORCE]) / shared
        if m <= 0.0:
            continue
        samples = w[lb + Sums.SAMPLES] - w[jb + Sums.SAMPLES]
        var = (_error(w, j, m) ** 2 + _error(w, last, m) ** 2 + _noise(samples, m, sigma_f, sigma_a)) \
            / (shared * shared)
        if var < best_var:
            best_var, mass, first = var, m, j
    if first < 0:
        w[Windows.MASS] = math.nan
        w[Windows.STD] = math.inf
        return
    # the windows' scatter about the estimate, against what the model of the ends and the noise expects
    chi2, windows = 0.0, 0.0
    for k in range(first + 1, last + 1):
        kb, pb = Windows.ENDS + k * END_SLOTS, Windows.ENDS + (k - 1) * END_SLOTS
        residual = (w[kb + Sums.FORCE] - w[pb + Sums.FORCE]) - mass * (w[kb + Sums.SHARED] - w[pb + Sums.SHARED])
        expected = _error(w, k, mass) ** 2 + _error(w, k - 1, mass) ** 2 \
            + _noise(w[kb + Sums.SAMPLES] - w[pb + Sums.SAMPLES], mass, sigma_f, sigma_a)
        if expected > 0.0:
            chi2 += residual * residual / expected
            windows += 1.0
    if windows >= 2.0:
        best_var *= max(1.0, chi2 / (windows - 1.0))
    w[Windows.MASS] = mass
    w[Windows.STD] = math.sqrt(best_var)


@njit(cache=True, error_model="numpy")
def push(w, t, force, shared, drop, in_contact, sustained, sigma_f, sigma_a):
    """One sample: Fc [N] and g − a2 [m/s²] at ``t`` [s]; ``drop`` [N] confirms an extremum; the contact state of
    the estimator; the sensors' noise σ_F [N] and σ_a [m/s²]. Returns True when a window within one contact (no
    opening between its ends) has just closed: the bodies move together."""
    if w[Windows.COUNT] == 0.0 and not in_contact:
        return False  # before first contact
    w[Windows.RUNNING + Sums.FORCE] += force
    w[Windows.RUNNING + Sums.SHARED] += shared
    w[Windows.RUNNING + Sums.SAMPLES] += 1.0
    w[Windows.COUNT] += 1.0
    count = w[Windows.COUNT]
    slot = int(count) % RING
    w[Windows.FORCE_RING + slot] = force
    for i in range(N_SUMS):
        w[Windows.SUMS_RING + slot * N_SUMS + i] = w[Windows.RUNNING + i]
    if not in_contact:  # open: the next end is the next contact's maximum
        w[Windows.OPENED] = 1.0
        w[Windows.LOOKING] = 1.0
        w[Windows.EXTREME] = -math.inf
        w[Windows.BEYOND] = 0.0
        return False
    together = False
    looking, extreme = w[Windows.LOOKING], w[Windows.EXTREME]
    if (looking > 0.0 and force > extreme) or (looking < 0.0 and force < extreme):
        w[Windows.EXTREME] = force
        w[Windows.EXTREME_AT] = count
        w[Windows.BEYOND] = 0.0
    elif abs(force - w[Windows.EXTREME]) <= drop:
        w[Windows.BEYOND] = 0.0
    else:
        w[Windows.BEYOND] += 1.0
    if w[Windows.BEYOND] >= HOLD:  # the extremum is confirmed: an end at its vertex
        w[Windows.BEYOND] = 0.0
        ring = w[Windows.FORCE_RING:Windows.FORCE_RING + RING]
        at, timing = ring_vertex(ring, w[Windows.EXTREME_AT], count, sigma_f, w[Windows.LOOKING], drop)
        together = w[Windows.OPENED] == 0.0 and w[Windows.N_ENDS] > 0.0
        force_at, shared_at = _at(w, at, count)
        source = Windows.SUMS_RING + (int(at) % RING) * N_SUMS
        _store_end(w, t, source, force_at, shared_at, timing, sigma_f, sigma_a)
        w[Windows.LOOKING] = -w[Windows.LOOKING]
        w[Windows.EXTREME] = force
        w[Windows.EXTREME_AT] = count
    if sustained and t - w[Windows.LAST_COMMIT] > COMMIT_TIME:
        force_at, shared_at = _at(w, count, count)
        _store_end(w, t, Windows.RUNNING, force_at, shared_at, MAX_HALF_WIDTH, sigma_f, sigma_a)
    return together
