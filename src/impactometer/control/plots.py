"""Figures of the absorber: force histories of the strategies (the paper's Fig. 10b) and metric distributions.

matplotlib is imported lazily, inside the functions.
"""

from __future__ import annotations

import math

import numpy as np

#: line colour per strategy (and per oracle run)
COLOURS = {"closed": "tab:gray", "constant": "tab:blue", "realtime": "tab:red", "realtime (oracle)": "tab:orange"}


def legend_outside(ax) -> None:
    from ..plotting import legend_outside as outside

    outside(ax)


def _pyplot():
    from ..plotting import _pyplot as pyplot

    return pyplot()


def plot_absorption(result, ax=None):
    """Contact force of every strategy vs time, the control start and the bound level; stroke below.

    Returns the figure.
    """
    plt = _pyplot()
    if ax is None:
        fig, axes = plt.subplots(2, 1, figsize=(9, 7), sharex=True, constrained_layout=True,
                                 gridspec_kw={"height_ratios": [2, 1]})
    else:
        axes = np.atleast_1d(ax)
        fig = axes[0].figure
    s = result.scenario
    for name, run in result.runs.items():
        r = run.result
        colour = COLOURS.get(name)
        axes[0].plot(r.time * 1e3, r.contact_force / 1e3, lw=0.9, color=colour, label=name)
        if len(axes) > 1:
            axes[1].plot(r.time * 1e3, r.u1 * 1e3, lw=0.9, color=colour, label=name)
    start = result.control_start
    for a in axes:
        if math.isfinite(start):
            a.axvline(start * 1e3, color="k", ls=":", lw=1, label="control starts")
        a.grid(alpha=0.3)
    if math.isfinite(result.bound.level):
        axes[0].axhline(result.bound.level / 1e3, color="tab:green", ls="--", lw=1,
                        label=f"bound level (η_max = {result.bound.efficiency:.2f})")
    axes[0].set_ylabel("contact force [kN]")
    ident = result.identified
    how = "oracle" if ident.method == "oracle" else f"identified ({ident.method}): M1 = {ident.mass:.1f} kg, " \
                                                      f"V0 = {ident.velocity:.2f} m/s"
    axes[0].set_title(f"M1 = {s.mass:g} kg, V0 = {s.velocity:.2f} m/s, p0 = {s.pressure_gauge / 1e3:g} kPa\n{how}",
                      fontsize=10)
    legend_outside(axes[0])
    if len(axes) > 1:
        usable = result.absorber.usable_stroke(result.rig)
        axes[1].axhline(usable * 1e3, color="k", ls="--", lw=1, label="usable stroke")
        axes[1].set_ylabel("mass displacement [mm]")
        legend_outside(axes[1])
    axes[-1].set_xlabel("time after first contact [ms]")
    return fig


def plot_distributions(rows, *, quantities=("efficiency", "peak_force_controlled_N", "stroke_used_m"), ax=None):
    """Box plots of metrics per strategy over many cases (rows of :func:`~impactometer.control.study.absorption_table`).

    The bound η_max is drawn next to the efficiencies. Returns the figure.
    """
    plt = _pyplot()
    if ax is None:
        fig, axes = plt.subplots(1, len(quantities), figsize=(4.2 * len(quantities), 4.5), constrained_layout=True)
    else:
        axes = ax
        fig = np.atleast_1d(axes)[0].figure
    axes = np.atleast_1d(axes)
    labels = list(dict.fromkeys(row["strategy"] for row in rows))
    for a, quantity in zip(axes, quantities, strict=False):
        data = [[row[quantity] for row in rows if row["strategy"] == name and _finite(row.get(quantity))]
                for name in labels]
        names = list(labels)
        if quantity == "efficiency":
            bound = {(row["mass_kg"], row["velocity_m_s"], row["pressure_gauge_Pa"]): row["efficiency_max"]
                     for row in rows if _finite(row.get("efficiency_max"))}
            data.append(list(bound.values()))
            names.append("bound η_max")
        a.boxplot([d if d else [np.nan] for d in data], showfliers=True)
        a.set_xticks(range(1, len(names) + 1), names, rotation=30, ha="right")
        a.set_title(quantity)
        a.grid(alpha=0.3, axis="y")
    return fig


def _finite(value) -> bool:
    return value is not None and not isinstance(value, bool) and math.isfinite(float(value))
