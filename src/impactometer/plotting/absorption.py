"""Figures of the absorber: force histories of the strategies (the paper's Fig. 10b) and metric distributions.

matplotlib is imported lazily, inside the functions.
"""

from __future__ import annotations

import math

import numpy as np

from ..filters import cfc_filter
from . import _pyplot, legend_outside

#: line colour per strategy (and per oracle run)
COLOURS = {"closed": "tab:gray", "constant": "tab:blue", "realtime": "tab:red", "predictive": "tab:purple",
           "auto": "tab:purple", "realtime (oracle)": "tab:orange", "predictive (oracle)": "tab:pink"}


def plot_absorption(result, ax=None):
    """The paper's Fig. 10b: contact force of every strategy vs time (thin: as simulated; thick: CFC 60, the load
    the stage-B force ratio is judged on), the control start, stage B and the reference force F_ref; the mass
    displacement below.

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
    deepest = 0.0
    for name, run in result.runs.items():
        r = run.result
        colour = COLOURS.get(name)
        body = cfc_filter(r.contact_force, r.sample_rate, 60)
        axes[0].plot(r.time * 1e3, r.contact_force / 1e3, lw=0.4, color=colour, alpha=0.5)
        axes[0].plot(r.time * 1e3, body / 1e3, lw=1.6, color=colour,
                     label=f"{name}: R = {run.metrics.stage_b_force_ratio:.2f}")
        if len(axes) > 1:
            axes[1].plot(r.time * 1e3, r.u1 * 1e3, lw=0.9, color=colour, label=name)
        deepest = max(deepest, float(r.time[np.argmax(r.u1)]))
    start = result.control_start
    for a in axes:
        if math.isfinite(start):
            a.axvline(start * 1e3, color="k", ls=":", lw=1, label="control starts")
        a.grid(alpha=0.3)
    judged = [run.metrics for run in result.runs.values() if math.isfinite(run.metrics.reference_force)]
    if judged:
        m = judged[-1]
        axes[0].axhline(m.reference_force / 1e3, color="tab:green", ls="--", lw=1,
                        label=f"F_ref = {m.reference_force:.0f} N ({list(result.runs)[-1]})")
        axes[0].set_ylim(0.0, 4.0 * max(m.reference_force, max(j.stage_b_peak_force for j in judged) / 3.0) / 1e3)
    axes[0].set_xlim(0.0, 1.1 * deepest * 1e3 if deepest > 0.0 else None)
    axes[0].set_ylabel("contact force [kN]")
    ident = result.identified
    how = "oracle" if ident.method == "oracle" else f"identified ({result.identification}): " \
                                                      f"M1 = {ident.mass:.3g} kg, V0 = {ident.velocity:.3g} m/s"
    axes[0].set_title(f"{result.rig.name}: M1 = {s.mass:g} kg, V0 = {s.velocity:.2f} m/s, "
                      f"p0 = {s.pressure_gauge / 1e3:g} kPa\n{how}", fontsize=10)
    legend_outside(axes[0])
    if len(axes) > 1:
        usable = result.absorber.usable_stroke(result.rig)
        axes[1].axhline(usable * 1e3, color="k", ls="--", lw=1, label="usable stroke")
        axes[1].set_ylabel("mass displacement [mm]")
        legend_outside(axes[1])
    axes[-1].set_xlabel("time after first contact [ms]")
    return fig
