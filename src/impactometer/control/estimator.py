"""What the controller knows, updated at every sample from the sensors a real stand has.

Sensors (with noise): contact force Fc, piston acceleration a2, chamber pressures pL and pU, rod displacement u2.

- Chamber pressures: first-order low-pass filters (``tau_filter``).
- Piston position and velocity: an observer that integrates the measured acceleration and corrects it with the
  rod displacement (a second-order complementary filter of bandwidth ``observer_bandwidth``, critically damped):
  no drift, and far less noise than a differentiated displacement.
- Contact: on above 5 σ of the force sensor for 3 samples, off below 2 σ for 3 samples (the levels of the
  identification's pulse detector). Sustained contact (stage B) is a contact after the first that has lasted 1.5 ×
  the first contact pulse: the collision that starts it is over and the two bodies move together.
- Mass refinement: the bodies share one acceleration at the instants they have the same velocity, so
  M1·(g − a2) = Fc integrates exactly between them; the estimate is the ratio of the sums, Σ Fc / Σ (g − a2), over
  windows between such instants (:func:`_regress`), with the standard error sqrt(n·s²)/Σ (g − a2) from the residual
  variance s². It is combined with the mass known at the control start by inverse-variance weighting (that one's
  standard error never taken below 25 % of the value: the early answer rests on a few contact pulses, and on a
  stand that reaches stage B early its error is often larger than stated), and dropped when the two differ by more
  than 3 combined standard errors (an early answer of 5 kg for a 40 kg mass happens).
- What the identification answered (M1, V0 and M1's standard error) is known from the control start on; before,
  only the controller's own stage-B estimates exist.
- Mass velocity: before mass and piston move together, the momentum balance of the mass,
  v1 = V0 + g·t − ∫Fc dt / M1, with the latest M1 (unknown before the control start). Once they do (a sustained
  contact, or a contact that has held a whole window), it starts from the observer's piston velocity (mostly at a
  window end, an instant of equal velocities) and follows the momentum balance dv1/dt = g − Fc/M1, pulled towards
  the observer's velocity with a 5 Hz bandwidth: no drift, and nothing of the oscillation of the mass on the
  contact element (above 100 Hz), which the valve must not feed. The piston's mean velocity before that is the
  observer's, low-passed over 5 ms.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..identify.pulses import DETECT_SIGMAS, HOLD, RELEASE_SIGMAS
from ..model import dynamics as d
from . import settings as s

# slots of the estimator state
(IMPULSE, FORCE_PREV, P_LOWER_F, P_UPPER_F, X_HAT, V_HAT, ABOVE, BELOW, IN_CONTACT, CONTACT_START, FIRST_PULSE,
 MASS, MASS_STD, VELOCITY, SUSTAINED, LATCHED, OPENING_MODEL, TARGET, V_SLOW, STAGE_B, LOOKING, EXTREME,
 LAST_COMMIT, HAS_FIRST, COUNT, EXTREME_AT) = range(26)
#: blocks of the sums of the stage-B regression (Σ Fc, Σ (g − a2), Σ Fc², Σ (g − a2)², Σ Fc·(g − a2), n): running
#: within the current contact, at the first and the last window end of the current contact, and banked from
#: earlier contacts; then rings of the last RING samples' force and running sums
N_SUMS = 6
RING = 64
RUNNING, FIRST, LAST, BANK = (26 + N_SUMS * i for i in range(4))
FORCE_RING = 26 + 4 * N_SUMS
SUMS_RING = FORCE_RING + RING
N_ESTIMATOR = SUMS_RING + RING * N_SUMS
#: half width of the parabola fitted around a force extremum to time it [samples]
VERTEX_HALF_WIDTH = 16
#: time constant of the slow piston velocity [s]: the mean motion of mass and piston, without the oscillation of the
#: mass on the contact element (above 100 Hz on the built-in stands) that a valve must not feed
SLOW_VELOCITY_TIME = 5e-3
#: bandwidth of the correction of the mass velocity (momentum balance) towards the observer's in stage B [rad/s]
VELOCITY_CORRECTION = 2.0 * math.pi * 5.0
#: sustained contact: a contact after the first one that has lasted this multiple of the first pulse [-]. The rule
#: of ``identify.pulses.is_sustained`` (measured against the first pulse), compiled here because the loop cannot
#: call that Python function, and judged sample by sample while the contact runs (>=). Lower than
#: ``pulses.SUSTAINED_FACTOR`` (2 × the longest pulse before) on purpose: the loop needs the instant the collision
#: that starts the contact is over and the bodies move together, not the identification's stricter test of a bounce
SUSTAIN_FACTOR = 1.5
#: samples of sustained contact before the stage-B mass estimate is used
MIN_SAMPLES = 25
#: a window end is placed at least this often in sustained contact without force extrema [s]
COMMIT_TIME = 10e-3
#: floor of the relative standard error of the mass known at the control start [-]
PRIOR_FLOOR = 0.25
#: the prior is dropped when it and the stage-B estimate differ by more than this many combined standard errors
CONSISTENCY = 3.0
#: a mass estimate is acted on only when its standard error is below this fraction of it [-]: the identified one
#: (``control.identified.usable_mass``) and the controller's own stage-B estimate alike
MASS_TRUST = 1.0


@njit(cache=True, error_model="numpy")
def initial(y0, ctrl):
    """Controller state before first contact (piston at rest at its measured position, chambers as charged);
    besides the estimates it holds the latch of the supervisor, the controller's model of the valve opening and the
    last target force."""
    e = np.zeros(N_ESTIMATOR)
    e[P_LOWER_F] = y0[d.P_LOWER]
    e[P_UPPER_F] = y0[d.P_UPPER]
    e[X_HAT] = y0[d.U2]
    e[TARGET] = math.nan
    e[CONTACT_START] = math.nan
    e[FIRST_PULSE] = math.nan
    e[MASS] = math.nan
    e[MASS_STD] = math.inf
    e[VELOCITY] = math.nan
    return e


@njit(cache=True, error_model="numpy")
def update(e, t, dt, force, acceleration, p_lower, p_upper, displacement, gravity, ctrl):
    """Advance the estimator state ``e`` by one sample at time ``t`` [s] with the sensor readings (SI units)."""
    if t > 0.0:
        e[IMPULSE] += 0.5 * (e[FORCE_PREV] + force) * dt
    e[FORCE_PREV] = force
    alpha = dt / (ctrl[s.TAU_FILTER] + dt)
    e[P_LOWER_F] += alpha * (p_lower - e[P_LOWER_F])
    e[P_UPPER_F] += alpha * (p_upper - e[P_UPPER_F])
    # observer: predict with the measured acceleration, correct with the measured displacement
    w = ctrl[s.OBSERVER_BANDWIDTH] * dt
    e[X_HAT] += e[V_HAT] * dt + 0.5 * acceleration * dt * dt
    e[V_HAT] += acceleration * dt
    residual = displacement - e[X_HAT]
    e[X_HAT] += 2.0 * w * residual
    e[V_HAT] += w * w / dt * residual
    e[V_SLOW] += dt / (SLOW_VELOCITY_TIME + dt) * (e[V_HAT] - e[V_SLOW])
    # contact detection with hysteresis (levels of the pulse detector)
    sigma = max(ctrl[s.FORCE_NOISE], 1e-9)
    if e[IN_CONTACT] == 0.0:
        e[ABOVE] = e[ABOVE] + 1.0 if force > DETECT_SIGMAS * sigma else 0.0
        if e[ABOVE] >= HOLD:
            e[IN_CONTACT] = 1.0
            e[CONTACT_START] = t - (HOLD - 1) * dt
            e[BELOW] = 0.0
    else:
        e[BELOW] = e[BELOW] + 1.0 if force < RELEASE_SIGMAS * sigma else 0.0
        if e[BELOW] >= HOLD:
            e[IN_CONTACT] = 0.0
            e[ABOVE] = 0.0
            if math.isnan(e[FIRST_PULSE]):
                e[FIRST_PULSE] = t - (HOLD - 1) * dt - e[CONTACT_START]
    # pulses.is_sustained for the running contact (NaN FIRST_PULSE: still the first pulse, never sustained)
    e[SUSTAINED] = 1.0 if e[IN_CONTACT] != 0.0 and t - e[CONTACT_START] >= SUSTAIN_FACTOR * e[FIRST_PULSE] else 0.0
    if ctrl[s.REFINE_MASS] != 0.0:
        _regress(e, t, force, gravity - acceleration, DETECT_SIGMAS * sigma)
    if e[STAGE_B] == 0.0 and (e[SUSTAINED] != 0.0 or (e[IN_CONTACT] != 0.0 and e[HAS_FIRST] != 0.0
                                                      and e[LAST + 5] > e[FIRST + 5])):
        e[STAGE_B] = 1.0  # sustained, or a contact that has held a whole window: the bodies move together
    known = t >= ctrl[s.T_START]  # the identification's answer exists from the control start on
    _combine(e, ctrl, known)
    if e[STAGE_B] != 0.0:  # momentum balance of the mass, pulled slowly towards the observer's velocity
        if e[STAGE_B] == 1.0:  # onset: mostly at a window end, where both bodies have the piston's velocity
            e[VELOCITY] = e[V_HAT]
            e[STAGE_B] = 2.0
        deceleration = force / e[MASS] if e[MASS] > 0.0 else 0.0
        e[VELOCITY] += (gravity - deceleration) * dt + VELOCITY_CORRECTION * dt * (e[V_HAT] - e[VELOCITY])
    elif not known:
        e[VELOCITY] = math.nan
    elif e[MASS] > 0.0:
        e[VELOCITY] = ctrl[s.VELOCITY_HAT] + gravity * t - e[IMPULSE] / e[MASS]
    else:
        e[VELOCITY] = ctrl[s.VELOCITY_HAT] + gravity * t


@njit(cache=True, error_model="numpy")
def _commit(e, t, source):
    """Make the sums at slot ``source`` the last window end of the current contact (and its first, if none)."""
    if e[HAS_FIRST] == 0.0:
        for i in range(N_SUMS):
            e[FIRST + i] = e[source + i]
        e[HAS_FIRST] = 1.0
    for i in range(N_SUMS):
        e[LAST + i] = e[source + i]
    e[LAST_COMMIT] = t


@njit(cache=True, error_model="numpy")
def _vertex(e, at, count):
    """Sample count of the force extremum found near ``at``: the vertex of the least-squares parabola through the
    force samples within VERTEX_HALF_WIDTH of it (those still in the ring), rounded and kept within them. Noise
    moves the largest sample by several samples along a flat top; the vertex, far less."""
    low = max(at - VERTEX_HALF_WIDTH, count - RING + 1, 1.0)
    high = min(at + VERTEX_HALF_WIDTH, count)
    s0 = s1 = s2 = s3 = s4 = f0 = f1 = f2 = 0.0
    k = low
    while k <= high:
        x = k - at
        f = e[FORCE_RING + int(k) % RING]
        s0 += 1.0
        s1 += x
        s2 += x * x
        s3 += x * x * x
        s4 += x * x * x * x
        f0 += f
        f1 += f * x
        f2 += f * x * x
        k += 1.0
    # normal equations of f ≈ a + b·x + c·x², solved by Cramer's rule for b and c
    det = s0 * (s2 * s4 - s3 * s3) - s1 * (s1 * s4 - s3 * s2) + s2 * (s1 * s3 - s2 * s2)
    if s0 < 5.0 or det == 0.0:
        return at
    b = (s0 * (f1 * s4 - s3 * f2) - f0 * (s1 * s4 - s3 * s2) + s2 * (s1 * f2 - f1 * s2)) / det
    c = (s0 * (s2 * f2 - f1 * s3) - s1 * (s1 * f2 - f1 * s2) + f0 * (s1 * s3 - s2 * s2)) / det
    if c == 0.0:
        return at
    return min(max(at + round(-b / (2.0 * c)), low), high)


@njit(cache=True, error_model="numpy")
def _regress(e, t, force, shared, drop):
    """Stage-B regression of M1·(g − a2) = Fc over windows between equal-velocity instants.

    M1·∫(g − a2) dt = ∫Fc dt holds exactly only between instants where mass and piston have the same velocity (the
    paper's eq. 4): in contact the mass oscillates on the contact element, and a window cut elsewhere carries the
    relative velocity at its ends. Its extremes of compression are the extremes of the contact force, so the window
    ends are the force's extrema within one contact (confirmed once it has moved ``drop`` [N] away from them, timed
    by :func:`_vertex`), and, in a sustained contact without oscillation, an end every ``COMMIT_TIME``. A contact
    that ends banks its windows; a collision (one maximum) gives none.
    """
    if e[IN_CONTACT] == 0.0:
        for i in range(N_SUMS):  # the contact ended (or none yet): bank its windows, start afresh
            if e[HAS_FIRST] != 0.0:
                e[BANK + i] += e[LAST + i] - e[FIRST + i]
            e[RUNNING + i] = 0.0
        e[HAS_FIRST] = 0.0
        e[LOOKING] = 0.0
        e[COUNT] = 0.0
        return
    e[RUNNING] += force
    e[RUNNING + 1] += shared
    e[RUNNING + 2] += force * force
    e[RUNNING + 3] += shared * shared
    e[RUNNING + 4] += force * shared
    e[RUNNING + 5] += 1.0
    e[COUNT] += 1.0
    count = e[COUNT]
    slot = int(count) % RING
    e[FORCE_RING + slot] = force
    for i in range(N_SUMS):
        e[SUMS_RING + slot * N_SUMS + i] = e[RUNNING + i]
    if e[LOOKING] == 0.0:  # first sample of the contact
        e[LOOKING] = 1.0
        e[EXTREME] = force
        e[EXTREME_AT] = count
        e[LAST_COMMIT] = t
        return
    if (e[LOOKING] > 0.0 and force > e[EXTREME]) or (e[LOOKING] < 0.0 and force < e[EXTREME]):
        e[EXTREME] = force
        e[EXTREME_AT] = count
    elif abs(force - e[EXTREME]) > drop:  # the extremum is confirmed: a window end at its vertex
        vertex = _vertex(e, e[EXTREME_AT], count)
        _commit(e, t, SUMS_RING + (int(vertex) % RING) * N_SUMS)
        e[LOOKING] = -e[LOOKING]
        e[EXTREME] = force
        e[EXTREME_AT] = count
    if e[SUSTAINED] != 0.0 and t - e[LAST_COMMIT] > COMMIT_TIME:
        _commit(e, t, RUNNING)


@njit(cache=True, error_model="numpy")
def _combine(e, ctrl, known):
    """Mass estimate [kg] and its standard error from the prior (once ``known``) and the stage-B sums."""
    prior = ctrl[s.MASS_HAT] if known else math.nan
    prior_std = max(ctrl[s.MASS_STD], PRIOR_FLOOR * prior) if prior > 0.0 else math.inf
    sums = np.empty(N_SUMS)
    for i in range(N_SUMS):
        sums[i] = e[BANK + i] + (e[LAST + i] - e[FIRST + i] if e[HAS_FIRST] != 0.0 else 0.0)
    sum_f, sum_a, sum_ff, sum_aa, sum_fa, n = sums[0], sums[1], sums[2], sums[3], sums[4], sums[5]
    if n < MIN_SAMPLES or sum_a <= 0.0:
        e[MASS] = prior
        e[MASS_STD] = prior_std
        return
    stage_b = sum_f / sum_a
    variance = max(sum_ff - 2.0 * stage_b * sum_fa + stage_b * stage_b * sum_aa, 0.0) / (n - 1.0)
    stage_b_std = max(math.sqrt(n * variance) / sum_a, 1e-9 * stage_b)
    if not (prior > 0.0 and math.isfinite(prior_std)) \
            or abs(prior - stage_b) > CONSISTENCY * math.sqrt(prior_std * prior_std + stage_b_std * stage_b_std):
        # no prior, or one the stage-B data contradict: the data alone, once they can be trusted
        trusted = stage_b > 0.0 and stage_b_std < MASS_TRUST * stage_b
        e[MASS] = stage_b if trusted else math.nan
        e[MASS_STD] = stage_b_std if trusted else math.inf
        return
    w_prior = 1.0 / (prior_std * prior_std)
    w_b = 1.0 / (stage_b_std * stage_b_std)
    e[MASS] = (prior * w_prior + stage_b * w_b) / (w_prior + w_b)
    e[MASS_STD] = 1.0 / math.sqrt(w_prior + w_b)
