"""Figures of the studies (matplotlib imported lazily). Each function takes the tidy rows and returns a Figure."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from ..studies.tables import Row, flag, group_stats, number, pick
from . import _pyplot, figure_legend

#: colour per compared method
COLORS = {"paper": "tab:red", "robust-early": "tab:orange", "robust": "tab:blue", "brute": "tab:red",
          "fast": "tab:blue"}


def _color(method: Any) -> str | None:
    return COLORS.get(method)


def _methods(rows: Sequence[Row], column: str = "method") -> list[str]:
    return list(dict.fromkeys(r[column] for r in rows))


def plot_peak_force(rows: Sequence[Row]):
    """Simulated and recorded first-pulse peak force vs the two-body closed form, per case."""
    plt = _pyplot()
    fig, ax = plt.subplots(1, 2, figsize=(11, 4), constrained_layout=True)
    closed = np.array([r["closed_form_peak_force"] for r in rows], dtype=float)
    simulated = np.array([r["simulated_peak_force"] for r in rows], dtype=float)
    recorded = np.array([r["recorded_peak_force"] for r in rows], dtype=float)
    mass = np.array([r["mass"] for r in rows], dtype=float)
    sc = ax[0].scatter(closed / 1e3, simulated / 1e3, c=mass, cmap="viridis", s=14, label="simulated (1 MHz)")
    ax[0].scatter(closed / 1e3, recorded / 1e3, c="none", edgecolors="tab:red", s=22, lw=0.7,
                  label="recorded by the DAQ")
    top = np.nanmax(np.concatenate([closed, simulated, recorded])) / 1e3 * 1.05 if closed.size else 1.0
    ax[0].plot([0, top], [0, top], "k--", lw=0.8, label="equal")
    ax[0].set(xlabel="closed form peak force [kN]", ylabel="first-pulse peak force [kN]", xlim=(0, top),
              ylim=(0, top))
    figure_legend(fig, ax[0])
    fig.colorbar(sc, ax=ax[0], label="M1 [kg]")
    pressure = np.array([r["pressure_gauge"] for r in rows], dtype=float) / 1e3
    sc2 = ax[1].scatter(mass, (simulated / closed - 1) * 100, s=14, c=pressure, cmap="plasma")
    ax[1].axhline(0, color="k", lw=0.8)
    ax[1].set(xlabel="M1 [kg]", ylabel="simulated / closed form − 1 [%]")
    fig.colorbar(sc2, ax=ax[1], label="p0 [kPa]")
    fig.suptitle("First contact pulse: simulator and DAQ vs the two-body closed form")
    return fig


def plot_case_bars(rows: Sequence[Row]):
    """Figs. 3-4: signed mass and velocity error per case as bars, methods side by side, one row per pressure."""
    plt = _pyplot()
    pressures = sorted({r["pressure_gauge"] for r in rows})
    methods = _methods(rows)
    fig, axes = plt.subplots(len(pressures), 2, figsize=(13, 3.2 * len(pressures)), squeeze=False,
                             constrained_layout=True)
    for row_axes, p in zip(axes, pressures, strict=False):
        subset = pick(rows, pressure_gauge=p)
        labels = list(dict.fromkeys(f"{r['mass']:g} kg\n{r['velocity']:.2g} m/s" for r in subset))
        x = np.arange(len(labels))
        width = 0.8 / max(len(methods), 1)
        for j, method in enumerate(methods):
            chosen = pick(subset, method=method)
            for ax, column in zip(row_axes, ("mass_error", "velocity_error"), strict=False):
                values = np.array([r[column] for r in chosen], dtype=float) * 100
                at = x[:values.size] + (j - (len(methods) - 1) / 2) * width
                ax.bar(at, values, width, label=method, color=_color(method))
                failed = ~np.isfinite(values)
                ax.plot(at[failed], np.zeros(failed.sum()), "x", color=_color(method), ms=7,
                        label=f"{method} failed" if failed.any() and ax is row_axes[0] else None)
        for ax, what in zip(row_axes, ("mass", "velocity"), strict=False):
            ax.set_yscale("symlog", linthresh=2.0)
            ax.axhline(0, color="k", lw=0.6)
            ax.set_xticks(x, labels, fontsize=6)
            ax.set_ylabel(f"{what} error [%]")
            ax.set_title(f"{what} identification, p0 = {p / 1e3:g} kPa")
    figure_legend(fig, axes[0][0])
    return fig


def plot_mean_error_vs(rows: Sequence[Row], parameters: Sequence[tuple[str, str, float]], *,
                       errors: Sequence[str] = ("mass_error",), title: str = "", maximum: bool = False,
                       log_x: bool = False, reference: tuple[float, str] | None = None):
    """Mean (and optionally max) |error| [%] vs each parameter: one column per parameter, one row per error,
    one line per method. ``parameters`` lists (column, axis label, display scale); ``reference`` draws a
    horizontal line (value [%], label) on the first row."""
    plt = _pyplot()
    fig, axes = plt.subplots(len(errors), len(parameters), figsize=(4.8 * max(len(parameters), 2), 3.8 * len(errors)),
                             squeeze=False, constrained_layout=True)
    for i, error in enumerate(errors):
        for ax, (column, label, scale) in zip(axes[i], parameters, strict=False):
            for method in _methods(rows):
                stats = sorted(group_stats(pick(rows, method=method), (column,), (error,)), key=lambda s: s[column])
                x = np.array([s[column] for s in stats]) * scale
                ax.plot(x, [s[f"mean_abs_{error}"] for s in stats], "o-", color=_color(method),
                        label=f"{method} mean")
                if maximum:
                    ax.plot(x, [s[f"max_abs_{error}"] for s in stats], "v:", color=_color(method),
                            label=f"{method} max")
            if reference is not None and i == 0:
                ax.axhline(reference[0], color="k", ls="--", lw=0.8, label=reference[1])
            ax.set(xlabel=label, ylabel=f"|{error.replace('_', ' ')}| [%]", yscale="log")
            if log_x:
                ax.set_xscale("log")
            ax.grid(alpha=0.3, which="both")
    figure_legend(fig, axes[0][0])
    fig.suptitle(title)
    return fig


def plot_noise(rows: Sequence[Row]):
    """Fig. 6: mean |mass error| vs noise level on the force, the acceleration and both, methods side by side."""
    plt = _pyplot()
    targets = ("force", "acceleration", "both")
    fig, axes = plt.subplots(2, 3, figsize=(14, 7), sharey="row", constrained_layout=True)
    for col, target in enumerate(targets):
        subset = [r for r in rows if r["noise_on"] in (target, "none")]
        for row, error in enumerate(("mass_error", "velocity_error")):
            ax = axes[row][col]
            for method in _methods(rows):
                stats = sorted(group_stats(pick(subset, method=method), ("noise",), (error,)),
                               key=lambda s: s["noise"])
                x = [s["noise"] * 100 for s in stats]
                ax.plot(x, [s[f"mean_abs_{error}"] for s in stats], "o-", color=_color(method), label=method)
            ax.set_yscale("log")
            ax.grid(alpha=0.3, which="both")
            ax.set(xlabel=f"noise on {target} [% of RMS]", ylabel=f"mean |{error.split('_')[0]} error| [%]")
    figure_legend(fig, axes[0][0])
    fig.suptitle("Identification error vs Gaussian noise (mean over the grid)")
    return fig


def plot_map_tables(rows: Sequence[Row], x: str, xlabel: str, *, log_x: bool = True, title: str = "",
                    x_scale: float = 1.0):
    """Figs. 8-9: mean |mass| and |velocity| error [%] (and time per identification) vs ``x``, one line per
    search method, feature set and test set."""
    plt = _pyplot()
    panels = [("mass_error_mean", "mean |mass error| [%]", 100.0),
              ("velocity_error_mean", "mean |velocity error| [%]", 100.0)]
    if any("time_per_identification_s" in r for r in rows):
        panels.append(("time_per_identification_s", "time per identification [ms]", 1e3))
    fig, axes = plt.subplots(1, len(panels), figsize=(5.0 * len(panels), 4.0), squeeze=False,
                             constrained_layout=True)
    keys = [k for k in ("search", "feature_set", "cases") if any(k in r for r in rows)]
    keys += [k for k in ("noise", "size") if k != x and len({r.get(k) for r in rows}) > 1]  # e.g. Fig. 9 settings
    series = list(dict.fromkeys(tuple(r.get(k) for k in keys) for r in rows))
    styles = ["-", "--", ":", "-."]
    feature_sets = list(dict.fromkeys(r.get("feature_set") for r in rows))
    for ax, (column, label, scale) in zip(axes[0], panels, strict=False):
        for values in series:
            chosen = sorted(pick(rows, **dict(zip(keys, values, strict=False))), key=lambda r: r[x])
            setting = dict(zip(keys, values, strict=False))
            ls = styles[feature_sets.index(setting.get("feature_set")) % len(styles)]
            marker = "s" if setting.get("cases") == "grid125" else "o"
            ax.plot([r[x] * x_scale for r in chosen], [r[column] * scale for r in chosen], ls=ls, marker=marker, ms=4,
                    color=_color(setting.get("search", "")), label=" / ".join(str(v) for v in values))
        ax.set(xlabel=xlabel, ylabel=label)
        ax.set_yscale("log")
        if log_x:
            ax.set_xscale("log")
        ax.grid(alpha=0.3, which="both")
    figure_legend(fig, axes[0][-1])
    fig.suptitle(title)
    return fig


def plot_map_recordings(rows: Sequence[Row]):
    """Map from noisy recordings: mean and max |mass| and |velocity| error [%] on held-back recordings, a group of
    bars per feature set, one bar per search method."""
    plt = _pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(11, 4), constrained_layout=True)
    feature_sets = list(dict.fromkeys(r["feature_set"] for r in rows))
    searches = _methods(rows, "search")
    width = 0.8 / max(len(searches), 1)
    for ax, quantity in zip(axes, ("mass", "velocity"), strict=True):
        for k, search in enumerate(searches):
            chosen = {r["feature_set"]: r for r in pick(rows, search=search)}
            x = np.arange(len(feature_sets)) + (k - (len(searches) - 1) / 2) * width
            mean = [100 * number(chosen[f][f"{quantity}_error_mean"]) if f in chosen else np.nan for f in feature_sets]
            top = [100 * number(chosen[f][f"{quantity}_error_max"]) if f in chosen else np.nan for f in feature_sets]
            ax.bar(x, mean, width, color=_color(search), label=f"{search} mean")
            ax.scatter(x, top, marker="_", s=200, color="k", label="max" if k == 0 else None)
        ax.set_xticks(np.arange(len(feature_sets)), feature_sets)
        ax.set(ylabel=f"|{quantity} error| [%]", title=f"{quantity}, held-back recordings")
        ax.set_yscale("log")
        ax.grid(alpha=0.3, which="both", axis="y")
    figure_legend(fig, axes[-1])
    fig.suptitle("Response map from noisy calibration recordings")
    return fig


def plot_absorption_study(rows: Sequence[Row], *, strategy: str = "predictive"):
    """Absorber strategies on stage B: the distribution of the force ratio R per strategy (oracle and achievable
    reference included), and per impact the identified ``strategy`` against its oracle and against the achievable
    reference."""
    plt = _pyplot()
    strategies = list(dict.fromkeys(r["strategy"] for r in rows))
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.6), constrained_layout=True,
                             gridspec_kw={"width_ratios": [1.6, 1, 1]})

    def ratio(row: Row | None) -> float:
        return np.nan if row is None or not flag(row.get("stage_b")) else number(row.get("stage_b_force_ratio"))

    data = [np.array([ratio(r) for r in rows if r["strategy"] == name]) for name in strategies]
    axes[0].boxplot([d[np.isfinite(d)] if np.isfinite(d).any() else np.array([np.nan]) for d in data])
    axes[0].set_xticks(range(1, len(strategies) + 1),
                       [f"{name}\n({int(np.isfinite(d).sum())} with stage B)" for name, d in zip(strategies, data,
                                                                                               strict=True)],
                       rotation=20, fontsize=8)
    axes[0].axhline(1.0, color="k", lw=0.8)
    median_target, p90_target = 1.3, 1.6  # the acceptance targets (studies.absorption.TARGETS)
    axes[0].axhline(median_target, color="tab:green", ls="--", lw=0.8, label=f"target median R {median_target:g}")
    axes[0].axhline(p90_target, color="tab:olive", ls=":", lw=0.8, label=f"target 90th percentile R {p90_target:g}")
    axes[0].set(ylabel="stage-B force ratio R [-] (ideal 1)", yscale="log")
    ticks = [1.0, median_target, p90_target, 2.0, 3.0, 4.0, 6.0]
    axes[0].set_yticks(ticks, [f"{tick:g}" for tick in ticks])
    axes[0].yaxis.set_minor_formatter("")
    axes[0].grid(alpha=0.3, which="both")
    figure_legend(fig, axes[0])
    by = {(r["case"], r["strategy"]): r for r in rows}
    cases = sorted({r["case"] for r in rows})
    mine = np.array([ratio(by.get((c, strategy))) for c in cases])
    mass = np.array([number(by[(c, strategy)]["mass_kg"]) if (c, strategy) in by else np.nan for c in cases])
    for ax, other, label in ((axes[1], f"{strategy} (oracle)", f"R, {strategy} with the true M1, V0"),
                             (axes[2], "achievable reference", "achievable R of the valve")):
        theirs = np.array([ratio(by.get((c, other))) for c in cases])
        sc = ax.scatter(theirs, mine, c=mass, cmap="viridis", s=16)
        finite = np.concatenate([mine[np.isfinite(mine)], theirs[np.isfinite(theirs)]])
        top = float(finite.max()) * 1.05 if finite.size else 2.0
        line = np.array([1.0, top])
        ax.plot(line, line, "k--", lw=0.8)
        if other.endswith("(oracle)"):
            ax.fill_between(line, 0.9 * line, 1.1 * line, color="tab:gray", alpha=0.2, lw=0)
        ax.set(xlabel=label, ylabel=f"R, {strategy} (identified)", xlim=(0.9, top), ylim=(0.9, top))
        ax.grid(alpha=0.3)
    fig.colorbar(sc, ax=axes[2], label="M1 [kg]")
    fig.suptitle("Adaptive absorption judged on stage B (CFC 60 peak force / F_ref)")
    return fig


def plot_valve_design(rows: Sequence[Row]):
    """Maps over valve size × response time: median and 90th-percentile R and the number of bottomed-out runs."""
    plt = _pyplot()
    areas = sorted({r["effective_area_mm2"] for r in rows})
    times = sorted({r["response_time_ms"] for r in rows})
    grids = {key: np.full((len(times), len(areas)), np.nan) for key in ("median", "p90", "bottomed")}
    for i, t in enumerate(times):
        for j, a in enumerate(areas):
            chosen = [r for r in rows if r["effective_area_mm2"] == a and r["response_time_ms"] == t]
            values = np.array([number(r.get("stage_b_force_ratio")) for r in chosen if flag(r.get("stage_b"))])
            values = values[np.isfinite(values)]
            if values.size:
                grids["median"][i, j] = np.median(values)
                grids["p90"][i, j] = np.percentile(values, 90)
            grids["bottomed"][i, j] = sum(flag(r.get("bottomed_out")) for r in chosen)
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.4), constrained_layout=True)
    for ax, (key, title) in zip(axes, (("median", "median R"), ("p90", "90th percentile R"),
                                       ("bottomed", "runs bottomed out")), strict=True):
        grid = grids[key]
        # the count map starts white at zero (a map of zeros is good news, not a colour of alarm)
        limits = {} if key != "bottomed" else {"vmin": 0.0, "vmax": max(1.0, float(np.nanmax(grid)))}
        image = ax.imshow(grid, origin="lower", aspect="auto", cmap="viridis_r" if key != "bottomed" else "Reds",
                          **limits)
        for i in range(len(times)):
            for j in range(len(areas)):
                if np.isfinite(grid[i, j]):
                    ax.text(j, i, f"{grid[i, j]:.2f}" if key != "bottomed" else f"{grid[i, j]:.0f}", ha="center",
                            va="center", fontsize=8, color="w" if key != "bottomed" else "k")
        ax.set_xticks(range(len(areas)), [f"{a:g}" for a in areas])
        ax.set_yticks(range(len(times)), [f"{t:g}" for t in times])
        ax.set(xlabel="effective area of the open valve [mm²]", ylabel="response time 10-90 % [ms]", title=title)
        fig.colorbar(image, ax=ax)
    fig.suptitle("Valve design: stage-B force ratio R of the predictive absorber over valve size and speed "
                 "(ISO 6358 valves, C ≈ S/5 dm³/(s·bar))")
    return fig
