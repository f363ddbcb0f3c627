"""Figure of a peak-to-peak identification (matplotlib imported lazily)."""

from __future__ import annotations

from . import _pyplot, legend_outside


def plot_identification(recording, result, ax=None):
    """Force and piston acceleration vs time with t00, t01, t11 and the onsets used marked; returns the figure."""
    plt = _pyplot()
    if ax is None:
        fig, axes = plt.subplots(2, 1, figsize=(9, 6), sharex=True, constrained_layout=True)
    else:
        axes = list(ax) if hasattr(ax, "__len__") else [ax, ax.twinx()]
        fig = axes[0].figure
    t = recording.time * 1e3
    axes[0].plot(t, recording.contact_force / 1e3, color="k", lw=0.8)
    axes[0].set_ylabel("contact force [kN]")
    axes[1].plot(t, recording.piston_acceleration / 1e3, color="tab:red", lw=0.8)
    axes[1].set_ylabel("piston acceleration [km/s²]")
    axes[1].set_xlabel("time [ms]")
    for name, when, color in (("t00", result.t00, "tab:green"), ("t01", result.t01, "tab:blue"),
                              ("t11", result.t11, "tab:purple")):
        for a in axes:
            a.axvline(when * 1e3, color=color, ls="--", lw=1, label=name if a is axes[0] else None)
    for k, onset in enumerate(result.onsets):
        axes[0].axvline(onset * 1e3, color="tab:orange", lw=0.6, alpha=0.7, label="onsets" if k == 0 else None)
    legend_outside(axes[0])
    axes[0].set_title(f"{result.variant}: M1 = {result.mass:.3g} kg, V0 = {result.velocity:.4g} m/s "
                      f"(available at {result.available_at * 1e3:.2f} ms)")
    return fig
