"""Figures of the absorber: force histories of the strategies (the paper's Fig. 10b) and metric distributions.

matplotlib is imported lazily, inside the functions.
"""

from __future__ import annotations

import math

import numpy as np

from . import _pyplot, legend_outside

#: line colour per strategy (and per oracle run)
COLOURS = {"closed": "tab:gray", "constant": "tab:blue", "realtime": "tab:red", "predictive": "tab:purple",
           "auto": "tab:purple", "realtime (oracle)": "tab:orange", "predictive (oracle)": "tab:pink"}
#: the zoomed panel shows at least the first ZOOM [s] after first contact (the collision the identification reads)
ZOOM = 0.02
#: the time axis stops at this multiple of the runs' median time to their deepest point when one run takes longer
LONG_RUN = 2.5
#: line widths: the force as simulated, and the CFC-filtered body load
THIN, THICK = 0.4, 1.6


def plot_absorption(result, body_loads, body_cfc, ax=None):
    """The paper's Fig. 10b: contact force of every strategy vs time (thin: as simulated; thick: CFC 60, the load
    the metrics are judged on), the control start, the first sustained contact and the common window of R_B (shaded
    to the deepest point of the last run to reach it), F_ref, F_floor and F0; the first milliseconds zoomed (the
    collision the identification reads); the displacements of the mass (solid) and of the piston (dashed) against
    the usable stroke and the bottom stop below. No force is clipped.

    Parameters
    ----------
    result : AbsorptionResult
    body_loads : dict
        Strategy -> the CFC-filtered contact force of its run [N] (``control.event.body_load``).
    body_cfc : int
        The CFC class of that filter.
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
    # the legends share the entries out: the runs and the instants by the first panel, the forces and the line
    # styles by the force history, the bodies and the stroke by the displacements (each a handful, none repeated)
    key = zoom if zoom is not None else force
    start = result.control_start
    window = max(ZOOM, 1.25 * start) if math.isfinite(start) else ZOOM
    deepest_of = {}
    for name, run in result.runs.items():
        r = run.result
        colour = COLOURS.get(name)
        body = body_loads[name]
        t = r.time * 1e3
        force.plot(t, r.contact_force / 1e3, lw=THIN, color=colour, alpha=0.5)
        m = run.metrics
        label = f"{name}: R_B = {m.stage_b_ratio:.2f}, peak / F0 = {m.whole_event_peak_ratio:.2f}"
        force.plot(t, body / 1e3, lw=THICK, color=colour, label=label if key is force else None)
        if zoom is not None:
            early = r.time <= window
            zoom.plot(t[early], r.contact_force[early] / 1e3, lw=THIN * 2, color=colour, alpha=0.6)
            zoom.plot(t[early], body[early] / 1e3, lw=THICK, color=colour, label=label)
        if motion is not None:
            motion.plot(t, r.u1 * 1e3, lw=1.1, color=colour)
            motion.plot(t, r.u2 * 1e3, lw=0.9, ls="--", color=colour)
        deepest_of[name] = float(r.time[np.argmax(r.u1)])
    # the time axis ends after the deepest point of the last run, unless one run takes far longer than the others
    # (a small constant opening creeps for seconds): then at LONG_RUN × their median, the slow run named
    times = sorted(deepest_of.values())
    deepest = min(times[-1], LONG_RUN * float(np.median(times))) if times else 0.0
    common = result.window
    for a in axes:
        if math.isfinite(start):
            a.axvline(start * 1e3, color="k", ls=":", lw=1,
                      label=f"control starts ({start * 1e3:.1f} ms)" if a is key else None)
        if math.isfinite(common.start):
            a.axvline(common.start * 1e3, color="tab:green", ls="-.", lw=1,
                      label=f"first sustained contact ({common.start * 1e3:.1f} ms)" if a is key else None)
            a.axvspan(common.start * 1e3, deepest * 1e3, color="tab:green", alpha=0.06,
                      label="common window of R_B (to the deepest point)" if a is force else None)
        a.grid(alpha=0.3)
    if math.isfinite(common.start):
        force.axhline(common.reference_force / 1e3, color="tab:green", ls="--", lw=1,
                      label=f"F_ref = {common.reference_force:.0f} N (closed valve at the first sustained contact)")
        force.axhline(common.floor_force / 1e3, color="tab:brown", ls="--", lw=1,
                      label=f"F_floor = {common.floor_force:.0f} N (valve wide open, bodies together)")
    for name, at in deepest_of.items():
        if at > deepest:
            force.plot([], [], ls="none", label=f"{name}: deepest point at {at * 1e3:.0f} ms, beyond the axis")
    runs = list(result.runs.values())
    if runs:
        f0 = runs[0].metrics.impact_force
        force.axhline(f0 / 1e3, color="k", ls="--", lw=0.8, label=f"F0 = {f0:.0f} N (whole event, ideal)")
    force.set_xlim(0.0, 1.1 * deepest * 1e3 if deepest > 0.0 else None)
    force.set_ylabel("contact force [kN]")
    ident = result.identified
    s = result.scenario
    how = "oracle" if ident.method == "oracle" else f"identified ({result.identification}): " \
                                                    f"M1 = {ident.mass:.3g} kg, V0 = {ident.velocity:.3g} m/s"
    fig.suptitle(f"{result.rig.name}: M1 = {s.mass:g} kg, V0 = {s.velocity:.2f} m/s, "
                 f"p0 = {s.pressure_gauge / 1e3:g} kPa\n{how}", fontsize=10)
    _style_keys(force, "thin: as simulated", f"thick: CFC {body_cfc} (the metrics are judged on it)", (THIN, THICK),
                ("-", "-"))
    legend_outside(force)
    if zoom is not None:
        legend_outside(zoom)
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
