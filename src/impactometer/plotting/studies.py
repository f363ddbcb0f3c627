"""Figures of the studies (matplotlib imported lazily). Each function takes the tidy rows and returns a Figure."""

from __future__ import annotations

import textwrap
from collections.abc import Sequence
from typing import Any

import numpy as np

from ..tables import Row, group_stats, number, pick
from . import _pyplot, figure_legend, labelled

#: colour per compared method
COLORS = {"paper": "tab:red", "robust-early": "tab:orange", "robust": "tab:blue", "model": "tab:green",
          "brute": "tab:red", "fast": "tab:blue"}


def _color(method: Any) -> str | None:
    return COLORS.get(method)


def _methods(rows: Sequence[Row], column: str = "method") -> list[str]:
    return list(dict.fromkeys(r[column] for r in rows))


def _series(ax, x, y, style: str, *, label: str, answered: set[str], name: str, **options) -> None:
    """One line on ``ax``, in the legend as ``label`` only where it has finite data; ``name`` joins ``answered``
    then (the names never answered are listed once, as giving no answer, by :func:`figure_legend`)."""
    shown = labelled(label, y)
    ax.plot(x, y, style, label=shown, **options)
    if shown:
        answered.add(name)


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
    fig.colorbar(sc, ax=ax[0], label="M1 [kg]")
    pressure = np.array([r["pressure_gauge"] for r in rows], dtype=float) / 1e3
    sc2 = ax[1].scatter(mass, (simulated / closed - 1) * 100, s=14, c=pressure, cmap="plasma")
    ax[1].axhline(0, color="k", lw=0.8)
    ax[1].set(xlabel="M1 [kg]", ylabel="simulated / closed form − 1 [%]")
    fig.colorbar(sc2, ax=ax[1], label="p0 [kPa]")
    figure_legend(fig)
    fig.suptitle("First contact pulse: simulator and DAQ vs the two-body closed form")
    return fig


def plot_case_bars(rows: Sequence[Row]):
    """Figs. 3-4: |mass| and |velocity| error [%] per case on a log axis, so that the paper variant's tens of per
    cent and the robust variant's hundredths are both readable; methods side by side, a hatched bar a negative
    error (an underestimate), a cross a case a method gave no answer for. One panel per pressure and quantity."""
    from matplotlib.patches import Patch
    from matplotlib.transforms import blended_transform_factory

    plt = _pyplot()
    pressures = sorted({r["pressure_gauge"] for r in rows})
    methods = _methods(rows)
    panels = [(p, what) for p in pressures for what in ("mass", "velocity")]
    fig, axes = plt.subplots(len(panels), 1, figsize=(13, 2.7 * len(panels) + 0.8), squeeze=False,
                             constrained_layout=True)
    width = 0.8 / max(len(methods), 1)
    sizes = [abs(number(r[f"{what}_error"])) * 100 for r in rows for what in ("mass", "velocity")]
    positive = np.array([v for v in sizes if np.isfinite(v) and v > 0.0])
    low, high = (positive.min() / 3.0, positive.max() * 3.0) if positive.size else (1e-2, 1e2)
    keys: dict[str, Any] = {}
    for ax, (p, what) in zip(axes[:, 0], panels, strict=True):
        subset = pick(rows, pressure_gauge=p)
        labels = list(dict.fromkeys(f"{r['mass']:g} kg\n{r['velocity']:.2g} m/s" for r in subset))
        x = np.arange(len(labels))
        on_floor = blended_transform_factory(ax.transData, ax.transAxes)
        for j, method in enumerate(methods):
            values = np.array([number(r[f"{what}_error"]) for r in pick(subset, method=method)]) * 100
            at = x[:values.size] + (j - (len(methods) - 1) / 2) * width
            below, failed = values < 0.0, ~np.isfinite(values)
            bars = ax.bar(at[~failed], np.abs(values[~failed]), width, color=_color(method), lw=0.0,
                          label=labelled(method, values))
            for bar, negative in zip(bars, below[~failed], strict=True):
                if negative:
                    bar.set(hatch="///", edgecolor="w")
            crosses = ax.plot(at[failed], np.full(failed.sum(), 0.04), "x", color=_color(method), ms=7,
                              transform=on_floor)
            # keys to the styles, in the legend after the methods' bars
            if below.any():
                keys.setdefault("hatched: negative error (underestimate)",
                                Patch(facecolor="0.55", hatch="///", edgecolor="w", lw=0.0))
            if failed.any():
                keys.setdefault(f"{method}: no answer (×)", crosses[0])
        ax.set_yscale("log")
        ax.set_ylim(low, high)
        ax.set_xlim(-0.6, len(labels) - 0.4)
        ax.set_xticks(x, labels, fontsize=8)
        ax.tick_params(axis="y", labelsize=8)
        ax.grid(alpha=0.3, which="major", axis="y")
        ax.set_ylabel(f"|{what} error| [%]")
        ax.set_title(f"{what} identification, p0 = {p / 1e3:g} kPa", fontsize=10)
    figure_legend(fig, extra=keys)
    return fig


