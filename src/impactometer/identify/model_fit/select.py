"""The fits of the contact laws and the choice among them.

Each law is fitted by continuation in the record's length (:data:`STAGES`): the likelihood of a whole record,
dozens of contact pulses long, has local minima a start a few per cent off falls into (on a 10 kg, 3 m/s pad
record started from the robust answer, 2.6 % and 2.1 % off, the whole-record fit stopped at chi2/dof = 130, or 1.006
after 40 evaluations, against 0.983 from the truth); the first pulse alone has none of them. The windows up to
8 ms fit M1, V0 and the contact instant with the stand parameters held: with the contact's parameters free, the
first pulses hardly tell M1 from the contact (a 10 kg, 3 m/s Hunt-Crossley record fitted 29 kg, 2.43 m/s on its
first 20 ms as well as the truth, and the whole record never came back: chi2/dof = 113); so the 15 ms window frees
the stand parameters with M1 held (a stand whose pad differs from the one assumed gets its pad before M1 is
freed), and from 30 ms on every unknown is free. On the 15 ms window the laws are compared by BIC, and a law
whose BIC exceeds the best by more than ``SCREEN_MARGIN`` is not carried to the whole record (its full fit would
cost the most and lose anyway); the whole-record BIC chooses among the others.

The screens are a saving, not evidence: they drop a law on the promise that its whole-record fit would lose anyway.
Where the laws kept leave the whole record undescribed (χ²/dof above the identification's limit of a model answer),
that promise is void: a law held to its screening windows' fit can stop far from the record (as the retry of a
whole-record fit shows), while the law it lost to does not carry to the whole record, and the answer would fall back
to the robust one for want of a law. The dropped laws are then fitted to the whole record too (``rescue`` of
:func:`_fit_laws`), each from where its screening stopped, and every law competes by its whole-record BIC as the
criterion states; the extra fits cost only records that would otherwise fall back. On a peak-oriented pad record
(``tests/foreign_stand.py``, seed 8: M1 56.8 kg, V0 1.20 m/s) the power law, dropped on the first 15 ms by a BIC
1.8e5 above the hysteretic law's (its 15 ms fit, M1 held, at χ²/dof 75), fits the whole record to χ²/dof 0.99 (M1
57.2 ± 0.6 kg), where the hysteretic law's whole-record fit leaves 118 and the robust answer was 51.3 ± 2.3 kg.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ...errors import IdentificationError
from ...rig import Rig
from .engine import MAX_EVALUATIONS, LawFit, Observed, _least_bic, fit_law, staged, window
from .forward import Grid, Layout, _horizon, _predict, free_parameters, make_layout, stand_values

#: windows after the start contact instant [s] fitted in turn, and whether the stand parameters are free in them;
#: the whole record follows
STAGES = ((0.004, "core"), (0.008, "core"), (0.015, "stand"), (0.03, "all"))
#: the stage on which the laws are screened (index into STAGES)
SCREEN_WINDOW = 2
#: a law whose BIC on the screening window exceeds the best law's by more than this is dropped [-] (a difference
#: of 10 is "very strong" evidence on Kass and Raftery's scale; the wrong laws of the pad stand lose by 10^4)
SCREEN_MARGIN = 100.0
#: the first screens, on each window with the stand parameters held (indices into STAGES): a law whose BIC there
#: exceeds the best law's by more than EARLY_MARGIN is dropped, where the best law explains the window down to the
#: noise (χ²/dof <= EARLY_REDUCED_CHI2). On the pad stand the wrong laws lose by 7e3-9e5 on the first 4 ms and
#: would cost two more windows each (a third of the time of a record); the power law, within the margin on the
#: first 4 ms of half the pad records, loses by 1e5 on the first 15 ms, where its window with the stand free cost
#: an eighth of the time of a record
EARLY_WINDOWS = (0, 1)
EARLY_MARGIN = 1000.0
EARLY_REDUCED_CHI2 = 1.1
#: the rule, as the details of an answer state it
CRITERION = (f"BIC = chi2 + k ln N, whole record; laws more than {EARLY_MARGIN:g} above a best law that explains "
             f"the first {' or '.join(f'{STAGES[k][0] * 1e3:g}' for k in EARLY_WINDOWS)} ms (chi2/dof <= "
             f"{EARLY_REDUCED_CHI2:g}) or {SCREEN_MARGIN:g} above the best on the first "
             f"{STAGES[SCREEN_WINDOW][0] * 1e3:g} ms dropped, and fitted to the whole record too where no law kept "
             "describes it")
#: a whole-record fit that leaves χ²/dof above this, or stops before it converges, is tried again from the start
#: with the finer windows of FINE_STAGES, the stand parameters free from the first (M1 held up to 20 ms): light,
#: fast impacts bounce dozens of times (2 ms steps of the window keep each new pulse within reach), and a pad far
#: from the one assumed (3.6 times stiffer, e = 0.25) leads the first windows astray when it is held
RETRY_REDUCED_CHI2 = 1.1
FINE_STAGES = (*((end, "stand") for end in (0.002, 0.004, 0.006, 0.008, 0.011, 0.015, 0.02)),
               *((end, "all") for end in (0.025, 0.03, 0.035, 0.04, 0.045)))
#: most residual evaluations of each window up to the screening one (the law of a pad record converges in 3-12;
#: the wrong laws stop at the cap, far above the best)
SCREEN_EVALUATIONS = 8


@dataclass(frozen=True)
class _Start:
    """Where every law's fit starts: M1 [kg], V0 [m/s], the contact instant [s] and the pre-charge [Pa gauge]
    (None: fitted, starting from ``pressure_gauge_start``; else held where ``pressure_gauge_std`` [Pa] is 0, or fitted
    with the prior ``pressure_gauge`` ± ``pressure_gauge_std``)."""

    mass: float
    velocity: float
    contact_time: float
    pressure_gauge: float | None
    pressure_gauge_start: float
    pressure_gauge_std: float = 0.0


def _screen(fits: dict[str, LawFit], span: float, margin: float, *, within: float | None = None) -> dict[str, str]:
    """The laws of ``fits`` (law -> its fit on the window of ``span`` [s] after contact) to drop, each with why:
    those whose BIC exceeds the best law's by more than ``margin``; with ``within``, only where the best law
    leaves χ²/dof <= ``within`` (it explains the window down to the noise, so a law far above it cannot catch up
    once its parameters are freed)."""
    best = _least_bic(fits.values())
    if best is None or within is not None and best.reduced_chi2 > within:
        return {}
    return {law: f"BIC on the first {span * 1e3:g} ms exceeds the best law's ({best.law}) by "
                 f"{fit.bic - best.bic:.4g} > {margin:g}"
            for law, fit in fits.items() if fit.bic > best.bic + margin}


def _start_law(rig: Rig, law: str, uncertain: tuple[str, ...] | None, start: _Start,
               sample_rate: float) -> tuple[_Layouts, dict]:
    """The layouts of ``law``'s windows and the physical values its fit starts from."""
    free = free_parameters(law, uncertain)
    values = {"mass": start.mass, "velocity": start.velocity, "contact_time": start.contact_time,
               **stand_values(rig, law, free)}
    if start.pressure_gauge is None:
        values["pressure_gauge"] = start.pressure_gauge_start
    elif start.pressure_gauge_std > 0.0:
        values["pressure_gauge"] = start.pressure_gauge
    return _Layouts(rig, law, free, start, sample_rate), values


