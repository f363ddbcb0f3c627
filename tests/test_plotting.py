"""The figures say what they show: nothing clipped, no legend entry without data, legends off the titles, the
samples an answer used marked, filtered data labelled as such, one acceleration unit everywhere."""

from __future__ import annotations

import math

import matplotlib.pyplot as plt
import numpy as np
import pytest

from impactometer.control import absorb
from impactometer.filters import filter_recording
from impactometer.identify.inspection import inspect_recording
from impactometer.identify.peak_to_peak import identify, used_samples
from impactometer.model import simulate
from impactometer.plotting import ACCELERATION_LABEL
from impactometer.plotting.identification import plot_identification
from impactometer.plotting.simulation import plot_simulation
from impactometer.plotting.studies import (
    plot_case_bars,
    plot_map_recordings,
    plot_map_tables,
    plot_mean_error_vs,
    plot_noise,
    plot_peak_force,
    text_colour,
)
from impactometer.recording import Recording
from impactometer.rig import Scenario
from impactometer.studies import StudyOptions, get_study, load_studies
from impactometer.studies.valve_design import valve_label

METHODS = ("paper", "robust-early", "robust")


def _study_figure(name, rows):
    """The figure of study ``name`` drawn from ``rows``, with the values the study computes for it."""
    load_studies()
    return get_study(name).drawing(rows, StudyOptions()).plot()


@pytest.fixture(autouse=True)
def _close_figures():
    yield
    plt.close("all")


def _texts(fig) -> list[str]:
    return [t.get_text() for legend in fig.legends + [a.get_legend() for a in fig.axes if a.get_legend()]
            for t in legend.get_texts()]


def _clear_of_title(fig) -> bool:
    """Whether no legend of ``fig`` overlaps its suptitle once drawn."""
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    title = fig._suptitle.get_window_extent(renderer)
    legends = fig.legends + [a.get_legend() for a in fig.axes if a.get_legend()]
    return not any(legend.get_window_extent(renderer).overlaps(title) for legend in legends)


def _error_rows(rng, **columns) -> list[dict]:
    """Rows of an identification study over ``columns``; robust-early never answers."""
    keys = list(columns)
    rows = []
    for values in np.array(np.meshgrid(*columns.values(), indexing="ij")).reshape(len(keys), -1).T:
        for method, size in zip(METHODS, (0.2, math.nan, 1e-3), strict=True):
            error = size * rng.standard_normal(2)
            rows.append({**dict(zip(keys, values, strict=True)), "method": method, "mass_error": error[0],
                         "velocity_error": error[1]})
    return rows


def test_legend_names_no_series_without_data_and_keeps_off_the_title():
    rows = _error_rows(np.random.default_rng(0), sample_rate=[5e3, 20e3, 100e3], mass=[10.0, 30.0])
    fig = plot_mean_error_vs(rows, (("sample_rate", "sampling frequency [kHz]", 1e-3),),
                             errors=("mass_error", "velocity_error"), maximum=True, log_x=True,
                             reference=(5.0, "paper: mean < 5 % above 30-40 kHz"),
                             title="Identification error vs sampling frequency (mean and max over the grid)")
    texts = _texts(fig)
    assert "paper mean" in texts and "robust max" in texts
    assert not [t for t in texts if t.startswith("robust-early") and "no answer" not in t]
    assert "robust-early: no answer" in texts
    assert _clear_of_title(fig)


def test_noise_figure_lists_a_method_that_answered_somewhere():
    rng = np.random.default_rng(1)
    rows = []
    for noise, on in ((0.0, "none"), (0.05, "force"), (0.05, "acceleration"), (0.05, "both")):
        for method in METHODS:
            answered = method != "robust-early" or noise > 0.0  # the early answer only with noise
            rows.append({"noise": noise, "noise_on": on, "method": method,
                         "mass_error": 0.01 * rng.random() if answered else math.nan,
                         "velocity_error": 0.01 * rng.random() if answered else math.nan})
    texts = _texts(plot_noise(rows))
    assert "robust-early" in texts and not [t for t in texts if "no answer" in t]


def _case_rows(rng) -> list[dict]:
    rows = []
    for p in (20e3, 100e3):
        for mass in (10.0, 20.0, 30.0, 40.0, 50.0):
            for velocity in (1.0, 2.0, 3.0):
                for method, size in zip(METHODS, (0.5, math.nan, 2e-4), strict=True):
                    error = size * rng.standard_normal(2)
                    rows.append({"pressure_gauge": p, "mass": mass, "velocity": velocity, "method": method,
                                 "mass_error": error[0], "velocity_error": error[1]})
    return rows