def plot_mean_error_vs(rows: Sequence[Row], parameters: Sequence[tuple[str, str, float]], *,
                       errors: Sequence[str] = ("mass_error",), title: str = "", maximum: bool = False,
                       log_x: bool = False, reference: tuple[float, str] | None = None):
    """Mean (and optionally max) |error| [%] vs each parameter: one column per parameter, one row per error,
    one line per method. ``parameters`` lists (column, axis label, display scale); ``reference`` draws a
    horizontal line (value [%], label) on the first row. A method without a finite value anywhere is named in the
    legend as giving no answer."""
    plt = _pyplot()
    fig, axes = plt.subplots(len(errors), len(parameters), figsize=(4.8 * max(len(parameters), 2), 3.8 * len(errors)),
                             squeeze=False, constrained_layout=True)
    answered: set[str] = set()
    for i, error in enumerate(errors):
        for ax, (column, label, scale) in zip(axes[i], parameters, strict=False):
            for method in _methods(rows):
                stats = sorted(group_stats(pick(rows, method=method), (column,), (error,)), key=lambda s: s[column])
                x = np.array([s[column] for s in stats]) * scale
                lines = [("mean", "o-", "mean_abs")] + ([("max", "v:", "max_abs")] if maximum else [])
                for what, style, key in lines:
                    _series(ax, x, [s[f"{key}_{error}"] for s in stats], style, label=f"{method} {what}",
                            answered=answered, name=method, color=_color(method))
            if reference is not None and i == 0:
                ax.axhline(reference[0], color="k", ls="--", lw=0.8, label=reference[1])
            ax.set(xlabel=label, ylabel=f"|{error.replace('_', ' ')}| [%]", yscale="log")
            if log_x:
                ax.set_xscale("log")
            ax.grid(alpha=0.3, which="both")
    figure_legend(fig, no_answer=[m for m in _methods(rows) if m not in answered])
    fig.suptitle(title)
    return fig