def _fit_laws(data: Observed, rig: Rig, laws: tuple[str, ...], uncertain: tuple[str, ...] | None,
              start: _Start, *, rescue: float | None = None) -> tuple[dict[str, LawFit], dict[str, dict]]:
    """Fit every law of ``laws`` (screened on the windows ``STAGES[k]`` of ``EARLY_WINDOWS`` and
    ``STAGES[SCREEN_WINDOW]``); returns the whole-record fits of the laws kept and, for every law, what became of
    it (a summary of its fit, the screening window's BIC, or why it failed or was dropped).

    With ``rescue`` (a χ²/dof [-]): where no whole-record fit of the laws kept leaves χ²/dof at or below it, the
    laws the screens dropped are fitted to the whole record too, each from where its screening stopped, and every
    law's whole-record fit competes by BIC (the module's note)."""
    fits: dict[str, LawFit] = {}
    report: dict[str, dict] = {}
    running: dict[str, tuple[LawFit, dict, _Layouts, np.ndarray]] = {}
    dropped: dict[str, tuple[tuple[LawFit, dict, _Layouts, np.ndarray], int]] = {}
    done = 0
    for stop, margin, within in (*((k + 1, EARLY_MARGIN, EARLY_REDUCED_CHI2) for k in EARLY_WINDOWS),
                                 (SCREEN_WINDOW + 1, SCREEN_MARGIN, None)):
        for law in laws if not done else tuple(running):
            if done:
                _, values, layouts, offsets = running[law]
            else:
                layouts, values = _start_law(rig, law, uncertain, start, data.grid.sample_rate)
                offsets = data.offsets
            try:
                fit, values, offsets = _fit_stages(data, layouts, values, offsets, STAGES[done:stop], start,
                                                   evaluations=SCREEN_EVALUATIONS)
            except IdentificationError as exc:
                report[law] = {"error": str(exc)}
                running.pop(law, None)
                continue
            running[law] = (fit, values, layouts, offsets)
        span = STAGES[stop - 1][0]
        for law, why in _screen({law: item[0] for law, item in running.items()}, span, margin,
                                within=within).items():
            dropped[law] = (running.pop(law), stop)
            report[law] = {**_screened(dropped[law][0][0], span), "dropped": why}
        done = stop
    for law, item in running.items():
        _fit_whole(data, law, item, SCREEN_WINDOW + 1, start, fits, report)
    if rescue is not None and dropped and all(fit.reduced_chi2 > rescue for fit in fits.values()):
        for law, (item, stop) in dropped.items():
            why = report[law]["dropped"]
            _fit_whole(data, law, item, stop, start, fits, report)
            report[law]["rescued"] = (f"dropped by a screen ({why}), fitted to the whole record because no law kept "
                                      f"leaves chi2/dof <= {rescue:g} there")
    return fits, report


