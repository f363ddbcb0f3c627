"""What the batch and the streaming peak-to-peak identification check before they start: the options they share,
and that the robust variant is not given filtered channels."""

from __future__ import annotations

from typing import Any

import numpy as np

from ...errors import IdentificationError, shown
from ...recording import START_TIME_LIMIT, Recording
from ...signals.noise import MAINS
from ...validation import check_real
from ..plausibility import CHANNEL_SYMBOLS
from ..result import VARIANTS
from .segment import Segment, lag_correlation


def check_options(variant: Any, gravity: Any, start_time: Any, *,
                  error: type[Exception] = IdentificationError) -> tuple[str, float, float]:
    """The options the batch and the streaming identification share, checked.

    Parameters
    ----------
    variant : {"robust", "paper"}
    gravity : float
        Gravitational acceleration [m/s²], within [0, 100].
    start_time : float
        Time of the first sample [s], within ±``START_TIME_LIMIT``.
    error : type
        Exception raised, naming the option, its value and what was expected.

    Returns
    -------
    tuple
        (variant, gravity [m/s²], start time [s]).
    """
    if not isinstance(variant, str) or variant not in VARIANTS:
        raise error(f"variant must be one of {sorted(VARIANTS)}, got {shown(variant)}")
    gravity = check_real("gravity", gravity, low=0.0, high=100.0, unit=" [m/s²]", error=error)
    start_time = check_real("start_time", start_time, low=-START_TIME_LIMIT, high=START_TIME_LIMIT, unit=" [s]",
                            error=error)
    return variant, gravity, start_time


def check_unfiltered(recording: Recording, variant: str) -> None:
    """IdentificationError when the robust variant is asked to identify channels the recording says were
    CFC-filtered (``metadata['cfc']``, as :func:`~impactometer.filters.filter_recording` notes it).

    A zero-phase low-pass filter spreads each contact onset ahead of the contact and colours the noise: the
    robust variant's onset times, noise model and standard errors would all be wrong (answers off by several
    standard errors, or absurd). It identifies the unfiltered channels instead; the paper variant, which reads
    peaks, accepts filtered ones.
    """
    filtered = recording.metadata.get("cfc")
    if variant != "robust" or not isinstance(filtered, dict):
        return
    named = {name: cfc for name, cfc in filtered.items() if name in ("contact_force", "piston_acceleration")}
    if named:
        listed = ", ".join(f"{name} (CFC {cfc})" for name, cfc in named.items())
        raise IdentificationError(f"{recording.source}: {listed} filtered; the robust identification needs the "
                                  "unfiltered channels (a zero-phase filter moves the contact onsets ahead of the "
                                  "contact and colours the noise, so its answers and standard errors would be "
                                  "wrong) -- identify without --cfc, or use --variant paper")


def filtered_caution(recording: Recording, variant: str) -> str | None:
    """A caution for the paper variant's answer from CFC-filtered channels, else None: the filter hides the noise
    (so the noise caution of :func:`~impactometer.identify.peak_to_peak.paper.paper_caution` stays silent) while it
    flattens and delays the force peaks that eqs. (3)-(5) read."""
    filtered = recording.metadata.get("cfc")
    if variant != "paper" or not isinstance(filtered, dict):
        return None
    named = {name: cfc for name, cfc in filtered.items() if name in ("contact_force", "piston_acceleration")}
    if not named:
        return None
    listed = ", ".join(f"{name} (CFC {cfc})" for name, cfc in named.items())
    return (f"{listed} low-pass filtered: the filter hides the sensor noise but flattens and shifts the force peaks "
            "that eqs. (3)-(5) read, so this answer may be far off (the robust variant on the unfiltered record "
            "accounts for the noise)")


#: lag-1 autocorrelation of the pre-trigger noise above which a channel counts as low-pass filtered [-]
COLOURED_LIMIT = 0.5




def check_white_noise(seg: Segment) -> None:
    """IdentificationError when the pre-trigger noise of a channel is correlated from sample to sample.

    A low-pass filter (CFC, a smoothing DAQ setting) colours the noise and spreads every contact onset ahead of
    the contact: the robust variant's noise model and onset times would then be wrong and its standard errors far
    too small, so it refuses rather than answer. Other causes correlate the pre-trigger too, and the refusal
    names them (:func:`correlated_cause`): mains hum, and a pre-trigger that is not at rest.
    """
    if seg.noise_correlation > COLOURED_LIMIT:
        cause = correlated_cause(seg)
        if cause:
            raise IdentificationError(f"{cause}; the robust variant needs white noise before the impact (its noise "
                                      f"model, and the offsets it removes)")
        raise IdentificationError(
            f"the channels look low-pass filtered: their pre-trigger noise has a sample-to-sample correlation of "
            f"{seg.noise_correlation:.2f} (white noise: about 0, limit {COLOURED_LIMIT}); the robust variant needs "
            "the unfiltered channels (a filter colours the noise and moves the contact onsets ahead of the "
            "contact) -- identify the record without --cfc, or use --variant paper")


def correlated_cause(seg: Segment) -> str | None:
    """Why the pre-trigger of a channel is correlated where its cause is not a low-pass filter, else None.

    Each correlated channel's pre-trigger is fitted with a straight line and, where it spans a period, with a
    straight line and a mains hum (:data:`MAINS`, with the second harmonic): a hum is named where its fit leaves
    white noise (lag-1 correlation within :data:`COLOURED_LIMIT`), a channel that is not at rest (it moves, or
    the record begins inside the impact) where the line alone does. Filtered noise stays correlated after both.
    """
    n = seg.pre_samples
    time = np.arange(n) / seg.sample_rate
    line = np.column_stack([np.ones(n), time - time.mean()])
    for name, x in (("contact_force", seg.force[:n]), ("piston_acceleration", seg.acceleration[:n])):
        if lag_correlation(x) <= COLOURED_LIMIT:
            continue
        hums = []
        for frequency in MAINS:
            if n < 0.5 * seg.sample_rate / frequency:  # under half a period: a hum cannot be told from a trend
                continue
            waves = [f(2.0 * np.pi * k * frequency * time) for k in (1, 2) for f in (np.sin, np.cos)]
            design = np.column_stack([line, *waves])
            fit = np.linalg.lstsq(design, x, rcond=None)[0]
            rest = x - design @ fit
            if lag_correlation(rest) <= COLOURED_LIMIT:
                hums.append((float(rest @ rest), frequency, float(np.hypot(fit[2], fit[3]))))
        if hums:  # the mains frequency that leaves the least
            _, frequency, amplitude = min(hums)
            peak = float(np.max(np.abs(seg.force if name == "contact_force" else seg.acceleration)))
            span = (time[-1] - time[0]) * 1e3
            return (f"the pre-trigger holds mains hum: {name} oscillates at the mains frequency (50/60 Hz; "
                    f"{frequency:g} Hz fits its {span:.3g} ms best) with an amplitude of {amplitude:.3g} "
                    f"{CHANNEL_SYMBOLS[name]} ({amplitude / peak:.2%} of its peak); remove the hum at its source "
                    "(grounding, shielding) or with a notch filter")
        fit = np.linalg.lstsq(line, x, rcond=None)[0]
        if lag_correlation(x - line @ fit) <= COLOURED_LIMIT:
            moved = float(fit[1] * (time[-1] - time[0]))
            return (f"the pre-trigger is not at rest: {name} moves by {moved:.3g} {CHANNEL_SYMBOLS[name]} over its "
                    f"{(time[-1] - time[0]) * 1e3:.3g} ms (a channel that drifts, or a record that begins inside the "
                    "impact)")
    return None