def plot_noise(rows: Sequence[Row]):
    """Fig. 6: mean |mass error| vs noise level on the force, the acceleration and both, methods side by side."""
    plt = _pyplot()
    targets = ("force", "acceleration", "both")
    fig, axes = plt.subplots(2, 3, figsize=(14, 7), sharey="row", constrained_layout=True)
    answered: set[str] = set()
    for col, target in enumerate(targets):
        subset = [r for r in rows if r["noise_on"] in (target, "none")]
        for row, error in enumerate(("mass_error", "velocity_error")):
            ax = axes[row][col]
            for method in _methods(rows):
                stats = sorted(group_stats(pick(subset, method=method), ("noise",), (error,)),
                               key=lambda s: s["noise"])
                _series(ax, [s["noise"] * 100 for s in stats], [s[f"mean_abs_{error}"] for s in stats], "o-",
                        label=method, answered=answered, name=method, color=_color(method))
            ax.set_yscale("log")
            ax.grid(alpha=0.3, which="both")
            ax.set(xlabel=f"noise on {target} [% of RMS]", ylabel=f"mean |{error.split('_')[0]} error| [%]")
    figure_legend(fig, no_answer=[m for m in _methods(rows) if m not in answered])
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
    names = [" / ".join(str(v) for v in values) for values in series]
    styles = ["-", "--", ":", "-."]
    feature_sets = list(dict.fromkeys(r.get("feature_set") for r in rows))
    answered: set[str] = set()
    for ax, (column, label, scale) in zip(axes[0], panels, strict=False):
        for values, name in zip(series, names, strict=True):
            chosen = sorted(pick(rows, **dict(zip(keys, values, strict=False))), key=lambda r: r[x])
            setting = dict(zip(keys, values, strict=False))
            ls = styles[feature_sets.index(setting.get("feature_set")) % len(styles)]
            marker = "s" if setting.get("cases") == "grid125" else "o"
            _series(ax, [r[x] * x_scale for r in chosen], [number(r[column]) * scale for r in chosen],
                    f"{ls}{marker}", label=name, answered=answered, name=name, ms=4,
                    color=_color(setting.get("search", "")))
        ax.set(xlabel=xlabel, ylabel=label)
        ax.set_yscale("log")
        if log_x:
            ax.set_xscale("log")
        ax.grid(alpha=0.3, which="both")
    figure_legend(fig, no_answer=[name for name in names if name not in answered])
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
    answered: set[str] = set()
    for ax, quantity in zip(axes, ("mass", "velocity"), strict=True):
        for k, search in enumerate(searches):
            chosen = {r["feature_set"]: r for r in pick(rows, search=search)}
            x = np.arange(len(feature_sets)) + (k - (len(searches) - 1) / 2) * width
            mean = [100 * number(chosen[f][f"{quantity}_error_mean"]) if f in chosen else np.nan for f in feature_sets]
            top = [100 * number(chosen[f][f"{quantity}_error_max"]) if f in chosen else np.nan for f in feature_sets]
            ax.bar(x, mean, width, color=_color(search), label=labelled(f"{search} mean", mean))
            ax.scatter(x, top, marker="_", s=200, color="k", label=labelled("max", top))
            if labelled(search, mean):
                answered.add(search)
        ax.set_xticks(np.arange(len(feature_sets)), feature_sets)
        ax.set(ylabel=f"|{quantity} error| [%]", title=f"{quantity}, held-back recordings")
        ax.set_yscale("log")
        ax.grid(alpha=0.3, which="both", axis="y")
    figure_legend(fig, no_answer=[s for s in searches if s not in answered])
    fig.suptitle("Response map from noisy calibration recordings")
    return fig


