"""Stage B, sustained contact: where it is decided, for every caller.

The one rule (:func:`is_sustained`): a contact pulse after the first that lasts longer than a factor times a pulse
before it. A bounce lasts as long as the contact's stiffness makes it, whatever the law; sustained contact lasts
as long as the gas spring holds the bodies together, many bounces long. Each caller has its named preset here:

======================================  =================================================================
:data:`SUSTAINED_FACTOR`                the identification and ``inspect``: against the LONGEST pulse before
                                        (:func:`sustained_index`, :func:`~.pulses.contact_pulses`)
:data:`SUSTAINED_WINDOW_FACTOR`         the absorber's common window and metrics (``control.event``,
                                        ``control.metrics``): against the FIRST pulse, to the deepest point
:data:`SUSTAINED_CONTROL_FACTOR`        the controller's compiled estimator (:func:`controller_sustained`):
                                        a running contact against the FIRST pulse, sample by sample
======================================  =================================================================
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Protocol

from numba import njit

#: the identification's preset: the first pulse longer than 2 × the LONGEST pulse before it (a bounce of a noisy
#: record is never taken for sustained contact)
SUSTAINED_FACTOR = 2.0
#: the absorber's common window (``control.event``) and metrics: a pulse that lasts, to the deepest point, 4 × the
#: FIRST pulse; it judges a finished, noise-free run, so it asks for the contact that holds the bodies together for
#: good
SUSTAINED_WINDOW_FACTOR = 4.0
#: the controller's estimator (``control.estimator``, compiled: a running contact that has lasted 1.5 × the FIRST
#: pulse, judged sample by sample); the loop needs the instant the collision that starts the contact is over and
#: the bodies move together, not the identification's stricter test of a bounce
SUSTAINED_CONTROL_FACTOR = 1.5


class Span(Protocol):
    """A detected pulse as stage B reads it (:class:`~.pulses.PulseSpan`): sample indices."""

    @property
    def zero(self) -> int: ...

    @property
    def end(self) -> int: ...

    @property
    def complete(self) -> bool: ...


class Timed(Protocol):
    """A pulse with times as stage B reads it (:class:`~.pulses.Pulse`)."""

    @property
    def start(self) -> float: ...

    @property
    def sustained(self) -> bool: ...


def is_sustained(k: int, length: float, longest: float, factor: float = SUSTAINED_FACTOR) -> bool:
    """True when pulse ``k`` (0 = the first) of ``length`` is sustained contact (stage B): never the first pulse,
    and a later one that lasts longer than ``factor`` times the ``longest`` pulse before it (any unit of time).

    The one rule of stage B for the simulation's pulses (:func:`~.pulses.contact_pulses`), the detected ones
    (:func:`sustained_index`), ``inspect``, the absorber's common window and metrics
    (:data:`SUSTAINED_WINDOW_FACTOR`, the first pulse as ``longest``) and the streaming identification's running
    pulse; the controller's compiled estimator judges it with :func:`controller_sustained`.
    """
    return k > 0 and length > factor * longest


@njit(cache=True)
def controller_sustained(held, first_pulse):
    """Whether a running contact that has ``held`` [s] is sustained for the controller's estimator (compiled):
    it has lasted :data:`SUSTAINED_CONTROL_FACTOR` times the ``first_pulse`` [s].

    :func:`is_sustained` judged at every sample of the running contact, the first pulse as the one before it: a
    NaN ``first_pulse`` (the first pulse still running) is never sustained, and the running contact becomes
    sustained at the sample it reaches the factor (``>=``: the instant, not the strict test of a finished pulse).
    """
    return held >= SUSTAINED_CONTROL_FACTOR * first_pulse


def sustained_index(spans: Sequence[Span], *, size: int, factor: float = SUSTAINED_FACTOR) -> int | None:
    """Index in ``spans`` of the pulse where sustained contact (stage B, :func:`is_sustained`) starts, or None,
    counting a pulse still running at the end of the data (``size`` samples) by how long it has run so far."""
    if len(spans) < 2 or not spans[0].complete:
        return None
    longest = 0
    for k, span in enumerate(spans):
        length = (span.end if span.complete else size) - span.zero
        if is_sustained(k, length, longest, factor):
            return k
        if not span.complete:
            return None
        longest = max(longest, length)
    return None


def sustained_start(spans: Sequence[Span], *, size: int, factor: float = SUSTAINED_FACTOR) -> int | None:
    """Sample index where sustained contact (stage B) starts (see :func:`sustained_index`), or None."""
    k = sustained_index(spans, size=size, factor=factor)
    return None if k is None else spans[k].zero


def stage_b_start(pulses: Sequence[Timed]) -> float | None:
    """Start of sustained contact (stage B) [s] of pulses marked by :func:`~.pulses.contact_pulses` or
    ``inspect``, or None when the record has none."""
    return next((p.start for p in pulses if p.sustained), None)
