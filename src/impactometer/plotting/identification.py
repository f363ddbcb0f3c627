"""Figure of an identification (matplotlib imported lazily)."""

from __future__ import annotations

import math

import numpy as np

from . import ACCELERATION_LABEL, _pyplot, legend_outside


def plot_identification(result, recording=None, ax=None, *, used=None):
    """Figure of an :class:`~impactometer.identify.result.Identification`; returns the figure.

    Parameters
    ----------
    result : Identification
        The answer.
    recording : Recording, optional
        With it: contact force [kN] and piston acceleration [m/s²] vs time [ms], with what the answer used marked:
        t00 (first contact, the origin of the integrals) and, for the paper variant, the force peaks t01 and t11;
        for the robust variant the samples its equations read when ``used`` gives them: onsets, turning points of
        the force in stage A and in stage B, separations, the stage-B span, or the pulses of a contact-phase fit.
        Without it: mass [kg] and velocity [m/s] of the early and the final answer, with their standard errors,
        vs the time they were available [ms].
    ax : Axes or pair of Axes, optional
        Where to draw (one Axes: a twin is added for the second quantity).
    used : dict of arrays, optional
        Times [s] of what a robust answer's equations read in ``recording``
        (:func:`impactometer.identify.peak_to_peak.used_samples`), marked on the force.
    """
    plt = _pyplot()
    if ax is None:
        fig, axes = plt.subplots(2, 1, figsize=(10, 6.5), sharex=True, constrained_layout=True)
    else:
        axes = list(ax) if hasattr(ax, "__len__") else [ax, ax.twinx()]
        fig = axes[0].figure
    if recording is None:
        _answers(axes, result)
    else:
        _signals(axes, result, recording, used)
    legend_outside(axes[0])
    name = result.method if recording is None else result.variant
    axes[0].set_title(f"{name}: M1 = {result.mass:.3g} kg, V0 = {result.velocity:.4g} m/s "
                      f"(available at {result.available_at * 1e3:.2f} ms)")
    return fig


def _signals(axes, result, recording, rows) -> None:
    t = recording.time * 1e3
    force = recording.contact_force
    axes[0].plot(t, force / 1e3, color="k", lw=0.8)
    axes[0].set_ylabel("contact force [kN]")
    axes[1].plot(t, recording.piston_acceleration, color="tab:red", lw=0.8)
    axes[1].set_ylabel(ACCELERATION_LABEL)
    axes[1].set_xlabel("time [ms]")
    instants = [("t00: first contact", result.t00, "tab:green")]
    if result.variant == "paper":  # the instants eqs. (3)-(5) read
        instants += [("t01: first force peak", result.t01, "tab:blue"),
                     ("t11: second force peak", result.t11, "tab:purple")]
    for name, when, color in instants:
        if math.isfinite(when):
            for a in axes:
                a.axvline(when * 1e3, color=color, ls="--", lw=1, label=name if a is axes[0] else None)
    if rows is not None:
        _mark_rows(axes, rows, recording, result.details["equations"])


def _mark_rows(axes, rows, recording, used) -> None:
    """The samples a robust answer's equations read, on the force (and the stage-B span on both panels)."""
    def on_force(when):
        return when * 1e3, np.interp(when, recording.time, recording.contact_force) / 1e3

    b = rows["turning_b"]
    if b.size:
        for a in axes:
            a.axvspan(b[0] * 1e3, b[-1] * 1e3, color="tab:orange", alpha=0.1, lw=0,
                      label=f"stage B rows: {b.size} turning points over {used.get('stage_b_samples', 0)} samples"
                      if a is axes[0] else None)
    for k, (lo, hi) in enumerate(rows["contact_phase"]):
        axes[0].axvspan(lo * 1e3, hi * 1e3, color="tab:cyan", alpha=0.15, lw=0,
                        label=f"contact-phase fit: {used['contact_phase'].get('samples', 0)} samples "
                              f"({used['contact_phase'].get('branches')})" if k == 0 else None)
    found = rows["onsets_found"]
    kept = rows["onsets"]
    if found.size and not kept.size:
        axes[0].plot(*on_force(found), "o", mfc="none", color="0.4", ms=7,
                     label=f"onsets found, {used.get('onsets', 0)} of {found.size} used")
    for key, marker, colour, label in (("onsets", "o", "tab:green", "onsets used"),
                                       ("turning_a", "^", "tab:blue", "turning points used, stage A"),
                                       ("turning_b", "v", "tab:orange", "turning points used, stage B"),
                                       ("separations", "s", "tab:purple", "separations used")):
        if rows[key].size:
            axes[0].plot(*on_force(rows[key]), marker, color=colour, ms=6, mec="k", mew=0.5,
                         label=f"{label} ({rows[key].size})")


def _answers(axes, result) -> None:
    answers = [("early", result.early, "tab:orange"), ("final", result, "k")]
    for label, found, color in answers:
        if found is None:
            continue
        at = found.available_at * 1e3
        for a, value, std in ((axes[0], found.mass, found.mass_std), (axes[1], found.velocity, found.velocity_std)):
            a.errorbar([at], [value], yerr=[std] if math.isfinite(std) else None, fmt="o", color=color, capsize=3,
                       label=label if a is axes[0] else None)
    axes[0].set_ylabel("mass M1 [kg]")
    axes[1].set_ylabel("velocity V0 [m/s]")
    axes[1].set_xlabel("available at [ms]")
