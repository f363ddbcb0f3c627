"""The model fit of a record that grows, as :class:`~.streaming.ModelStream` runs it: the first answer on the first
window, the screen of the contact laws, and one update per cadence warm-started from the last.

The state of one impact is a :class:`_Growing`; the functions here advance it. Every window of the record reaches
them as an :class:`~.engine.Observed` whose last sample is the last one the answer may read.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ...errors import IdentificationError
from ...rig import Rig
from .engine import MAX_EVALUATIONS, LawFit, Observed, _least_bic
from .first_window import _fit_window
from .forward import Layout
from .select import (
    EARLY_MARGIN,
    EARLY_REDUCED_CHI2,
    RETRY_REDUCED_CHI2,
    SCREEN_MARGIN,
    SCREEN_WINDOW,
    STAGES,
    _Layouts,
    _screen,
    _Start,
    _start_law,
)

#: Levenberg-Marquardt steps of one update, and the residual evaluations each may take (the dampings it tries
#: until χ² falls)
UPDATE_STEPS = 1
STEP_EVALUATIONS = 3
#: residual evaluations of each other law's fit on the first window for the screen (the batch fit takes
#: SCREEN_EVALUATIONS = 8): fewer only leave a law's χ² higher, and a law is dropped only where the stand's law
#: explains the window down to the noise; on the pad stand the wrong laws lose by 7e3-9e5 against a margin of 1e3
STREAM_SCREEN_EVALUATIONS = 3
#: steps added where the update leaves χ²/dof above ``RETRY_REDUCED_CHI2`` (a law far from its optimum: a stand
#: other than the one assumed, or the stand freed at the screening window); such an update outlasts its cadence
CATCH_UP_STEPS = 4
#: a fit explains the samples after first contact where their χ²/dof stays within this many standard deviations
#: of its distribution (sqrt(2/dof)) above 1: the χ²/dof of a whole window, pre-trigger included, hides a misfit
#: of the few hundred samples after contact in the thousand before it
EXPLAINED_SPREAD = 3.0


@dataclass
class _LawState:
    """One contact law followed by the updates: its layouts, last values [SI], offsets [N], [m/s²] and fit."""

    layouts: _Layouts
    values: dict
    offsets: np.ndarray
    fit: LawFit


@dataclass
class _Pending:
    """The first window's screen still to do: the window, its length [s] after contact, the laws still to fit on
    it and the fits made of the others."""

    data: Observed | None = None
    span: float = 0.0
    laws: tuple[str, ...] = ()
    fitted: dict[str, _LawState] = field(default_factory=dict)


@dataclass
class _Growing:
    """The fit of one impact's growing record: the stand, the laws to consider, the unknowns marked uncertain, the
    laws followed (``states``), where their fits started, the laws still to screen on the first window
    (``pending``: its data, its length [s], the laws and the fits made of them), the chosen law and why, and notes
    on what failed."""

    rig: Rig
    laws: tuple[str, ...]
    uncertain: tuple[str, ...] | None
    states: dict[str, _LawState] = field(default_factory=dict)
    start: _Start | None = None
    pending: _Pending = field(default_factory=_Pending)
    chosen: str | None = None
    choice: str = ""
    notes: list[str] = field(default_factory=list)
    #: the last fit judged by :func:`_explained` and the verdict
    judged: tuple[LawFit, bool] | None = None

    def best(self) -> LawFit | None:
        """The fit of smallest BIC among the laws followed (None before the first answer)."""
        return _least_bic(state.fit for state in self.states.values())


def _explained(growing: _Growing, fit: LawFit, data: Observed) -> bool:
    """Whether ``fit`` explains the samples of ``data`` (the window it was fitted on) after its first contact down
    to their noise (see :data:`EXPLAINED_SPREAD`), judged once per fit; the model is zero before contact, so those
    samples' share of χ² is the offsets'."""
    if growing.judged is None or growing.judged[0] is not fit:
        size, start, rate = data.channels.shape[1], data.grid.start_time, data.grid.sample_rate
        contact = fit.values["contact_time"]
        # the samples before contact (the first ones): the instants start + k/rate below it, counted as the
        # search of those instants counts them, without making them
        before = min(max(math.ceil((contact - start) * rate), 0), size)
        while before > 0 and start + (before - 1) / rate >= contact:
            before -= 1
        while before < size and start + before / rate < contact:
            before += 1
        pre = float(np.sum(np.square((data.channels[:, :before] - fit.offsets[:, None]) / data.noise[:, None])))
        dof = 2 * (size - before) - fit.unknowns
        growing.judged = (fit, dof > 0 and (fit.chi2 - pre) / dof <= 1.0 + EXPLAINED_SPREAD * math.sqrt(2.0 / dof))
    return growing.judged[1]


def _fit_core(growing: _Growing, law: str, data: Observed, core: dict | None, evaluations: int,
              information: bool) -> _LawState:
    """``law`` fitted on ``data`` with the stand held, from the growing fit's start or the ``core`` values (M1,
    V0, the contact instant) of another law's fit."""
    assert growing.start is not None  # set before any fit
    layouts, values = _start_law(growing.rig, law, growing.uncertain, growing.start, data.grid.sample_rate)
    if core is not None:
        values.update({name: core[name] for name in ("mass", "velocity", "contact_time")})
    fit = _fit_window(data, layouts("core", values), values, evaluations=evaluations, information=information)
    return _LawState(layouts, {**values, **fit.values}, fit.offsets, fit)


