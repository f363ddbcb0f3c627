"""Figure of an identification (matplotlib imported lazily)."""

from __future__ import annotations

import math

from . import _pyplot, legend_outside


def plot_identification(result, recording=None, ax=None):
    """Figure of an :class:`~impactometer.identify.result.Identification`; returns the figure.

    Parameters
    ----------
    result : Identification
        The answer.
    recording : Recording, optional
        With it: contact force [kN] and piston acceleration [km/s²] vs time [ms], with the instants the answer used
        (peak-to-peak: t00, t01, t11 and the onsets) marked. Without it: mass [kg] and
        velocity [m/s] of the early and the final answer, with their standard errors, vs the time they were
        available [ms].
    ax : Axes or pair of Axes, optional
        Where to draw (one Axes: a twin is added for the second quantity).
    """
    plt = _pyplot()
    if ax is None:
        fig, axes = plt.subplots(2, 1, figsize=(9, 6), sharex=True, constrained_layout=True)
    else:
        axes = list(ax) if hasattr(ax, "__len__") else [ax, ax.twinx()]
        fig = axes[0].figure
    if recording is None:
        _answers(axes, result)
    else:
        _signals(axes, result, recording)
    legend_outside(axes[0])
    name = result.method if recording is None else result.variant
    axes[0].set_title(f"{name}: M1 = {result.mass:.3g} kg, V0 = {result.velocity:.4g} m/s "
                      f"(available at {result.available_at * 1e3:.2f} ms)")
    return fig


def _signals(axes, result, recording) -> None:
    t = recording.time * 1e3
    axes[0].plot(t, recording.contact_force / 1e3, color="k", lw=0.8)
    axes[0].set_ylabel("contact force [kN]")
    axes[1].plot(t, recording.piston_acceleration / 1e3, color="tab:red", lw=0.8)
    axes[1].set_ylabel("piston acceleration [km/s²]")
    axes[1].set_xlabel("time [ms]")
    for name, when, color in (("t00", result.t00, "tab:green"), ("t01", result.t01, "tab:blue"),
                              ("t11", result.t11, "tab:purple")):
        if math.isfinite(when):  # the peak-to-peak instants; other methods have none
            for a in axes:
                a.axvline(when * 1e3, color=color, ls="--", lw=1, label=name if a is axes[0] else None)
    for k, onset in enumerate(result.onsets):
        axes[0].axvline(onset * 1e3, color="tab:orange", lw=0.6, alpha=0.7, label="onsets" if k == 0 else None)


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