def _fit_whole(data: Observed, law: str, item: tuple[LawFit, dict, _Layouts, np.ndarray], stop: int, start: _Start,
               fits: dict[str, LawFit], report: dict[str, dict]) -> None:
    """Fit ``law`` from its state ``item`` after the windows ``STAGES[:stop]`` on to the whole record (and again
    by :func:`_retry` where it stays far from the record); its fit into ``fits``, what became of it into
    ``report``."""
    fit, values, layouts, offsets = item
    screened = _screened(fit, STAGES[stop - 1][0])
    try:
        fits[law], _, _ = _fit_stages(data, layouts, values, offsets, (*STAGES[stop:], (None, "all")), start)
    except IdentificationError as exc:
        report[law] = {**screened, "error": str(exc)}
        return
    retried = _retry(data, layouts, fits[law], start)
    if retried is not None:
        fits[law] = retried
    report[law] = {**fits[law].summary(), **screened, "retried": retried is not None}


def _screened(fit: LawFit, span: float) -> dict:
    return {"screen_window_ms": span * 1e3, "screen_bic": fit.bic, "screen_reduced_chi2": fit.reduced_chi2}


class _Layouts:
    """The layouts of one law's windows: ``core`` (M1, V0, contact instant; the stand held), ``stand`` (V0, the
    contact instant and the stand parameters; M1 held at its last value) and ``all``."""

    def __init__(self, rig: Rig, law: str, free: tuple[str, ...], start: _Start, sample_rate: float):
        self.rig, self.law, self.free, self.start, self.sample_rate = rig, law, free, start, sample_rate
        self._fixed: dict[str, Layout] = {}

    def fixed(self, kind: str) -> Layout:
        """The layout ``core`` or ``all``, made once when first asked for (a stream's screening fits of the other
        laws on the first window never free the stand)."""
        if kind not in self._fixed:
            self._fixed[kind] = self._make(() if kind == "core" else self.free)
        return self._fixed[kind]

    def _make(self, free: tuple[str, ...], mass: float | None = None):
        return make_layout(self.rig, self.law, free, pressure_gauge=self.start.pressure_gauge,
                           contact_time=self.start.contact_time, sample_rate=self.sample_rate, mass=mass,
                           pressure_gauge_std=self.start.pressure_gauge_std)

    def __call__(self, kind: str, values: dict):
        return self._make(self.free, values["mass"]) if kind == "stand" else self.fixed(kind)


def _retry(data: Observed, layouts, fit: LawFit, start: _Start) -> LawFit | None:
    """The fit of :data:`FINE_STAGES` from the start, where ``fit`` stopped before it converged or leaves
    χ²/dof above ``RETRY_REDUCED_CHI2`` and the finer continuation does better; else None."""
    if fit.converged and fit.reduced_chi2 <= RETRY_REDUCED_CHI2:
        return None
    values = {name: value for name, value in fit.values.items() if name not in ("mass", "velocity", "contact_time")}
    values.update(mass=start.mass, velocity=start.velocity, contact_time=start.contact_time)
    try:
        other, _, _ = _fit_stages(data, layouts, values, data.offsets, (*FINE_STAGES, (None, "all")), start)
    except IdentificationError:
        return None
    return other if other.reduced_chi2 < fit.reduced_chi2 else None


