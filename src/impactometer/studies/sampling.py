"""Study ``sampling`` (the paper's Fig. 7): mean and maximum error vs sampling frequency (5 kHz … 200 kHz).

Recordings pass the sensor model's anti-alias filter at each rate. The paper reports a mean mass error below 5 %
above 30-40 kHz with outliers near 20 %, and recommends 50 kHz or more.
"""

from __future__ import annotations

from ..sensors import MAX_SAMPLE_RATE, MIN_SAMPLE_RATE
from .base import Row, Setting, Study, StudyFigure, StudyOptions, case_seed, register, scenario_grid
from .identification import (
    DEFAULT_METHODS,
    MODEL_REQUIRES,
    STUDY_METHODS,
    by_method,
    clean_recordings,
    identify_rows,
    max_abs,
    mean_abs,
    methods_of,
    pct,
    per_method,
    seeded_grid,
    with_failures,
    with_noise,
)

NAME = "sampling"
#: default values per grid axis (the paper's 125 scenarios)
GRID = 5
DEFAULTS = {"rates": [5e3, 10e3, 20e3, 30e3, 40e3, 50e3, 100e3, 200e3], "noise": 0.0,
            "methods": DEFAULT_METHODS}
SETTINGS = {"rates": Setting("numbers", MIN_SAMPLE_RATE, MAX_SAMPLE_RATE, "frequency"),
            "noise": Setting("number", 0.0, 1.0, "fraction"), "methods": STUDY_METHODS}


def _cases(options: StudyOptions) -> list[Row]:
    rates = sorted(float(r) for r in options.param(NAME, "rates", DEFAULTS["rates"]))
    scenarios = scenario_grid(options, GRID)
    if float(options.param(NAME, "noise", DEFAULTS["noise"])) > 0:
        scenarios = seeded_grid(scenarios, options)  # noise realisations only where there is noise
    # scenario-major order: every chunk holds a mix of cheap and expensive rates (balanced workers)
    return [{**s, "sample_rate": rate} for s in scenarios for rate in rates]


def _evaluate(cases: list[Row], options: StudyOptions) -> list[Row]:
    level = float(options.param(NAME, "noise", DEFAULTS["noise"]))
    methods = methods_of(options, NAME)
    rows = []
    for rate in dict.fromkeys(c["sample_rate"] for c in cases):
        group = [c for c in cases if c["sample_rate"] == rate]
        for case, clean in zip(group, clean_recordings(group, options, sample_rate=rate), strict=False):
            recording = with_noise(clean, {"contact_force": level, "piston_acceleration": level},
                                   case_seed(options, NAME, case["case"]))
            rows += identify_rows(recording, {**case, "noise": level}, methods, rig=options.rig)
    return rows


def _aggregate(rows: list[Row]) -> list[Row]:
    return by_method(rows, ("sample_rate",))


def _good_from(rows: list[Row], method: str) -> str:
    """Lowest rate from which every higher rate has a mean mass error below 5 %."""
    rates = sorted({r["sample_rate"] for r in rows}, reverse=True)
    good = None
    for rate in rates:
        if not mean_abs(rows, "mass_error", method=method, sample_rate=rate) < 5.0:
            break
        good = rate
    return "never" if good is None else f"{good / 1e3:g} kHz"


def _summary(rows: list[Row]) -> list[Row]:
    rates = sorted({r["sample_rate"] for r in rows})
    at = min((r for r in rates if r >= 40e3), default=rates[-1])
    return [{"quantity": "mean mass error below 5 % from (Fig. 7)",
             "ours": per_method(rows, lambda m: _good_from(rows, m)), "paper": "30-40 kHz"},
            {"quantity": f"mean / max mass error at {at / 1e3:g} kHz",
             "ours": per_method(rows, lambda m: f"{pct(mean_abs(rows, 'mass_error', method=m, sample_rate=at))} / "
                                                f"{pct(max_abs(rows, 'mass_error', method=m, sample_rate=at))}"),
             "paper": "< 5 % mean, outliers ≈ 20 %"}]


def _figure(rows: list[Row], options: StudyOptions) -> StudyFigure:
    return StudyFigure("plot_mean_error_vs", rows, {
        "parameters": (("sample_rate", "sampling frequency [kHz]", 1e-3),), "errors": ("mass_error", "velocity_error"),
        "maximum": True, "log_x": True, "reference": (5.0, "paper: mean < 5 % above 30-40 kHz"),
        "title": "Identification error vs sampling frequency (mean and max over the grid)"})


STUDY = register(Study(name=NAME, title="Mean and maximum error vs sampling frequency", figure="Fig. 7",
                       cases=_cases, evaluate=_evaluate, aggregate=_aggregate, summary=with_failures(_summary),
                       drawing=_figure, chunk_size=7, requires=MODEL_REQUIRES, defaults=DEFAULTS, settings=SETTINGS))
