"""What the batch and the streaming peak-to-peak identification check before they start: the options they share,
and that the robust variant is not given filtered channels."""

from __future__ import annotations

from typing import Any

from ...errors import IdentificationError, shown
from ...recording import START_TIME_LIMIT, Recording
from ...validation import check_real
from ..result import VARIANTS
from .segment import Segment


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
    (so the noise caution of :func:`~impactometer.identify.peak_to_peak.paper_caution` stays silent) while it
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
    too small, so it refuses rather than answer.
    """
    if seg.noise_correlation > COLOURED_LIMIT:
        raise IdentificationError(
            f"the channels look low-pass filtered: their pre-trigger noise has a sample-to-sample correlation of "
            f"{seg.noise_correlation:.2f} (white noise: about 0, limit {COLOURED_LIMIT}); the robust variant needs "
            "the unfiltered channels (a filter colours the noise and moves the contact onsets ahead of the "
            "contact) -- identify the record without --cfc, or use --variant paper")