def _first_fit(growing: _Growing, data: Observed, span: float, starts: list[_Start]) -> LawFit | None:
    """The first answer on the first window (``span`` [s] after contact): the stand's own law (the first of
    ``laws`` otherwise) fitted to convergence with the stand held, from each start in turn until a fit explains the
    window (:func:`_explained`); the fit of smallest χ². The other laws wait for :func:`_screen_pending` (one at each
    update) unless no fit explains the window; then they are screened at once."""
    own = growing.rig.contact.law if growing.rig.contact.law in growing.laws else growing.laws[0]
    found: tuple[_LawState, _Start] | None = None
    for start in starts:
        growing.start = start
        try:
            state = _fit_core(growing, own, data, None, MAX_EVALUATIONS, True)
        except IdentificationError as exc:
            growing.notes.append(f"{own} on the first {span * 1e3:.3g} ms: {exc}")
            continue
        if found is None or state.fit.chi2 < found[0].fit.chi2:
            found = (state, start)
        if _explained(growing, found[0].fit, data):
            break
    if found is None:
        return None
    growing.states, growing.start = {own: found[0]}, found[1]
    growing.pending = _Pending(data, span, tuple(law for law in growing.laws if law != own))
    if growing.pending.laws:
        growing.choice = (f"{own} (the stand's law) for the first answer; the other laws are screened on the first "
                          f"{span * 1e3:.3g} ms at the next update")
        if not _explained(growing, found[0].fit, data):
            _screen_pending(growing, every=True)
    return growing.best()


def _screen_pending(growing: _Growing, *, every: bool = False) -> None:
    """One law still to screen (``every``: all of them) fitted on the first window from the first law's answer, in
    ``STREAM_SCREEN_EVALUATIONS``; once none is left, the laws screened as the batch fit screens them on that
    window, and the law chosen where one is left."""
    pending = growing.pending
    data, span, others, fitted = pending.data, pending.span, pending.laws, pending.fitted
    assert data is not None  # a window is pending while laws are
    first = next(iter(growing.states.values()))
    for law in others if every else others[:1]:
        try:
            fitted[law] = _fit_core(growing, law, data, first.values, STREAM_SCREEN_EVALUATIONS, False)
        except IdentificationError as exc:
            growing.notes.append(f"{law} on the first {span * 1e3:.3g} ms: {exc}")
    rest = () if every else others[1:]
    growing.pending = _Pending(data if rest else None, span, rest, fitted)
    if rest:
        return
    better = min(fitted.values(), key=lambda state: state.fit.chi2, default=None)
    if better is not None and better.fit.chi2 < first.fit.chi2:  # it may answer: fitted to convergence
        try:
            fitted[better.fit.law] = _fit_core(growing, better.fit.law, data, better.values, MAX_EVALUATIONS, True)
        except IdentificationError as exc:
            growing.notes.append(f"{better.fit.law} on the first {span * 1e3:.3g} ms: {exc}")
            del fitted[better.fit.law]
    growing.states.update(fitted)
    dropped = _screen({law: state.fit for law, state in growing.states.items()}, span, EARLY_MARGIN,
                      within=EARLY_REDUCED_CHI2)
    _keep(growing, dropped, "the only law left", span, only=len(growing.states) - len(dropped) == 1)


def _keep(growing: _Growing, dropped: dict[str, str], why: str, span: float, *, only: bool) -> None:
    for law in dropped:
        del growing.states[law]
    growing.choice = ""
    if only:
        best = growing.best()
        assert best is not None  # a law is left
        growing.chosen = best.law
        growing.states = {best.law: growing.states[best.law]}
        growing.choice = (f"{best.law}: {why} on the first {span * 1e3:.3g} ms"
                          + (f" ({'; '.join(f'{k}: {v}' for k, v in dropped.items())})" if dropped else ""))


def _refine(data: Observed, layout: Layout, values: dict, offsets: np.ndarray, steps: int) -> LawFit:
    """``steps`` Levenberg-Marquardt steps from ``values`` and ``offsets`` (:func:`.first_window._fit_window`)."""
    return _fit_window(data, layout, values, offsets, evaluations=1 + STEP_EVALUATIONS * steps, jacobians=steps)


def _update(growing: _Growing, data: Observed, span: float) -> LawFit | None:
    """One update on the record so far (``span`` [s] after contact): the pending screen first; each law followed
    refined from its last values (:func:`_refine`), the stand held before ``STAGES[SCREEN_WINDOW]`` and every
    unknown free from it on, where the smallest BIC chooses among the laws left (and the choice is kept)."""
    if growing.pending.laws:
        _screen_pending(growing)
    kind = "core" if span < STAGES[SCREEN_WINDOW][0] else "all"
    for law, state in list(growing.states.items()):
        try:
            layout = state.layouts(kind, state.values)
            fit = _refine(data, layout, state.values, state.offsets, UPDATE_STEPS)
            if fit.reduced_chi2 > RETRY_REDUCED_CHI2:  # far from the optimum: a few steps more, this time
                fit = _refine(data, layout, fit.values, fit.offsets, CATCH_UP_STEPS)
        except IdentificationError as exc:
            growing.notes.append(f"{law} at {span * 1e3:.3g} ms: {exc}")
            if len(growing.states) > 1:
                del growing.states[law]
            continue
        growing.states[law] = _LawState(state.layouts, {**state.values, **fit.values}, fit.offsets, fit)
    if growing.chosen is None and kind == "all" and growing.states:
        fits = {law: state.fit for law, state in growing.states.items()}
        _keep(growing, _screen(fits, span, SCREEN_MARGIN), "the smallest BIC", span, only=True)
    return growing.best()