def test_case_bars_show_large_and_small_errors_on_a_log_axis():
    rows = _case_rows(np.random.default_rng(2))
    fig = plot_case_bars(rows)
    panels = [a for a in fig.axes if a.patches]
    assert len(panels) == 4
    sizes = np.array([abs(r[f"{q}_error"]) * 100 for r in rows for q in ("mass", "velocity")])
    sizes = sizes[np.isfinite(sizes)]
    for ax in panels:
        assert ax.get_yscale() == "log"
        low, high = ax.get_ylim()
        assert low <= sizes.min() and high >= sizes.max()  # the robust hundredths and the paper's tens alike
        labels = ax.get_xticklabels() + ax.get_yticklabels()
        assert min(label.get_fontsize() for label in labels) >= 8
    texts = _texts(fig)
    assert "robust" in texts and "robust-early" not in texts  # no bar entry for a method without a bar
    assert "robust-early: no answer (×)" in texts


def test_valve_design_text_contrasts_and_an_empty_count_map_is_dropped():
    rows = [{"impact": i, "effective_area_mm2": a, "response_time_ms": t, "valve": valve_label(a, t),
             "stage_b_ratio": 1.0 + a / 400 + t + i, "bottomed_out": False}
            for a in (25.0, 100.0, 400.0) for t in (1.0, 3.0) for i in range(2)]
    fig = _study_figure("valve-design", rows)
    maps = [a for a in fig.axes if a.images]
    assert [a.get_title() for a in maps] == ["median R_B", "90th percentile R_B"]
    assert "on the 2 impacts every valve has it for" in fig._suptitle.get_text()
    assert "none of the 12 runs bottomed out" in fig._suptitle.get_text()
    for ax in maps:
        image = ax.images[0]
        for text in ax.texts:
            x, y = (int(round(v)) for v in text.get_position())
            assert text.get_color() == text_colour(image.cmap(image.norm(image.get_array()[y, x])))
    assert text_colour((1.0, 1.0, 0.0, 1.0)) == "k" and text_colour((0.27, 0.0, 0.33, 1.0)) == "w"
    rows[0]["bottomed_out"] = True
    fig = _study_figure("valve-design", rows)
    assert [a.get_title() for a in fig.axes if a.images][-1] == "runs bottomed out"


def test_the_other_study_figures_keep_their_legends_off_the_titles():
    rng = np.random.default_rng(3)
    tables = [{"size": size, "search": search, "feature_set": features, "cases": "random",
               "mass_error_mean": 0.01 * rng.random() if search == "fast" else math.nan,
               "velocity_error_mean": 0.01 * rng.random(), "time_per_identification_s": 1e-4}
              for size in (10, 50, 250) for search in ("brute", "fast") for features in ("peaks", "max-impulse")]
    recordings = [{"feature_set": f, "search": s, "mass_error_mean": 0.02, "mass_error_max": 0.1,
                   "velocity_error_mean": 0.01, "velocity_error_max": 0.05} for f in ("peaks", "max-impulse")
                  for s in ("brute", "fast")]
    peaks = [{"closed_form_peak_force": f, "simulated_peak_force": 1.01 * f, "recorded_peak_force": 0.98 * f,
              "mass": m, "pressure_gauge": 1e5} for f, m in ((2e3, 10.0), (4e3, 30.0), (6e3, 50.0))]
    absorption = [{"case": c, "strategy": s, "stage_b_ratio": 1.1 + 0.1 * c, "whole_event_peak_ratio": 3.0 + c,
                   "mass_kg": 10.0 * c} for c in range(1, 4)
                  for s in ("closed", "predictive", "predictive (oracle)", "achievable reference")]
    figures = [plot_map_tables(tables, "size", "map size", title="Response map: error vs database size"),
               plot_map_recordings(recordings), plot_peak_force(peaks),
               _study_figure("absorption", absorption)]
    for fig in figures:
        assert fig.legends and _clear_of_title(fig)
    texts = _texts(figures[0])
    assert "brute / peaks / random: no answer" not in texts  # it has velocity errors
    assert "fast / peaks / random" in texts


@pytest.fixture(scope="module")
def absorbed():
    return absorb(Scenario(mass=30.0, velocity=2.4, pressure_gauge=2e5), strategy=["closed", "predictive"],
                  identification="oracle")