def plot_absorption_study(rows: Sequence[Row], *, values: dict[str, dict[str, np.ndarray]], kept: int, left: int,
                          targets: dict[str, float], reference: str, strategy: str = "predictive"):
    """Absorber strategies on the common set of impacts (where the reference exists too): the distribution of R_B
    per strategy (oracle and achievable reference included) and of the whole-event CFC 60 peak / F0, and per impact
    the identified ``strategy`` against its oracle and against the achievable reference (``reference``).

    ``values``: strategy -> column -> its values on the common set, impact by impact; ``kept`` and ``left``: how many
    impacts the common set holds and leaves out; ``targets``: the study's targets (``median``, ``p90``,
    ``oracle_deviation``, ``achievable``). The study computes them (``studies.absorption``); a run without
    ``strategy``, its oracle or the reference draws those panels empty."""
    plt = _pyplot()
    strategies = list(values)

    def on_common_set(name: str, column: str) -> np.ndarray:
        return values.get(name, {}).get(column, np.full(kept, np.nan))

    impacts = list(dict.fromkeys(r["case"] for r in rows))
    fig, axes = plt.subplots(1, 4, figsize=(19, 4.8), constrained_layout=True,
                             gridspec_kw={"width_ratios": [1.5, 1.3, 1, 1]})
    for ax, column, label in ((axes[0], "stage_b_ratio", "R_B on the common window [-] (ideal 1)"),
                              (axes[1], "whole_event_peak_ratio", "whole-event CFC 60 peak / F0 [-]")):
        data = [on_common_set(name, column) for name in strategies]
        data = [d[np.isfinite(d)] for d in data]
        ax.boxplot([d if d.size else np.array([np.nan]) for d in data])
        # long names (an oracle's "from the control start") on two lines, so neighbours do not overlap
        ax.set_xticks(range(1, len(strategies) + 1), [textwrap.fill(name, 14) for name in strategies],
                      rotation=20, fontsize=8)
        ax.axhline(1.0, color="k", lw=0.8)
        ax.set(ylabel=label, yscale="log")
        ax.grid(alpha=0.3, which="both")
    axes[0].axhline(targets["median"], color="tab:green", ls="--", lw=0.8,
                    label=f"target median R_B {targets['median']:g}")
    axes[0].axhline(targets["p90"], color="tab:olive", ls=":", lw=0.8,
                    label=f"target 90th percentile R_B {targets['p90']:g}")
    ticks = [1.0, targets["median"], targets["p90"], 2.0, 3.0, 5.0]
    axes[0].set_yticks(ticks, [f"{tick:g}" for tick in ticks])
    axes[0].yaxis.set_minor_formatter("")
    axes[0].set_title(f"common set: {kept} of {len(impacts)} impacts ({left} left out, named in the "
                      "report)", fontsize=9)
    axes[1].axhline(3.0, color="tab:green", ls="--", lw=0.8, label="design target: 90th percentile peak / F0 3")
    axes[1].set_yticks([1.0, 2.0, 3.0, 5.0, 10.0], ["1", "2", "3", "5", "10"])
    axes[1].yaxis.set_minor_formatter("")
    figure_legend(fig)
    mine = on_common_set(strategy, "stage_b_ratio")
    mass = on_common_set(strategy, "mass_kg")
    sc = None
    for ax, other, label in ((axes[2], f"{strategy} (oracle)", f"R_B, {strategy} with the true M1, V0"),
                             (axes[3], reference, "R_B of the achievable reference")):
        theirs = on_common_set(other, "stage_b_ratio")
        sc = ax.scatter(theirs, mine, c=mass, cmap="viridis", s=16)
        finite = np.concatenate([mine[np.isfinite(mine)], theirs[np.isfinite(theirs)]])
        top = float(finite.max()) * 1.05 if finite.size else 2.0
        line = np.array([0.9, top])
        ax.plot(line, line, "k--", lw=0.8)
        band = targets["oracle_deviation"] if other.endswith("(oracle)") else targets["achievable"] - 1.0
        ax.fill_between(line, (1.0 - band) * line, (1.0 + band) * line, color="tab:gray", alpha=0.2, lw=0)
        ax.set(xlabel=label, ylabel=f"R_B, {strategy} (identified)", xlim=(0.9, top), ylim=(0.9, top))
        ax.grid(alpha=0.3)
    late = on_common_set(reference, "achievable_from_start_force_ratio")
    if np.isfinite(late).any():  # the best program that acts only from the loop's control start
        axes[3].scatter(late, mine, s=22, facecolors="none", edgecolors="k", lw=0.6,
                        label="reference acting from the control start")
        axes[3].legend(loc="upper left", fontsize=7, title="filled: from first contact", title_fontsize=7)
    if sc is not None:
        fig.colorbar(sc, ax=axes[3], label="M1 [kg]")
    fig.suptitle("Adaptive absorption: R_B = CFC 60 peak over [first sustained contact, deepest point] / "
                 "max(F_ref, F_floor), and the whole event")
    return fig


