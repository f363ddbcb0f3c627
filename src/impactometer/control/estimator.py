"""What the controller knows, updated at every sample from the sensors a real stand has.

Sensors (with noise): contact force Fc, piston acceleration a2, chamber pressures pL and pU, rod displacement u2.

- Chamber pressures: first-order low-pass filters (``tau_filter``).
- Piston position and velocity: an observer that integrates the measured acceleration and corrects it with the
  rod displacement (a second-order complementary filter of bandwidth ``observer_bandwidth``, critically damped):
  no drift, and far less noise than a differentiated displacement.
- Contact: on above 5 σ of the force sensor for 3 samples, off below 2 σ for 3 samples (the levels of the
  identification's pulse detector). Sustained contact (stage B) is a contact after the first that has lasted
  ``stage_b.SUSTAINED_CONTROL_FACTOR`` × the first contact pulse: the collision that starts it is over and the two
  bodies move together.
- Mass refinement: between two instants at which the bodies have the same velocity M1·(g − a2) = Fc integrates
  exactly, whatever happens between them; the estimate is Σ Fc / Σ (g − a2) between two such instants (the
  force's maxima, and its minima within a contact), chosen for the smallest error, with its standard error from
  the timing of those two instants and the sensor noise (:mod:`.windows`). It is combined with the mass known at
  the control start by inverse-variance weighting (that one's standard error never taken below ``mass_floor`` of
  the value: the relative error the identification that answered is validated to, 25 % for the peak-to-peak early
  answer and 1 % for the model's, :func:`.identified.mass_floor`), and dropped when the two differ by more than 3
  combined standard errors (an early peak-to-peak answer of 5 kg for a 40 kg mass happens). A mass known exactly
  (standard error 0, the oracle's) is not refined.
- What the identification answered (M1, V0 and M1's standard error) is known from the control start on; before,
  only the controller's own stage-B estimates exist, or, from ``early_start`` on, the partial knowledge the
  controller acts on from first contact: V0 from the first samples of the contact and M1 from a prior over the
  stand's rated masses (``early_mass`` ± ``early_mass_std``), which the stage-B estimate refines like an answer.
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

from ..model import dynamics
from ..signals.pulses import DETECT_SIGMAS, HOLD, RELEASE_SIGMAS
from ..signals.stage_b import controller_sustained
from . import windows
from .state import N_ESTIMATOR, Estimator, Settings, Windows

#: time constant of the slow piston velocity [s]: the mean motion of mass and piston, without the oscillation of the
#: mass on the contact element (above 100 Hz on the built-in stands) that a valve must not feed
SLOW_VELOCITY_TIME = 5e-3
#: bandwidth of the correction of the mass velocity (momentum balance) towards the observer's in stage B [rad/s]
VELOCITY_CORRECTION = 2.0 * math.pi * 5.0
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
    e[Estimator.P_LOWER_F] = y0[dynamics.P_LOWER]
    e[Estimator.P_UPPER_F] = y0[dynamics.P_UPPER]
    e[Estimator.X_HAT] = y0[dynamics.U2]
    e[Estimator.TARGET] = math.nan
    e[Estimator.CONTACT_START] = math.nan
    e[Estimator.FIRST_PULSE] = math.nan
    e[Estimator.MASS] = math.nan
    e[Estimator.MASS_STD] = math.inf
    e[Estimator.VELOCITY] = math.nan
    e[Estimator.WINDOWS:] = windows.initial()
    return e


@njit(cache=True, error_model="numpy")
def update(e, t, dt, force, acceleration, p_lower, p_upper, displacement, gravity, ctrl):
    """Advance the estimator state ``e`` by one sample at time ``t`` [s] with the sensor readings (SI units)."""
    if t > 0.0:
        e[Estimator.IMPULSE] += 0.5 * (e[Estimator.FORCE_PREV] + force) * dt
    e[Estimator.FORCE_PREV] = force
    alpha = dt / (ctrl[Settings.TAU_FILTER] + dt)
    e[Estimator.P_LOWER_F] += alpha * (p_lower - e[Estimator.P_LOWER_F])
    e[Estimator.P_UPPER_F] += alpha * (p_upper - e[Estimator.P_UPPER_F])
    # observer: predict with the measured acceleration, correct with the measured displacement
    w = ctrl[Settings.OBSERVER_BANDWIDTH] * dt
    e[Estimator.X_HAT] += e[Estimator.V_HAT] * dt + 0.5 * acceleration * dt * dt
    e[Estimator.V_HAT] += acceleration * dt
    residual = displacement - e[Estimator.X_HAT]
    e[Estimator.X_HAT] += 2.0 * w * residual
    e[Estimator.V_HAT] += w * w / dt * residual
    e[Estimator.V_SLOW] += dt / (SLOW_VELOCITY_TIME + dt) * (e[Estimator.V_HAT] - e[Estimator.V_SLOW])
    # contact detection with hysteresis (levels of the pulse detector)
    sigma = max(ctrl[Settings.FORCE_NOISE], 1e-9)
    if e[Estimator.IN_CONTACT] == 0.0:
        e[Estimator.ABOVE] = e[Estimator.ABOVE] + 1.0 if force > DETECT_SIGMAS * sigma else 0.0
        if e[Estimator.ABOVE] >= HOLD:
            e[Estimator.IN_CONTACT] = 1.0
            e[Estimator.CONTACT_START] = t - (HOLD - 1) * dt
            e[Estimator.BELOW] = 0.0
    else:
        e[Estimator.BELOW] = e[Estimator.BELOW] + 1.0 if force < RELEASE_SIGMAS * sigma else 0.0
        if e[Estimator.BELOW] >= HOLD:
            e[Estimator.IN_CONTACT] = 0.0
            e[Estimator.ABOVE] = 0.0
            if math.isnan(e[Estimator.FIRST_PULSE]):
                e[Estimator.FIRST_PULSE] = t - (HOLD - 1) * dt - e[Estimator.CONTACT_START]
    held = t - e[Estimator.CONTACT_START]
    sustained = e[Estimator.IN_CONTACT] != 0.0 and controller_sustained(held, e[Estimator.FIRST_PULSE])
    e[Estimator.SUSTAINED] = 1.0 if sustained else 0.0
    together = e[Estimator.SUSTAINED] != 0.0
    if ctrl[Settings.REFINE_MASS] != 0.0:  # a window within one contact also shows the bodies moving together
        together |= windows.push(e[Estimator.WINDOWS:], t, force, gravity - acceleration, DETECT_SIGMAS * sigma,
                                 e[Estimator.IN_CONTACT] != 0.0, e[Estimator.SUSTAINED] != 0.0, sigma,
                                 ctrl[Settings.ACCELERATION_NOISE])
    if e[Estimator.STAGE_B] == 0.0 and together:
        e[Estimator.STAGE_B] = 1.0
    known = t >= ctrl[Settings.START]  # the identification's answer exists from the control start on
    early = not known and t >= ctrl[Settings.EARLY_START]  # partial knowledge: V0 and a prior of M1
    _combine(e, ctrl, known, early)
    v0 = ctrl[Settings.EARLY_VELOCITY] if early else ctrl[Settings.VELOCITY]
    if e[Estimator.STAGE_B] != 0.0:  # momentum balance of the mass, pulled slowly towards the observer's velocity
        if e[Estimator.STAGE_B] == 1.0:  # onset: mostly at a window end, where both bodies have the piston's velocity
            e[Estimator.VELOCITY] = e[Estimator.V_HAT]
            e[Estimator.STAGE_B] = 2.0
        deceleration = force / e[Estimator.MASS] if e[Estimator.MASS] > 0.0 else 0.0
        e[Estimator.VELOCITY] += (gravity - deceleration) * dt \
            + VELOCITY_CORRECTION * dt * (e[Estimator.V_HAT] - e[Estimator.VELOCITY])
    elif not (known or early):
        e[Estimator.VELOCITY] = math.nan
    elif e[Estimator.MASS] > 0.0:
        e[Estimator.VELOCITY] = v0 + gravity * t - e[Estimator.IMPULSE] / e[Estimator.MASS]
    else:
        e[Estimator.VELOCITY] = v0 + gravity * t


@njit(cache=True, error_model="numpy")
def _combine(e, ctrl, known, early):
    """Mass estimate [kg] and its standard error from the prior (the answer once ``known``, its standard error
    floored at ``mass_floor`` of it; the rated masses' prior while ``early``) and the stage-B windows; a prior known
    exactly is kept."""
    if known:
        prior = ctrl[Settings.MASS]
        prior_std = max(ctrl[Settings.MASS_STD], ctrl[Settings.MASS_FLOOR] * prior) if prior > 0.0 else math.inf
    elif early:
        prior, prior_std = ctrl[Settings.EARLY_MASS], ctrl[Settings.EARLY_MASS_STD]
    else:
        prior, prior_std = math.nan, math.inf
    stage_b, stage_b_std = e[Estimator.WINDOWS + Windows.MASS], e[Estimator.WINDOWS + Windows.STD]
    if not (stage_b > 0.0 and math.isfinite(stage_b_std)) or (prior > 0.0 and prior_std == 0.0):
        e[Estimator.MASS] = prior
        e[Estimator.MASS_STD] = prior_std
        return
    if not (prior > 0.0 and math.isfinite(prior_std)) \
            or abs(prior - stage_b) > CONSISTENCY * math.sqrt(prior_std * prior_std + stage_b_std * stage_b_std):
        # no prior, or one the stage-B data contradict: the data alone, once they can be trusted
        trusted = stage_b > 0.0 and stage_b_std < MASS_TRUST * stage_b
        e[Estimator.MASS] = stage_b if trusted else math.nan
        e[Estimator.MASS_STD] = stage_b_std if trusted else math.inf
        return
    w_prior = 1.0 / (prior_std * prior_std)
    w_b = 1.0 / (stage_b_std * stage_b_std)
    e[Estimator.MASS] = (prior * w_prior + stage_b * w_b) / (w_prior + w_b)
    e[Estimator.MASS_STD] = 1.0 / math.sqrt(w_prior + w_b)
