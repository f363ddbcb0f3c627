"""Compiled sample-by-sample impact trigger shared by the batch and the streaming identification.

Inside an impact it follows the contact pulses with the detector of :mod:`.pulses` (its compiled step
:func:`~.pulses.edge`, its detection and release levels in running σ), with the hold
:data:`~.pulses.TRIGGER_HOLD` instead of the detector's :data:`~.pulses.HOLD` (both named and explained side by
side there).

One pass over the samples keeps a running (exponentially weighted) baseline and noise level of the force, fires
when the force leaves the noise, reports the end of each contact pulse and closes the impact after a quiet spell
or a maximum duration, then re-arms. Because it works sample by sample with all its state in two small arrays,
its events do not depend on how the samples are chunked.

A record may start at first contact (no quiet history before the impact: a simulation, a DAQ without
pre-trigger). The warm-up then holds the rise of the first pulse, which a baseline would learn as noise; so at
the end of the warm-up the spread of the samples is compared with the white noise seen in their second
differences (:func:`~.noise.second_difference_noise_std`), and a warm-up that rose far above its first sample
fires the trigger at sample 0 with a zero baseline (nothing before the record to learn an offset from).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .noise import second_difference_noise_std
from .pulses import DETECT_SIGMAS, RELEASE_SIGMAS, TRIGGER_HOLD, edge

IDLE, ACTIVE = 0, 1
EVENT_TRIGGER, EVENT_PULSE_END, EVENT_CLOSE, EVENT_PAST_PEAK = 1, 2, 3, 4
#: a pulse is past its peak when the force has fallen below this fraction of its maximum so far
PAST_PEAK_FRACTION = 0.5
#: time constant of the running baseline and noise level [samples] up to BASELINE_RATE [Hz]; above it the same
#: time (BASELINE_SAMPLES / BASELINE_RATE): at MHz rates the first contact takes thousands of samples to rise, and
#: a baseline with a fixed number of samples would follow that rise, its running σ growing with it, and never fire
BASELINE_SAMPLES, BASELINE_RATE = 256, 50e3
#: samples the baseline learns from before the trigger may fire
WARM_SAMPLES = 64
#: the trigger fires at this many running standard deviations above the baseline
TRIGGER_SIGMAS = 8.0

# float state: baseline mean, variance, frozen sigma at the trigger, frozen baseline, maximum of the pulse; while
# learning: first sample, the two previous samples, sum of squared second differences, largest sample
_MEAN, _VAR, _SIGMA, _BASE, _PMAX, _FIRST, _PREV1, _PREV2, _D2SUM, _WMAX = range(10)
# int state: mode, samples seen, index of trigger, samples since trigger, quiet run, inside a pulse, past peak,
# run of the pulse detector's step
_MODE, _SEEN, _TRIG, _SINCE, _QUIET, _INSIDE, _PAST, _RUN = range(8)
#: index of the int state that is 1 while the force is inside a pulse (read by the streaming identifier)
INSIDE = _INSIDE


def baseline_samples(sample_rate: float) -> int:
    """Time constant of the running baseline [samples] at ``sample_rate`` [Hz] (:data:`BASELINE_SAMPLES`)."""
    return max(BASELINE_SAMPLES, int(round(BASELINE_SAMPLES * sample_rate / BASELINE_RATE)))


def new_state() -> tuple[np.ndarray, np.ndarray]:
    """Fresh (float, int) state arrays of the trigger."""
    return np.zeros(10), np.zeros(8, dtype=np.int64)


@njit(cache=True)
def _starts_in_contact(x, index, fstate, floor):
    """Learn the warm-up sample ``x``; at its last sample, whether the record started at first contact.

    True when the warm-up rose more than ``TRIGGER_SIGMAS`` white-noise standard deviations (from the second
    differences, which a smooth pulse hardly has) above its first sample and its spread is as large.
    """
    if index == 0:
        fstate[_FIRST] = x
        fstate[_WMAX] = x
        fstate[_D2SUM] = 0.0
    else:
        if index >= 2:
            d2 = x - 2.0 * fstate[_PREV1] + fstate[_PREV2]
            fstate[_D2SUM] += d2 * d2
        if x > fstate[_WMAX]:
            fstate[_WMAX] = x
    fstate[_PREV2] = fstate[_PREV1]
    fstate[_PREV1] = x
    if index != WARM_SAMPLES - 1:
        return False
    noise = second_difference_noise_std(fstate[_D2SUM], index - 1)
    level = TRIGGER_SIGMAS * noise
    if level < floor:
        level = floor
    return fstate[_WMAX] - fstate[_FIRST] > level and np.sqrt(fstate[_VAR]) > level


@njit(cache=True)
def run_trigger(force, fstate, istate, floor, quiet_samples, max_samples, baseline, events):
    """Advance the trigger over ``force``; write (code, absolute sample index) rows into ``events``.

    Returns the number of events written (at most two per sample: a pulse past its peak and its end). ``floor`` [N]
    is the smallest trigger level (resolution of the channel), ``quiet_samples`` the release run that closes an
    impact, ``max_samples`` the longest impact, ``baseline`` the time constant of the running baseline
    (:func:`baseline_samples`).
    """
    alpha = 1.0 / baseline
    n_events = 0
    for k in range(force.shape[0]):
        x = force[k]
        index = istate[_SEEN]
        istate[_SEEN] += 1
        if istate[_MODE] == IDLE:
            sigma = np.sqrt(fstate[_VAR])
            level = TRIGGER_SIGMAS * sigma
            if level < floor:
                level = floor
            if index >= WARM_SAMPLES and x - fstate[_MEAN] > level:
                istate[_MODE] = ACTIVE
                istate[_TRIG] = index
                istate[_SINCE] = 0
                istate[_QUIET] = 0
                istate[_INSIDE] = 1
                fstate[_SIGMA] = sigma if sigma * DETECT_SIGMAS > floor else floor / DETECT_SIGMAS
                fstate[_BASE] = fstate[_MEAN]
                fstate[_PMAX] = x - fstate[_MEAN]
                istate[_PAST] = 0
                events[n_events, 0] = EVENT_TRIGGER
                events[n_events, 1] = index
                n_events += 1
            else:
                d = x - fstate[_MEAN]
                if index < WARM_SAMPLES:  # plain running mean and variance while learning
                    rate = 1.0 / (index + 1)
                elif d > 3.0 * sigma or d < -3.0 * sigma:  # outliers (the rise of a pulse) are not learnt
                    rate = 0.0
                else:
                    rate = alpha
                fstate[_MEAN] += rate * d
                fstate[_VAR] = (1.0 - rate) * (fstate[_VAR] + rate * d * d)
                if index < WARM_SAMPLES and _starts_in_contact(x, index, fstate, floor):
                    istate[_MODE] = ACTIVE
                    istate[_TRIG] = 0
                    istate[_SINCE] = index
                    noise = second_difference_noise_std(fstate[_D2SUM], index - 1)
                    fstate[_SIGMA] = noise if noise * DETECT_SIGMAS > floor else floor / DETECT_SIGMAS
                    fstate[_BASE] = 0.0
                    fstate[_PMAX] = fstate[_WMAX]
                    istate[_PAST] = 0
                    istate[_INSIDE] = 1 if x > RELEASE_SIGMAS * fstate[_SIGMA] else 0
                    istate[_QUIET] = 1 - istate[_INSIDE]
                    events[n_events, 0] = EVENT_TRIGGER
                    events[n_events, 1] = 0
                    n_events += 1
            continue
        istate[_SINCE] += 1
        y = x - fstate[_BASE]
        was = istate[_INSIDE]
        if was == 1:
            if y > fstate[_PMAX]:
                fstate[_PMAX] = y
            elif istate[_PAST] == 0 and y < PAST_PEAK_FRACTION * fstate[_PMAX] \
                    and fstate[_PMAX] > 2.0 * DETECT_SIGMAS * fstate[_SIGMA]:
                istate[_PAST] = 1
                events[n_events, 0] = EVENT_PAST_PEAK
                events[n_events, 1] = index
                n_events += 1
        release = RELEASE_SIGMAS * fstate[_SIGMA]
        istate[_INSIDE], istate[_RUN], changed = edge(y, DETECT_SIGMAS * fstate[_SIGMA], release, TRIGGER_HOLD,
                                                      was, istate[_RUN])
        if changed and was == 1:
            istate[_QUIET] = 1
            events[n_events, 0] = EVENT_PULSE_END
            events[n_events, 1] = index
            n_events += 1
        elif changed:
            istate[_QUIET] = 0
            istate[_PAST] = 0
            fstate[_PMAX] = y
        elif was == 0 and y <= release:
            istate[_QUIET] += 1
        if istate[_QUIET] >= quiet_samples or istate[_SINCE] >= max_samples:
            events[n_events, 0] = EVENT_CLOSE
            events[n_events, 1] = index
            n_events += 1
            istate[_MODE] = IDLE
            istate[_INSIDE] = 0
            istate[_RUN] = 0
            fstate[_VAR] = fstate[_SIGMA] ** 2
            fstate[_MEAN] = x
    return n_events
