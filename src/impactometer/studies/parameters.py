"""Study ``parameters`` (the paper's Fig. 5): mean mass error vs impacting mass, initial pressure and velocity.

Over the M1 × V0 × p0 grid (125 cases by default) with the base sensor noise. The paper finds smaller masses and
higher pressures more accurate and the velocity effect not significant.
"""

from __future__ import annotations

from functools import partial

from .base import Row, Study, StudyFigure, StudyOptions, register, scenario_grid
from .identification import REQUIRES, by_method, evaluate_noisy, mean_abs, pct, per_method, seeded_grid, with_failures

NAME = "parameters"
AXES = (("mass", "M1 [kg]", 1.0), ("pressure_gauge", "p0 [kPa]", 1e-3), ("velocity", "V0 [m/s]", 1.0))


def _cases(options: StudyOptions) -> list[Row]:
    return seeded_grid(scenario_grid(options), options)


def _aggregate(rows: list[Row]) -> list[Row]:
    return by_method(rows)


def _trend(rows: list[Row], column: str, method: str) -> str:
    values = sorted({r[column] for r in rows})
    low, high = values[0], values[-1]
    return (f"{pct(mean_abs(rows, 'mass_error', method=method, **{column: low}))} → "
            f"{pct(mean_abs(rows, 'mass_error', method=method, **{column: high}))}")


def _summary(rows: list[Row]) -> list[Row]:
    out = [{"quantity": "mean mass error over the grid (Fig. 5)",
            "ours": per_method(rows, lambda m: pct(mean_abs(rows, "mass_error", method=m))),
            "paper": "qualitative (depends on M1 and p0)"}]
    statements = {"mass": "smaller masses more accurate", "pressure_gauge": "higher pressure more accurate",
                  "velocity": "not significant (slightly better at higher V0)"}
    for column, label, _ in AXES:
        out.append({"quantity": f"mean mass error, lowest → highest {label}",
                    "ours": per_method(rows, lambda m, c=column: _trend(rows, c, m)),
                    "paper": statements[column]})
    return out


def _figure(rows: list[Row], options: StudyOptions) -> StudyFigure:
    title = f"Mean identification error vs scenario parameters (noise {options.noise * 100:g} % of RMS)"
    return StudyFigure("plot_mean_error_vs", rows, {"parameters": AXES, "errors": ("mass_error", "velocity_error"),
                                                    "title": title})


STUDY = register(Study(name=NAME, title="Mean mass error vs impacting mass, pressure and velocity",
                       figure="Fig. 5", cases=_cases, evaluate=partial(evaluate_noisy, NAME),
                       aggregate=_aggregate, summary=with_failures(_summary), drawing=_figure, chunk_size=10,
                       requires=REQUIRES))