def plot_valve_design(rows: Sequence[Row], *, areas: Sequence[float], times: Sequence[float],
                      grids: dict[str, np.ndarray], kept: int):
    """Maps over valve size × response time: median and 90th-percentile R_B (on the common set of impacts) and the
    number of bottomed-out runs (the last map only where a run bottomed out; otherwise the title says that none
    did). Each cell's number is written in black or white, whichever stands out from the cell's colour.

    ``areas`` [mm²] and ``times`` [ms]: the axes; ``grids``: ``median``, ``p90`` and ``bottomed``, each
    (times × areas); ``kept``: the impacts of the common set. The study computes them (``studies.valve_design``)."""
    plt = _pyplot()
    maps = [("median", "median R_B"), ("p90", "90th percentile R_B")]
    bottomed = int(np.nansum(grids["bottomed"]))
    if bottomed:
        maps.append(("bottomed", "runs bottomed out"))
    fig, axes = plt.subplots(1, len(maps), figsize=(5.0 * len(maps), 4.4), squeeze=False, constrained_layout=True)
    for ax, (key, title) in zip(axes[0], maps, strict=True):
        annotated_map(ax, grids[key], [f"{a:g}" for a in areas], [f"{t:g}" for t in times], count=key == "bottomed")
        ax.set(xlabel="effective area of the open valve [mm²]", ylabel="response time 10-90 % [ms]", title=title)
    none = "" if bottomed else f"; none of the {len(rows)} runs bottomed out (no map of them)"
    fig.suptitle(f"Valve design: R_B of the predictive absorber over valve size and speed, on the {kept} "
                 f"impacts every valve has it for\n(ISO 6358 valves, C ≈ S/5 dm³/(s·bar)){none}")
    return fig


def annotated_map(ax, grid: np.ndarray, xticks: Sequence[str], yticks: Sequence[str], *, count: bool = False,
                  digits: int = 2, cmap: str = "viridis_r", vmin: float | None = None, vmax: float | None = None):
    """A map of ``grid`` (rows: y) with each finite cell's value written on it in black or white, whichever stands
    out from the cell's colour (:func:`text_colour`), and its colour bar. ``count``: a map of counts, white at zero
    (a map of zeros is good news, not a colour of alarm)."""
    limits = {"vmin": 0.0, "vmax": max(1.0, float(np.nanmax(grid)))} if count else {"vmin": vmin, "vmax": vmax}
    image = ax.imshow(grid, origin="lower", aspect="auto", cmap="Reds" if count else cmap, **limits)
    for i in range(grid.shape[0]):
        for j in range(grid.shape[1]):
            if np.isfinite(grid[i, j]):
                ax.text(j, i, f"{grid[i, j]:.0f}" if count else f"{grid[i, j]:.{digits}f}", ha="center",
                        va="center", fontsize=8, color=text_colour(image.cmap(image.norm(grid[i, j]))))
    ax.set_xticks(range(grid.shape[1]), list(xticks))
    ax.set_yticks(range(grid.shape[0]), list(yticks))
    ax.figure.colorbar(image, ax=ax)
    return image


