"""Figures of the studies (matplotlib imported lazily). Each function takes the tidy rows and returns a Figure."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from ..plotting import _pyplot, figure_legend
from .tables import Row, group_stats, pick

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


def plot_strategy_distributions(rows: Sequence[Row]):
    """Absorber strategies side by side: distributions of efficiency, peak force after control and stroke."""
    plt = _pyplot()
    strategies = list(dict.fromkeys(r["strategy"] for r in rows))
    panels = [("efficiency", "efficiency η [-]", 1.0), ("peak_force_controlled_N", "peak force after control [kN]",
                                                         1e-3), ("stroke_used_m", "stroke used [mm]", 1e3)]
    fig, axes = plt.subplots(1, len(panels), figsize=(14, 4.2), constrained_layout=True)
    for ax, (column, label, scale) in zip(axes, panels, strict=False):
        data = []
        for strategy in strategies:
            values = np.array([np.nan if r.get(column) is None else float(r[column]) * scale for r in rows
                               if r["strategy"] == strategy])
            data.append(values[np.isfinite(values)])
        ax.boxplot([d if d.size else np.array([np.nan]) for d in data], showfliers=True)
        ax.set_xticks(range(1, len(strategies) + 1), strategies, rotation=20, fontsize=8)
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    bound = np.array([np.nan if r.get("efficiency_max") is None else float(r["efficiency_max"]) for r in rows])
    if np.isfinite(bound).any():
        axes[0].axhline(np.nanmedian(bound), color="k", ls="--", lw=0.8, label="median bound η_max")
        figure_legend(fig, axes[0])
    fig.suptitle("Absorber strategies over the impact grid")
    return fig
