"""Figures of the absorber: force histories of the strategies (the paper's Fig. 10b) and metric distributions.

matplotlib is imported lazily, inside the functions.
"""

from __future__ import annotations

import math

import numpy as np

from ..control.metrics import BODY_CFC
from ..filters import cfc_filter
from . import _pyplot, legend_outside

#: line colour per strategy (and per oracle run)
COLOURS = {"closed": "tab:gray", "constant": "tab:blue", "realtime": "tab:red", "predictive": "tab:purple",
           "auto": "tab:purple", "realtime (oracle)": "tab:orange", "predictive (oracle)": "tab:pink"}
#: the zoomed panel shows at least the first ZOOM [s] after first contact (the collision the identification reads)
ZOOM = 0.02
#: line widths: the force as simulated, and the CFC-filtered body load
THIN, THICK = 0.4, 1.6


def plot_absorption(result, ax=None):
    """The paper's Fig. 10b: contact force of every strategy vs time (thin: as simulated; thick: CFC 60, the load
    the stage-B force ratio R is judged on), the control start and the reference force F_ref; the first
    milliseconds zoomed (the collision the identification reads); the displacements of the mass (solid) and of
    the piston (dashed) against the usable stroke and the bottom stop below. No force is clipped.

    Parameters
    ----------
    result : AbsorptionResult
    ax : Axes or sequence of Axes, optional
        One Axes: the force history; two: with the displacements; three: the zoom, the force history and the
        displacements.

    Returns the figure.
    """
    plt = _pyplot()
    if ax is None:
        fig, axes = plt.subplots(3, 1, figsize=(11, 10), constrained_layout=True,
                                 gridspec_kw={"height_ratios": [1.3, 2, 1.3]})
        axes[2].sharex(axes[1])
    else:
        axes = np.atleast_1d(ax)
        fig = axes[0].figure
    zoom, force, motion = (axes[0], axes[1], axes[2]) if len(axes) >= 3 else (None, axes[0],
                                                                             axes[1] if len(axes) > 1 else None)
    start = result.control_start
    window = max(ZOOM, 1.25 * start) if math.isfinite(start) else ZOOM
    deepest = 0.0
    for name, run in result.runs.items():
        r = run.result
        colour = COLOURS.get(name)
        body = cfc_filter(r.contact_force, r.sample_rate, BODY_CFC)
        t = r.time * 1e3
        force.plot(t, r.contact_force / 1e3, lw=THIN, color=colour, alpha=0.5)
        force.plot(t, body / 1e3, lw=THICK, color=colour, label=f"{name}: R = {run.metrics.stage_b_force_ratio:.2f}")
        if zoom is not None:
            early = r.time <= window
            zoom.plot(t[early], r.contact_force[early] / 1e3, lw=THIN * 2, color=colour, alpha=0.6)
            zoom.plot(t[early], body[early] / 1e3, lw=THICK, color=colour)
        if motion is not None:
            motion.plot(t, r.u1 * 1e3, lw=1.1, color=colour)
            motion.plot(t, r.u2 * 1e3, lw=0.9, ls="--", color=colour)
        deepest = max(deepest, float(r.time[np.argmax(r.u1)]))
    for a in axes:
        if math.isfinite(start):
            a.axvline(start * 1e3, color="k", ls=":", lw=1, label="control starts" if a is force else None)
        a.grid(alpha=0.3)
    judged = [run.metrics for run in result.runs.values() if math.isfinite(run.metrics.reference_force)]
    if judged:
        m = judged[-1]
        force.axhline(m.reference_force / 1e3, color="tab:green", ls="--", lw=1,
                      label=f"F_ref = {m.reference_force:.0f} N ({list(result.runs)[-1]})")
    force.set_xlim(0.0, 1.1 * deepest * 1e3 if deepest > 0.0 else None)
    force.set_ylabel("contact force [kN]")
    ident = result.identified
    s = result.scenario
    how = "oracle" if ident.method == "oracle" else f"identified ({result.identification}): " \
                                                    f"M1 = {ident.mass:.3g} kg, V0 = {ident.velocity:.3g} m/s"
    fig.suptitle(f"{result.rig.name}: M1 = {s.mass:g} kg, V0 = {s.velocity:.2f} m/s, "
                 f"p0 = {s.pressure_gauge / 1e3:g} kPa\n{how}", fontsize=10)
    _style_keys(force, "thin: as simulated", f"thick: CFC {BODY_CFC} (R is judged on it)", (THIN, THICK),
                ("-", "-"))
    legend_outside(force)
    if zoom is not None:
        zoom.set_xlim(0.0, window * 1e3)
        zoom.set_ylabel("contact force [kN]")
        zoom.set_title(f"first {window * 1e3:.0f} ms: the collision the identification reads (the valve is closed "
                       "until the control starts)", fontsize=9)
        zoom.set_xlabel("time after first contact [ms]")
    if motion is not None:
        _displacements(motion, result)
    (motion if motion is not None else force).set_xlabel("time after first contact [ms]")
    return fig


def _displacements(ax, result) -> None:
    """The usable stroke and the bottom stop on the displacement panel, how deep the deepest run went, and the
    legend: which line is which body.

    The controller holds the piston (its rod transducer) to the usable stroke; the mass goes further by the pad's
    compression, and the run bottoms out only where the piston reaches the bottom stop.
    """
    usable = result.absorber.usable_stroke(result.rig)
    stroke = result.rig.cylinder.stroke
    ax.axhline(usable * 1e3, color="k", ls="--", lw=1, label=f"usable stroke {usable * 1e3:.0f} mm: the "
                                                             "controller's limit on the piston")
    ax.axhline(stroke * 1e3, color="tab:red", lw=1, label=f"bottom stop {stroke * 1e3:.0f} mm (piston)")
    _style_keys(ax, "solid: mass u1", "dashed: piston u2 (u1 − u2: pad compression)", (1.1, 0.9), ("-", "--"))
    name, run = max(result.runs.items(), key=lambda item: float(np.max(item[1].result.u1)))
    ax.plot([], [], ls="none", label=f"deepest ({name}): mass {np.max(run.result.u1) * 1e3:.1f} mm, "
                                     f"piston {np.max(run.result.u2) * 1e3:.1f} mm")
    ax.set_ylabel("displacement (down) [mm]")
    legend_outside(ax)


def _style_keys(ax, first: str, second: str, widths, styles) -> None:
    """Two grey legend entries saying what two line styles mean (drawn with no data)."""
    for label, width, style in zip((first, second), widths, styles, strict=True):
        ax.plot([], [], color="0.3", lw=width, ls=style, label=label)
