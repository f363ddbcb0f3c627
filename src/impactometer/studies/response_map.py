"""Studies ``map-size`` (the paper's Fig. 8), ``window`` (Fig. 9) and ``map-recordings``: the response-map analyses.

Thin wrappers: the tables come from :mod:`impactometer.studies.map_tables`; here they are split into
independent work units (one database size, feature set and test set; one window and noise level; one feature set)
for the runner, and summarised next to the paper's statements (velocity 5-10× more accurate than mass; more than
350 ms per identification at 3000×3000 with the brute search; mass error falling with the window T, velocity
insensitive to it). ``map-recordings`` is not in the paper: a map from noisy calibration recordings identifies
held-back noisy recordings.
"""

from __future__ import annotations

import numpy as np

from ..identify.response_map.features import FEATURE_SETS
from ..identify.response_map.search import SEARCHES
from ..tables import pick
from .base import MAX_GRID, Row, Setting, Study, StudyFigure, StudyOptions, plotted_by, register
from .map_tables import CASES, PAPER_SIZES, map_size_table, recordings_table, window_table

REQUIRES = ("impactometer.identify.response_map",)
MAP_SIZE = "map-size"
WINDOW = "window"
RECORDINGS = "map-recordings"
MAP_DEFAULTS = {"sizes": list(PAPER_SIZES), "grid125_sizes": [10, 50], "cases": list(CASES),
                "features": ["peaks", "max-impulse"], "searches": ["brute", "fast"], "n_random": 10}
WINDOW_DEFAULTS = {"windows": [round(0.002 * k, 3) for k in range(1, 16)], "sizes": [50], "noises": [0.0],
                   "searches": ["brute", "fast"], "n_random": 10}
RECORDINGS_DEFAULTS = {"features": list(FEATURE_SETS), "searches": ["brute", "fast"], "grid": 10, "map_grid": 50,
                       "n_held_back": 20}
_SIZES = Setting("integers", 2, max(PAPER_SIZES))
_SEARCHES = Setting("choices", choices=tuple(SEARCHES))
_FEATURES = Setting("choices", choices=tuple(FEATURE_SETS))
_N_RANDOM = Setting("integer", 1, 10_000)
MAP_SETTINGS = {"sizes": _SIZES, "grid125_sizes": _SIZES, "cases": Setting("choices", choices=CASES),
                "features": _FEATURES, "searches": _SEARCHES, "n_random": _N_RANDOM}
WINDOW_SETTINGS = {"windows": Setting("numbers", 0.0, 0.1, "time", low_open=True), "sizes": _SIZES,
                   "noises": Setting("numbers", 0.0, 1.0, "fraction"), "searches": _SEARCHES,
                   "n_random": _N_RANDOM}
RECORDINGS_SETTINGS = {"features": _FEATURES, "searches": _SEARCHES, "grid": Setting("integer", 2, MAX_GRID),
                       "map_grid": Setting("integer", 2, max(PAPER_SIZES)), "n_held_back": _N_RANDOM}


def _setting(options: StudyOptions, study: str, defaults: dict, name: str):
    return options.param(study, name, defaults[name])


def _map_cases(options: StudyOptions) -> list[Row]:
    get = lambda name: _setting(options, MAP_SIZE, MAP_DEFAULTS, name)  # noqa: E731
    sets = {"random": get("sizes"), "grid125": get("grid125_sizes")}
    return [{"feature_set": f, "cases": c, "size": int(n)} for f in get("features") for c, sizes in sets.items()
            if c in get("cases") for n in sorted(sizes, reverse=True)]


def _map_evaluate(cases: list[Row], options: StudyOptions) -> list[Row]:
    rows = []
    for case in cases:
        table = map_size_table(rig=options.rig, sizes=[case["size"]], feature_sets=[case["feature_set"]],
                               cases=[case["cases"]], searches=_setting(options, MAP_SIZE, MAP_DEFAULTS, "searches"),
                               n_random=_setting(options, MAP_SIZE, MAP_DEFAULTS, "n_random"), seed=options.seed,
                               sample_rate=options.sample_rate)
        rows += [{"case": case["case"], **row} for row in table]
    return rows


