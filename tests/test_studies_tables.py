"""Every registered study: tidy rows with the methods side by side, per-case seeding independent of chunking,
aggregate, summary and figure from the rows. Tiny sizes: one or two work units per study."""

from __future__ import annotations

import math
from functools import partial

import pytest

from impactometer.studies import STUDIES, StudyOptions, get_study, load_studies
from impactometer.studies.base import indexed_cases

load_studies()

#: per study: settings for a tiny run, the columns every row has, the column whose values are compared methods
TINY = {
    "cases": ({"cases.pressures": [100e3], "cases.velocities": [2.0]}, {"mass_error", "velocity_error"}, "method"),
    "parameters": ({}, {"mass_error", "velocity_error", "available_at"}, "method"),
    "noise": ({"noise.levels": [0.0, 0.05]}, {"noise_on", "noise", "mass_error"}, "method"),
    "sampling": ({"sampling.rates": [20e3, 50e3]}, {"sample_rate", "mass_error"}, "method"),
    "map-size": ({"map-size.sizes": [25], "map-size.grid125_sizes": [10], "map-size.features": ["peaks"]},
                 {"size", "mass_error_mean", "velocity_error_mean", "time_per_identification_s"}, "search"),
    "window": ({"window.windows": [0.01]}, {"window_s", "mass_error_mean", "velocity_error_mean"}, "search"),
    "map-recordings": ({"map-recordings.features": ["peaks"], "map-recordings.grid": 4, "map-recordings.map_grid": 10,
                        "map-recordings.n_held_back": 3},
                       {"feature_set", "map_grid", "mass_error_mean", "velocity_error_mean"}, "search"),
    "absorption": ({"absorption.strategies": ["closed", "predictive"], "absorption.reference_evaluations": 20},
                   {"strategy", "stage_b_ratio", "whole_event_peak_ratio", "common_window_start_s",
                    "floor_force_N", "reference_force_N", "bottomed_out", "rebound_m"}, "strategy"),
    "valve-design": ({"valve-design.areas_mm2": [100], "valve-design.response_times_ms": [3]},
                     {"effective_area_mm2", "response_time_ms", "stage_b_ratio", "whole_event_peak_ratio",
                      "bottomed_out"}, None),
    "absorber-design": ({"absorber-design.pressures": [200e3], "absorber-design.stiffnesses": [7e5]},
                        {"design", "pad_stiffness_N_m", "stage_b_ratio", "whole_event_peak_ratio",
                         "identified_available_at_s", "bottomed_out"}, None),
    "peak-force": ({}, {"simulated_peak_force", "recorded_peak_force", "closed_form_peak_force"}, None),
}
EXPECTED_METHODS = {"method": {"paper", "robust-early", "robust"}, "search": {"brute", "fast"},
                    "strategy": {"closed", "predictive", "predictive (oracle)",
                                 "predictive (oracle from the control start)", "achievable reference"}}
#: studies whose compared methods include the model fit (by default)
MODEL_STUDIES = {"noise", "sampling"}


def _ready(name):
    study = get_study(name)
    if study.missing():
        pytest.skip(f"study {name!r} needs {study.missing()}, not present in this tree")
    return study


def test_every_study_is_covered_here():
    assert set(STUDIES) == set(TINY)


def test_every_figure_a_study_names_is_drawn_by_the_plotting_module():
    from impactometer.plotting import studies as figures

    named = [study.drawing.args[0] for study in STUDIES.values() if isinstance(study.drawing, partial)]
    assert named and all(callable(getattr(figures, name, None)) for name in named)


@pytest.mark.parametrize("name", list(TINY))
def test_study_rows_aggregate_summary_and_figure(name):
    study = _ready(name)
    params, columns, methods = TINY[name]
    options = StudyOptions(grid=2, params=params)
    cases = indexed_cases(study, options)
    rows = study.evaluate(cases[:1], options)
    assert rows and all(columns <= set(row) for row in rows)
    assert all(row["case"] == 0 for row in rows)
    if methods:
        expected = EXPECTED_METHODS[methods] | ({"model"} if name in MODEL_STUDIES else set())
        assert {row[methods] for row in rows} == expected
    assert study.aggregate(rows)
    for line in study.summary(rows):
        assert set(line) == {"quantity", "ours", "paper"} and all(isinstance(v, str) for v in line.values())
    fig = study.drawing(rows, options).plot()
    assert fig.axes
    import matplotlib.pyplot as plt

    plt.close(fig)


def test_noise_of_a_case_does_not_depend_on_its_chunk():
    study = _ready("noise")
    options = StudyOptions(grid=2, seed=4, params={"noise.levels": [0.05]})
    cases = indexed_cases(study, options)
    together = study.evaluate(cases[:2], options)
    alone = study.evaluate(cases[1:2], options)
    second = [r for r in together if r["case"] == 1]
    # force, acceleration, both × paper, robust-early, robust, model
    assert len(second) == len(alone) == 12
    for a, b in zip(second, alone, strict=False):
        assert a.keys() == b.keys()
        for key in a:
            same = a[key] == b[key] or (isinstance(a[key], float) and math.isnan(a[key]) and math.isnan(b[key]))
            assert same, key


from hypothesis import given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

from impactometer.tables import read_csv, to_csv  # noqa: E402

_cells = st.one_of(st.integers(-10**12, 10**12), st.floats(allow_nan=False, allow_infinity=False, width=64),
                   st.text(alphabet=st.characters(blacklist_categories=("Cs",), blacklist_characters="\r\x00"),
                           max_size=12).filter(lambda s: not _looks_numeric(s)))


def _looks_numeric(text):
    try:
        float(text)
        return True
    except ValueError:
        return False


@settings(max_examples=60, deadline=None)
@given(st.lists(st.fixed_dictionaries({name: _cells for name in ("a", "b", "c,d", 'e"f')}), min_size=1, max_size=5))
def test_csv_round_trip_is_exact(rows):
    assert read_csv(to_csv(rows)) == rows