def plot_absorber_design(rows: Sequence[Row], *, designs: Sequence[Row], early: float, targets: dict[str, float]):
    """The absorber designs: every design on the plane whole-event p90 peak / F0 × p90 R_B (marker: fixed charge or
    charge per impact class; colour: piston mass; the Pareto front joined, the target box shaded), the front's
    designs against their p90 first pulse / F0 (the bound their pad and piston set), and a map over pad ×
    pre-charge of the lowest whole-event p90 of the fixed-charge designs (the best of the other axes per cell).

    ``designs``: one row per design (``studies.absorber_design.designs``); ``early``: what counts as an early
    answer [s]; ``targets``: ``whole_event_p90`` and ``stage_b_p90``."""
    plt = _pyplot()
    table = list(designs)
    fig, axes = plt.subplots(1, 3, figsize=(19, 5.2), constrained_layout=True)
    pistons = np.array([d["piston [kg]"] for d in table], float)
    norm = plt.Normalize(vmin=float(np.nanmin(pistons)), vmax=max(float(np.nanmax(pistons)),
                                                                  float(np.nanmin(pistons)) + 1e-9))
    for charge, marker, text in (("fixed", "o", "fixed charge"), ("per class", "^", "charge per impact class")):
        chosen = [d for d in table if str(d.get("charge", "fixed")).startswith(charge)]
        if chosen:
            axes[0].scatter([d["p90 peak / F0"] for d in chosen], [d["p90 R_B"] for d in chosen],
                                 c=[d["piston [kg]"] for d in chosen], cmap="viridis", norm=norm, marker=marker,
                                 s=30, edgecolors="k", linewidths=0.4, label=text)
    front = sorted((d for d in table if d["Pareto"]), key=lambda d: d["p90 peak / F0"])
    axes[0].plot([d["p90 peak / F0"] for d in front], [d["p90 R_B"] for d in front], "k--", lw=0.8,
                 label="Pareto front (no run bottomed out)")
    axes[0].fill_between([0.9, targets["whole_event_p90"]], 0.9, targets["stage_b_p90"], color="tab:green",
                         alpha=0.12, label=f"targets: p90 peak / F0 <= {targets['whole_event_p90']:g} and "
                                           f"p90 R_B <= {targets['stage_b_p90']:g}")
    axes[0].set(xlabel="whole-event p90 of the CFC 60 peak / F0 [-]", ylabel="p90 R_B [-]", xscale="log",
                title="designs with a common window for every impact")
    axes[0].set_xticks([1.0, 2.0, 3.0, 5.0, 10.0], ["1", "2", "3", "5", "10"])
    axes[0].xaxis.set_minor_formatter("")
    axes[0].grid(alpha=0.3, which="both")
    fig.colorbar(plt.cm.ScalarMappable(norm=norm, cmap="viridis"), ax=axes[0], label="piston mass [kg]")
    positions = np.arange(len(front))
    axes[1].barh(positions, [d["p90 peak / F0"] for d in front], color="tab:blue", alpha=0.6,
                 label="whole-event p90 peak / F0")
    axes[1].plot([d["p90 first pulse / F0"] for d in front], positions, "k|", ms=12,
                 label="p90 first pulse / F0 (unfiltered)")
    axes[1].axvline(targets["whole_event_p90"], color="tab:green", lw=1.0)
    axes[1].set_yticks(positions, [f"{d['design']}\nR_B {d['p90 R_B']:.2f}, {d['early answers'] * 100:.0f} % "
                                   f"within {early * 1e3:g} ms" for d in front], fontsize=6)
    axes[1].invert_yaxis()
    axes[1].set(xlabel="p90 / F0 [-]", title="the front: whole event and its first collision")
    pads = list(dict.fromkeys(f"{d['pad']} {d['pad [N/m]']:.2g}" for d in table if d.get("charge") == "fixed"))
    pressures = sorted({d["p0 [kPa]"] for d in table if d.get("charge") == "fixed"})
    grid = np.full((len(pressures), len(pads)), np.nan)
    for d in table:
        if d.get("charge") == "fixed" and np.isfinite(d["p90 peak / F0"]):
            i, j = pressures.index(d["p0 [kPa]"]), pads.index(f"{d['pad']} {d['pad [N/m]']:.2g}")
            grid[i, j] = np.fmin(grid[i, j], d["p90 peak / F0"])
    annotated_map(axes[2], grid, pads, [f"{p:g}" for p in pressures], cmap="viridis_r")
    axes[2].set(xlabel="pad (law, stiffness at 10 mm [N/m])", ylabel="pre-charge p0 [kPa]",
                title="whole-event p90 peak / F0 (lowest over valve and piston)")
    axes[2].tick_params(axis="x", labelrotation=60, labelsize=7)
    figure_legend(fig)
    fig.suptitle(f"Absorber design: {len(table)} designs, {len({r['impact'] for r in rows})} impacts each")
    return fig


def text_colour(rgba) -> str:
    """Black or white, whichever contrasts more with the colour ``rgba`` (WCAG relative luminance: black above
    0.179, where both contrasts are equal)."""
    linear = [c / 12.92 if c <= 0.04045 else ((c + 0.055) / 1.055) ** 2.4 for c in rgba[:3]]
    luminance = 0.2126 * linear[0] + 0.7152 * linear[1] + 0.0722 * linear[2]
    return "k" if luminance > 0.179 else "w"