def _window_cases(options: StudyOptions) -> list[Row]:
    get = lambda name: _setting(options, WINDOW, WINDOW_DEFAULTS, name)  # noqa: E731
    return [{"window_s": float(w), "noise": float(n)} for n in get("noises") for w in get("windows")]


def _window_evaluate(cases: list[Row], options: StudyOptions) -> list[Row]:
    get = lambda name: _setting(options, WINDOW, WINDOW_DEFAULTS, name)  # noqa: E731
    rows = []
    for case in cases:
        table = window_table(rig=options.rig, windows=[case["window_s"]], sizes=get("sizes"),
                             searches=get("searches"), n_random=get("n_random"), seed=options.seed,
                             sample_rate=options.sample_rate, noise=case["noise"])
        rows += [{"case": case["case"], **row} for row in table]
    return rows


def _percent(rows: list[Row], keys: tuple[str, ...]) -> list[Row]:
    """Rows with the error columns in percent and the time in ms, sorted by ``keys``."""
    out = []
    for row in rows:
        entry = {k: row[k] for k in keys if k in row}
        for column in ("mass_error_mean", "mass_error_max", "velocity_error_mean", "velocity_error_max"):
            entry[f"{column} [%]"] = row[column] * 100
        if "time_per_identification_s" in row:
            entry["time per identification [ms]"] = row["time_per_identification_s"] * 1e3
        entry["extrapolated"] = row.get("extrapolated", 0)
        out.append(entry)
    return sorted(out, key=lambda r: tuple(r[k] for k in keys if k in r))


def _map_aggregate(rows: list[Row]) -> list[Row]:
    return _percent(rows, ("feature_set", "cases", "search", "size"))


def _ratio_text(rows: list[Row], search: str) -> str:
    chosen = [r for r in pick(rows, search=search, cases="random") if r["velocity_error_mean"] > 0]
    if not chosen:
        return "–"
    ratios = np.array([r["mass_error_mean"] / r["velocity_error_mean"] for r in chosen])
    return f"{search} {np.median(ratios):.3g}× (median over sizes and features)"


def _map_summary(rows: list[Row]) -> list[Row]:
    largest = max((r["size"] for r in rows), default=0)
    def timing(search: str) -> str:
        values = [r["time_per_identification_s"] for r in pick(rows, search=search, size=largest)]
        return f"{search} {np.mean(values) * 1e3:.3g} ms" if values else "–"
    def best(search: str) -> str:
        chosen = pick(rows, search=search, size=largest, cases="random")
        if not chosen:
            return "–"
        return f"{search} mass {min(r['mass_error_mean'] for r in chosen) * 100:.2g} %, velocity " \
               f"{min(r['velocity_error_mean'] for r in chosen) * 100:.2g} %"
    return [{"quantity": "mass error / velocity error, response map (Fig. 8)",
             "ours": "; ".join(_ratio_text(rows, s) for s in ("brute", "fast")),
             "paper": "velocity 5-10× more accurate"},
            {"quantity": f"time per identification at {largest}×{largest}",
             "ours": "; ".join(timing(s) for s in ("brute", "fast")), "paper": "> 350 ms (brute force, 3000×3000)"},
            {"quantity": f"mean error at {largest}×{largest}, 10 random impacts (best feature set)",
             "ours": "; ".join(best(s) for s in ("brute", "fast")), "paper": "falls with the database size"}]


def _window_aggregate(rows: list[Row]) -> list[Row]:
    return _percent(rows, ("noise", "search", "size", "window_s"))


def _window_summary(rows: list[Row]) -> list[Row]:
    def trend(search: str, column: str) -> str:
        quietest = min((r["noise"] for r in rows), default=0.0)
        chosen = sorted(pick(rows, search=search, noise=quietest), key=lambda r: r["window_s"])
        if not chosen:
            return "–"
        first, last = chosen[0], chosen[-1]
        return (f"{search} {first[column] * 100:.2g} % at {first['window_s'] * 1e3:g} ms → "
                f"{last[column] * 100:.2g} % at {last['window_s'] * 1e3:g} ms")
    return [{"quantity": "mean mass error vs window T, max-impulse (Fig. 9)",
             "ours": "; ".join(trend(s, "mass_error_mean") for s in ("brute", "fast")),
             "paper": "falls with T, most for small databases"},
            {"quantity": "mean velocity error vs window T",
             "ours": "; ".join(trend(s, "velocity_error_mean") for s in ("brute", "fast")),
             "paper": "insensitive to T"}]


