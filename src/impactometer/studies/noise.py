"""Study ``noise`` (the paper's Fig. 6): mean error vs Gaussian noise on the force, the acceleration and both.

Noise is a fraction of each channel's RMS after first contact, as in the paper (0-10 %). Each scenario is
simulated once; every (channel, level) realisation draws from its own seed, a function of the root seed, the case
and the realisation only. The paper finds force noise more harmful than acceleration noise.
"""

from __future__ import annotations

from .base import Row, Setting, Study, StudyOptions, case_seed, plotted_by, register, scenario_grid
from .identification import (
    DEFAULT_METHODS,
    MODEL_REQUIRES,
    STUDY_METHODS,
    by_method,
    clean_recordings,
    identify_rows,
    mean_abs,
    methods_of,
    pct,
    per_method,
    seeded_grid,
    with_failures,
    with_noise,
)

NAME = "noise"
#: default values per grid axis (the paper's 125 scenarios)
GRID = 5
DEFAULTS = {"levels": [0.0, 0.02, 0.05, 0.1], "methods": DEFAULT_METHODS}
SETTINGS = {"levels": Setting("numbers", 0.0, 1.0, "fraction"), "methods": STUDY_METHODS}
#: which channels get the noise
TARGETS = {"force": ("contact_force",), "acceleration": ("piston_acceleration",),
           "both": ("contact_force", "piston_acceleration")}


def _cases(options: StudyOptions) -> list[Row]:
    return seeded_grid(scenario_grid(options, GRID), options)


def _variants(options: StudyOptions) -> list[tuple[str, float]]:
    levels = sorted({float(x) for x in options.param(NAME, "levels", DEFAULTS["levels"])})
    out = [("none", 0.0)] if 0.0 in levels else []
    return out + [(target, level) for target in TARGETS for level in levels if level > 0]


def _evaluate(cases: list[Row], options: StudyOptions) -> list[Row]:
    rows = []
    variants = _variants(options)
    methods = methods_of(options, NAME)
    for case, clean in zip(cases, clean_recordings(cases, options), strict=False):
        for j, (target, level) in enumerate(variants):
            noise = {channel: (level if channel in TARGETS.get(target, ()) else 0.0)
                     for channel in ("contact_force", "piston_acceleration")}
            recording = with_noise(clean, noise, case_seed(options, NAME, case["case"], j))
            rows += identify_rows(recording, {**case, "noise_on": target, "noise": level}, methods,
                                  rig=options.rig)
    return rows


def _aggregate(rows: list[Row]) -> list[Row]:
    return by_method(rows, ("noise_on", "noise"))


def _summary(rows: list[Row]) -> list[Row]:
    top = max(r["noise"] for r in rows)
    def text(m):
        return (f"force {pct(mean_abs(rows, 'mass_error', method=m, noise_on='force', noise=top))} vs "
                f"acceleration {pct(mean_abs(rows, 'mass_error', method=m, noise_on='acceleration', noise=top))}")
    return [{"quantity": f"mean mass error at {top * 100:g} % noise on one channel (Fig. 6)",
             "ours": per_method(rows, text), "paper": "force noise matters more than acceleration noise"},
            {"quantity": f"mean mass error at {top * 100:g} % noise on both channels",
             "ours": per_method(rows, lambda m: pct(mean_abs(rows, "mass_error", method=m, noise_on="both",
                                                             noise=top))),
             "paper": "needs almost noise-free data"}]


STUDY = register(Study(name=NAME, title="Identification error vs Gaussian noise on force, acceleration, both",
                       figure="Fig. 6", cases=_cases, evaluate=_evaluate, aggregate=_aggregate,
                       summary=with_failures(_summary), drawing=plotted_by("plot_noise"), chunk_size=2,
                       requires=MODEL_REQUIRES, defaults=DEFAULTS, settings=SETTINGS))
