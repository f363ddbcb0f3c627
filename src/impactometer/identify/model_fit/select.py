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
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ...errors import IdentificationError
from ...rig import Rig
from .fit import MAX_EVALUATIONS, LawFit, Observed, _Model, fit_law, window
from .forward import free_parameters, make_layout, stand_values

#: windows after the start contact instant [s] fitted in turn, and whether the stand parameters are free in them;
#: the whole record follows
STAGES = ((0.004, "core"), (0.008, "core"), (0.015, "stand"), (0.03, "all"))
#: the stage on which the laws are screened (index into STAGES)
SCREEN_WINDOW = 2
#: a law whose BIC on the screening window exceeds the best law's by more than this is dropped [-] (a difference
#: of 10 is "very strong" evidence on Kass and Raftery's scale; the wrong laws of the pad stand lose by 10^4)
SCREEN_MARGIN = 100.0
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
class Start:
    """Where every law's fit starts: M1 [kg], V0 [m/s], the contact instant [s] and the pre-charge [Pa gauge]
    (None: fitted, starting from ``pressure_start``)."""

    mass: float
    velocity: float
    contact_time: float
    pressure: float | None
    pressure_start: float


def fit_laws(data: Observed, rig: Rig, laws: tuple[str, ...], uncertain: tuple[str, ...] | None,
             start: Start) -> tuple[dict[str, LawFit], dict[str, dict]]:
    """Fit every law of ``laws`` (screened on the window ``STAGES[SCREEN_WINDOW]``); returns the whole-record fits
    of the laws kept and, for every law, what became of it (a summary of its fit, the screening window's BIC,
    or why it failed)."""
    fits: dict[str, LawFit] = {}
    report: dict[str, dict] = {}
    screened: dict[str, tuple[LawFit, dict, tuple[_Layouts, np.ndarray]]] = {}
    for law in laws:
        free = free_parameters(law, uncertain)
        values = {"mass": start.mass, "velocity": start.velocity, "contact_time": start.contact_time,
                  **stand_values(rig, law, free)}
        if start.pressure is None:
            values["pressure_gauge"] = start.pressure_start
        layouts = _Layouts(rig, law, free, start, data.grid.sample_rate)
        try:
            fit, values, offsets = _stages(data, layouts, values, data.offsets, STAGES[:SCREEN_WINDOW + 1], start,
                                           evaluations=SCREEN_EVALUATIONS)
        except IdentificationError as exc:
            report[law] = {"error": str(exc)}
            continue
        screened[law] = (fit, values, (layouts, offsets))
    if not screened:
        return fits, report
    best = min(fit.bic for fit, _, _ in screened.values())
    window_end = STAGES[SCREEN_WINDOW][0] * 1e3
    for law, (fit, values, (layouts, offsets)) in screened.items():
        screen = {"screen_window_ms": window_end, "screen_bic": fit.bic, "screen_reduced_chi2": fit.reduced_chi2}
        if fit.bic > best + SCREEN_MARGIN:
            report[law] = {**screen, "dropped": f"BIC on the first {window_end:g} ms exceeds the best law's by "
                                                f"{fit.bic - best:.4g} > {SCREEN_MARGIN:g}"}
            continue
        try:
            fits[law], _, _ = _stages(data, layouts, values, offsets, (*STAGES[SCREEN_WINDOW + 1:], (None, "all")),
                                      start)
        except IdentificationError as exc:
            report[law] = {**screen, "error": str(exc)}
            continue
        retried = _retry(data, layouts, fits[law], start)
        if retried is not None:
            fits[law] = retried
        report[law] = {**fits[law].summary(), **screen, "retried": retried is not None}
    return fits, report


class _Layouts:
    """The layouts of one law's windows: ``core`` (M1, V0, contact instant; the stand held), ``stand`` (V0, the
    contact instant and the stand parameters; M1 held at its last value) and ``all``."""

    def __init__(self, rig: Rig, law: str, free: tuple[str, ...], start: Start, sample_rate: float):
        self.rig, self.law, self.free, self.start, self.sample_rate = rig, law, free, start, sample_rate
        self.fixed = {kind: self._make(() if kind == "core" else free) for kind in ("core", "all")}

    def _make(self, free: tuple[str, ...], mass: float | None = None):
        return make_layout(self.rig, self.law, free, pressure=self.start.pressure,
                           contact_time=self.start.contact_time, sample_rate=self.sample_rate, mass=mass)

    def __call__(self, kind: str, values: dict):
        return self._make(self.free, values["mass"]) if kind == "stand" else self.fixed[kind]


def _retry(data: Observed, layouts, fit: LawFit, start: Start) -> LawFit | None:
    """The fit of :data:`FINE_STAGES` from the start, where ``fit`` stopped before it converged or leaves
    χ²/dof above ``RETRY_REDUCED_CHI2`` and the finer continuation does better; else None."""
    if fit.converged and fit.reduced_chi2 <= RETRY_REDUCED_CHI2:
        return None
    values = {name: value for name, value in fit.values.items() if name not in ("mass", "velocity", "contact_time")}
    values.update(mass=start.mass, velocity=start.velocity, contact_time=start.contact_time)
    try:
        other, _, _ = _stages(data, layouts, values, data.offsets, (*FINE_STAGES, (None, "all")), start)
    except IdentificationError:
        return None
    return other if other.chi2 < fit.chi2 else None


def _stages(data: Observed, layouts, values: dict, offsets, stages, start: Start, *,
            evaluations: int = MAX_EVALUATIONS):
    """Fit the windows of ``stages`` in turn (None: the whole record), each from the last one's answer; returns the
    last fit (its covariance only for the whole record), its values and its offsets."""
    fit = None
    for end, kind in stages:
        part = data if end is None else window(data, start.contact_time + end)
        fit = fit_law(replace(part, offsets=offsets), layouts(kind, values), values, evaluations=evaluations,
                      information=end is None)
        values, offsets = {**values, **fit.values}, fit.offsets
    return fit, values, offsets


#: the grid of impacts a start is sought on when the robust answer fails: M1 [kg] × V0 [m/s], geometric
START_MASSES = np.geomspace(2.0, 200.0, 9)
START_VELOCITIES = np.geomspace(0.3, 8.0, 9)


def grid_start(data: Observed, rig: Rig, contact_time: float, pressure: float | None,
               pressure_start: float) -> Start:
    """A start for :func:`fit_laws` without the robust answer: the impact of :data:`START_MASSES` ×
    :data:`START_VELOCITIES` whose prediction of the first window (``STAGES[0]``) with the stand's own law and
    parameters fits best (offsets from the pre-trigger), first contact at ``contact_time`` [s]."""
    law = rig.contact.law
    layout = make_layout(rig, law, (), pressure=pressure, contact_time=contact_time,
                         sample_rate=data.grid.sample_rate)
    model = _Model(window(data, contact_time + STAGES[0][0]), layout)
    best, chi2 = (float(START_MASSES[0]), float(START_VELOCITIES[0])), np.inf
    for mass in START_MASSES:
        for velocity in START_VELOCITIES:
            values = {"mass": mass, "velocity": velocity, "contact_time": contact_time}
            if pressure is None:
                values["pressure_gauge"] = pressure_start
            x = np.r_[layout.variables(values), data.offsets / data.noise]
            r = model.residuals(x)
            if float(r @ r) < chi2:
                best, chi2 = (mass, velocity), float(r @ r)
    return Start(mass=float(best[0]), velocity=float(best[1]), contact_time=contact_time, pressure=pressure,
                 pressure_start=pressure_start)