def _fit_stages(data: Observed, layouts: _Layouts, values: dict, offsets, stages, start: _Start, *,
                evaluations: int = MAX_EVALUATIONS):
    """Fit the windows of ``stages`` in turn (:func:`.engine.staged`; None: the record up to its
    :func:`~.forward.horizon` at the last window's answer), each from the last one's answer; returns the last fit
    (its covariance only for the last window), its values and its offsets."""

    def fit_one(stage, state):
        end, kind = stage
        _, values, offsets = state
        layout = layouts(kind, values)
        if end is None:
            span = data.grid.start_time + (data.grid.size - 1) / data.grid.sample_rate - values["contact_time"]
            reach, why = _horizon(layout, layout.variables(values), span, data.grid)
            part = window(data, values["contact_time"] + reach) if reach < span else data
        else:
            part = window(data, start.contact_time + end)
        fit = fit_law(part, layout, values, offsets=offsets, evaluations=evaluations, information=end is None)
        if end is None:
            fit = replace(fit, span=(reach, why))
        return fit, {**values, **fit.values}, fit.offsets

    return staged(stages, fit_one, (None, values, offsets))


#: the grid of impacts a start is sought on when the robust answer fails: M1 [kg] × V0 [m/s], geometric
START_MASSES = np.geomspace(2.0, 200.0, 9)
START_VELOCITIES = np.geomspace(0.3, 8.0, 9)


def _grid_starts(data: Observed, rig: Rig, contact_time: float, pressure_gauge: float | None,
                 pressure_gauge_start: float,
                count: int = 1, predicted: np.ndarray | None = None) -> list[_Start]:
    """Starts for :func:`_fit_laws` without the robust answer: the ``count`` impacts of :data:`START_MASSES` ×
    :data:`START_VELOCITIES` whose predictions of the first window with the stand's own law and parameters fit
    best (offsets from the pre-trigger), first contact at ``contact_time`` [s]; best first, none next to (one grid
    step from) a better one: the first window of a light, fast impact can hold more than one minimum.
    ``predicted`` (from :func:`_grid_predictions` on the same window) spares the integrations. The window is
    ``data`` up to ``STAGES[0]`` after ``contact_time``, or all of it where it is shorter."""
    part = window(data, contact_time + STAGES[0][0])
    if predicted is None or predicted.shape[-1] != part.grid.size:
        predicted = _grid_predictions(part.grid, rig, contact_time, pressure_gauge, pressure_gauge_start)
    chi2 = np.sum(np.square((part.channels - part.offsets[:, None]) / part.noise[:, None]
                            - predicted / part.noise[None, :, None]), axis=(1, 2))
    chi2 = np.where(np.isfinite(chi2), chi2, np.inf).reshape(START_MASSES.size, START_VELOCITIES.size)
    starts: list[_Start] = []
    taken: list[tuple[int, int]] = []
    for flat in np.argsort(chi2, axis=None, kind="stable"):
        i, j = (int(k) for k in np.unravel_index(flat, chi2.shape))
        if len(starts) == count or not np.isfinite(chi2[i, j]):
            break
        if any(abs(i - a) <= 1 and abs(j - b) <= 1 for a, b in taken):
            continue
        taken.append((i, j))
        starts.append(_Start(mass=float(START_MASSES[i]), velocity=float(START_VELOCITIES[j]),
                            contact_time=contact_time, pressure_gauge=pressure_gauge,
                            pressure_gauge_start=pressure_gauge_start))
    if not starts:
        raise IdentificationError("no impact of the start grid can be integrated on this stand")
    return starts


def _grid_predictions(grid: Grid, rig: Rig, contact_time: float, pressure_gauge: float | None,
                     pressure_gauge_start: float) -> np.ndarray:
    """The recorded channels (offsets zero) of every impact of :data:`START_MASSES` × :data:`START_VELOCITIES`,
    shape (masses × velocities, 2, samples), on ``grid`` with the stand's own law and parameters, first contact at
    ``contact_time`` [s]; NaN for an impact the model cannot carry. They depend on the stand and the samples'
    place after first contact only: a stream computes them before the impact."""
    layout = make_layout(rig, rig.contact.law, (), pressure_gauge=pressure_gauge, contact_time=contact_time,
                         sample_rate=grid.sample_rate)
    masses, velocities = np.meshgrid(START_MASSES, START_VELOCITIES, indexing="ij")
    rows = np.zeros((masses.size, len(layout.names)))
    rows[:, 0], rows[:, 1] = np.log(masses.ravel()), np.log(velocities.ravel())  # ln M1, ln V0; contact at 0
    if pressure_gauge is None:
        rows[:, -1] = np.log(pressure_gauge_start + rig.gas.atmospheric_pressure)
    params, times = layout.packed(rows)
    try:
        return _predict(grid, params, times)
    except IdentificationError:  # a grid point the model cannot carry: one by one, that point left out
        return np.stack([_one(grid, params[k:k + 1], times[k:k + 1]) for k in range(rows.shape[0])])


def _one(grid: Grid, params: np.ndarray, times: np.ndarray) -> np.ndarray:
    try:
        return _predict(grid, params, times)[0]
    except IdentificationError:
        return np.full((2, grid.size), np.nan)