def _map_figure(rows: list[Row], options: StudyOptions) -> StudyFigure:
    return StudyFigure("plot_map_tables", rows, {"x": "size", "xlabel": "database size N (N×N)",
                                                 "title": "Response map: error and time vs database size"})


def _window_figure(rows: list[Row], options: StudyOptions) -> StudyFigure:
    return StudyFigure("plot_map_tables", rows, {"x": "window_s", "xlabel": "integration window T [ms]",
                                                 "log_x": False, "x_scale": 1e3,
                                                 "title": "Response map (max-impulse): error vs integration window"})


def _recordings_cases(options: StudyOptions) -> list[Row]:
    return [{"feature_set": f} for f in _setting(options, RECORDINGS, RECORDINGS_DEFAULTS, "features")]


def _recordings_evaluate(cases: list[Row], options: StudyOptions) -> list[Row]:
    """One table per feature set: a map from ``grid``² recordings at the options' noise and sample rate."""
    get = lambda name: _setting(options, RECORDINGS, RECORDINGS_DEFAULTS, name)  # noqa: E731
    rows = []
    for case in cases:
        table = recordings_table(rig=options.rig, grid=get("grid"), map_grid=get("map_grid"), noise=options.noise,
                                 n_held_back=get("n_held_back"), feature_sets=[case["feature_set"]],
                                 searches=get("searches"), seed=options.seed, sample_rate=options.sample_rate)
        rows += [{"case": case["case"], "noise": options.noise, **row} for row in table]
    return rows


def _recordings_aggregate(rows: list[Row]) -> list[Row]:
    return _percent(rows, ("feature_set", "search", "map_grid"))


def _recordings_summary(rows: list[Row]) -> list[Row]:
    def best(search: str) -> str:
        chosen = pick(rows, search=search)
        if not chosen:
            return "–"
        row = min(chosen, key=lambda r: r["mass_error_mean"])
        return (f"{search} mass {row['mass_error_mean'] * 100:.2g} %, velocity "
                f"{row['velocity_error_mean'] * 100:.2g} % ({row['feature_set']})")
    return [{"quantity": "mean error on held-back recordings, map from noisy recordings (best feature set)",
             "ours": "; ".join(best(s) for s in ("brute", "fast")),
             "paper": "not studied (acceptance here: mass <= 1 %, velocity <= 0.5 %)"}]


STUDY_MAP = register(Study(name=MAP_SIZE, title="Response map: error and time per identification vs database size",
                           figure="Fig. 8", cases=_map_cases, evaluate=_map_evaluate, aggregate=_map_aggregate,
                           summary=_map_summary, drawing=_map_figure, chunk_size=1, requires=REQUIRES,
                           defaults=MAP_DEFAULTS, settings=MAP_SETTINGS))
STUDY_WINDOW = register(Study(name=WINDOW, title="Response map: error vs integration window T (max-impulse)",
                              figure="Fig. 9", cases=_window_cases, evaluate=_window_evaluate,
                              aggregate=_window_aggregate, summary=_window_summary, drawing=_window_figure,
                              chunk_size=3, requires=REQUIRES, defaults=WINDOW_DEFAULTS,
                              settings=WINDOW_SETTINGS))
STUDY_RECORDINGS = register(Study(name=RECORDINGS, title="Response map from noisy calibration recordings: error on "
                                                        "held-back recordings", figure="", cases=_recordings_cases,
                                  evaluate=_recordings_evaluate, aggregate=_recordings_aggregate,
                                  summary=_recordings_summary, drawing=plotted_by("plot_map_recordings"), chunk_size=1,
                                  requires=REQUIRES, defaults=RECORDINGS_DEFAULTS, settings=RECORDINGS_SETTINGS))
