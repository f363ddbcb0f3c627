"""Study ``cases`` (the paper's Figs. 3-4): per-case mass and velocity error at chosen pressures, as bars.

The paper shows experimental cases at 100 kPa (mass, Fig. 3) and 20 / 100 kPa (velocity, Fig. 4) and states a
velocity error consistently below 2 %. Here: simulated recordings with the base sensor noise, the masses of the
grid at the chosen velocities and pressures, every method side by side.
"""

from __future__ import annotations

from functools import partial

import numpy as np

from ..rig import VELOCITY_RANGE
from .base import PAPER_RANGES, Row, Setting, Study, StudyOptions, grid_size, plotted_by, register
from .identification import REQUIRES, by_method, evaluate_noisy, max_abs, pct, per_method, seeded_grid, with_failures

NAME = "cases"
DEFAULTS = {"pressures": [20e3, 100e3], "velocities": [1.0, 2.0, 3.0]}
SETTINGS = {"pressures": Setting("numbers", 0.0, 1e8, "pressure"),
            "velocities": Setting("numbers", 0.0, VELOCITY_RANGE[1], "velocity", low_open=True)}


def _cases(options: StudyOptions) -> list[Row]:
    pressures = [float(p) for p in options.param(NAME, "pressures", DEFAULTS["pressures"])]
    velocities = [float(v) for v in options.param(NAME, "velocities", DEFAULTS["velocities"])]
    masses = np.linspace(*PAPER_RANGES["mass"], grid_size(options, 5))
    scenarios = [{"mass": float(m), "velocity": v, "pressure_gauge": p}
                 for p in pressures for v in velocities for m in masses]
    return seeded_grid(scenarios, options)


def _aggregate(rows: list[Row]) -> list[Row]:
    return by_method(rows, ("pressure_gauge",))


def _summary(rows: list[Row]) -> list[Row]:
    return [{"quantity": "velocity error, max over the cases (Fig. 4)",
             "ours": per_method(rows, lambda m: pct(max_abs(rows, "velocity_error", method=m))),
             "paper": "consistently better than 2 %"},
            {"quantity": "mass error, max over the cases (Fig. 3)",
             "ours": per_method(rows, lambda m: pct(max_abs(rows, "mass_error", method=m))),
             "paper": "large diversity; worst at low pressure and large mass"}]


STUDY = register(Study(name=NAME, title="Per-case mass and velocity error at chosen pressures",
                       figure="Figs. 3-4", cases=_cases, evaluate=partial(evaluate_noisy, NAME),
                       aggregate=_aggregate, summary=with_failures(_summary), drawing=plotted_by("plot_case_bars"),
                       chunk_size=5, requires=REQUIRES, defaults=DEFAULTS, settings=SETTINGS))