def test_absorption_figure_clips_no_force_and_labels_its_lines(absorbed):
    fig = absorbed.plot()
    zoom, force, motion = fig.axes
    peak = max(float(run.result.contact_force.max()) for run in absorbed.runs.values()) / 1e3
    assert force.get_ylim()[1] >= peak and zoom.get_ylim()[1] >= peak
    assert 15.0 <= zoom.get_xlim()[1] <= 40.0  # the first ~20 ms, where the identification reads
    texts = _texts(fig)
    window = absorbed.window
    assert any(t.startswith("control starts") for t in texts)
    assert f"first sustained contact ({window.start * 1e3:.1f} ms)" in texts
    assert "common window of R_B (to the deepest point)" in texts
    assert any(t.startswith("F_floor") for t in texts) and any(t.startswith("F_ref") for t in texts)
    assert any(t.startswith("thin:") for t in texts) and any(t.startswith("thick: CFC 60") for t in texts)
    assert any(t.startswith("solid: mass") for t in texts) and any(t.startswith("dashed: piston") for t in texts)
    usable = absorbed.absorber.usable_stroke(absorbed.rig) * 1e3
    lines = {round(line.get_ydata()[0], 6): line.get_label() for line in motion.get_lines()
             if len(set(line.get_ydata())) == 1 and len(line.get_ydata()) == 2}
    assert "piston" in lines[round(usable, 6)] and "bottom stop" in lines[round(absorbed.rig.cylinder.stroke * 1e3,
                                                                                  6)]
    # the mass and the piston of every run are both drawn (the mass passes the piston by the pad's compression)
    assert len([line for line in motion.get_lines() if len(line.get_xdata()) > 2]) == 2 * len(absorbed.runs)
    # every panel has a legend a reader takes in at a glance, and no entry stands in two: the runs and the
    # instants by the zoom, the forces and the line styles by the force history, the bodies by the displacements
    entries = [[t.get_text() for t in ax.get_legend().get_texts()] for ax in (zoom, force, motion)]
    assert all(0 < len(panel) <= 8 for panel in entries), entries
    assert sum(len(panel) for panel in entries) == len({t for panel in entries for t in panel})
    assert [t.split(":")[0] for t in entries[0][:len(absorbed.runs)]] == list(absorbed.runs)
    assert any(t.startswith("control starts") for t in entries[0])


@pytest.fixture(scope="module")
def stiff_recording():
    r = simulate(Scenario(mass=25, velocity=1.8, pressure_gauge=1.5e5), "drop-stand-stiff", duration=0.08)
    pre = np.zeros(1000)
    return Recording(sample_rate=50e3, channels={"contact_force": np.r_[pre, r.contact_force],
                                                 "piston_acceleration": np.r_[pre, r.a2]},
                     start_time=-0.02, source="test")


def test_identification_figure_marks_the_samples_the_robust_answer_used(stiff_recording):
    result = identify(stiff_recording)
    used = result.details["equations"]
    rows = used_samples(result, stiff_recording)
    assert rows["onsets"].size == used["onsets"]
    assert rows["turning_a"].size + rows["turning_b"].size == used["extrema"]
    assert rows["separations"].size == used["separations"]
    fig = result.plot(stiff_recording, used=rows)
    texts = _texts(fig)
    for key, label in (("onsets", "onsets used"), ("extrema", "turning points used, stage A"),
                       ("separations", "separations used")):
        if used[key]:
            assert f"{label} ({used[key]})" in texts
    assert "t01: first force peak" not in texts  # the paper's instants are not rows of the robust answer
    marked = [line for line in fig.axes[0].get_lines() if line.get_label().startswith("separations used")]
    assert len(marked) == 1 and len(marked[0].get_xdata()) == used["separations"]
    paper = identify(stiff_recording, variant="paper")
    assert used_samples(paper, stiff_recording) is None
    assert "t11: second force peak" in _texts(plot_identification(paper, stiff_recording))


def test_filtered_recording_says_so_and_every_figure_uses_one_acceleration_unit(stiff_recording):
    filtered = filter_recording(stiff_recording, 180)
    fig = inspect_recording(filtered).plot(filtered)
    assert "CFC 180 filtered" in fig.axes[0].get_title()
    assert "contact force, CFC 180 filtered" in _texts(fig)
    assert "no CFC filter applied" in inspect_recording(stiff_recording).plot(stiff_recording).axes[0].get_title()
    labels = [fig.axes[1].get_ylabel(),
              plot_identification(identify(stiff_recording), stiff_recording).axes[1].get_ylabel(),
              plot_simulation(simulate(Scenario(mass=25, velocity=1.8, pressure_gauge=1.5e5), "drop-stand-stiff",
                                       duration=0.02)).axes[1].get_ylabel()]
    assert labels == [ACCELERATION_LABEL] * 3 and "m/s²" in ACCELERATION_LABEL
