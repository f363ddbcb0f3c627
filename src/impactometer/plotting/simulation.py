"""Figure of a simulated drop test: forces, motions and chamber pressures vs time."""

from __future__ import annotations

import numpy as np

from . import ACCELERATION_LABEL, _pyplot, legend_outside, shade_pulses


def plot_simulation(result, axes=None, *, pulses=None):
    """Contact force, piston acceleration, displacements and chamber pressures vs time, pulses shaded.

    Returns the figure.
    """
    plt = _pyplot()
    if axes is None:
        fig, axes = plt.subplots(4, 1, figsize=(9, 10), sharex=True, constrained_layout=True)
    else:
        axes = np.atleast_1d(axes)
        fig = axes[0].figure
    t = result.time * 1e3
    s = result.scenario
    axes[0].plot(t, result.contact_force / 1e3, color="k", lw=1)
    axes[0].set_ylabel("contact force [kN]")
    axes[0].set_title(f"M1 = {s.mass:g} kg, V0 = {s.velocity:.3f} m/s, p0 = {s.pressure_gauge / 1e3:g} kPa "
                      f"({result.rig.contact.law})")
    acceleration = result.a2
    axes[1].plot(t, acceleration, color="tab:red", lw=1)
    axes[1].set_ylabel(ACCELERATION_LABEL)
    _scale_without_stops(axes[1], t, acceleration, (result.top_stop_force > 0) | (result.bottom_stop_force > 0))
    axes[2].plot(t, result.u1 * 1e3, label="mass u1")
    axes[2].plot(t, result.u2 * 1e3, label="piston u2", ls="--")
    axes[2].set_ylabel("displacement [mm]")
    legend_outside(axes[2])
    axes[3].plot(t, result.pressure_lower / 1e3, label="lower chamber")
    axes[3].plot(t, result.pressure_upper / 1e3, label="upper chamber")
    axes[3].set_ylabel("pressure [kPa abs]")
    axes[3].set_xlabel("time after first contact [ms]")
    legend_outside(axes[3])
    for ax in axes:
        ax.set_xlim(t[0], t[-1])
        ax.grid(alpha=0.3)
        shade_pulses(ax, pulses)
    if pulses:
        legend_outside(axes[0])
    return fig


def _scale_without_stops(ax, t, values, on_stop) -> None:
    """Y limits of ``values`` off the stops: a stop's spike is marked, not allowed to flatten the rest."""
    free = ~np.asarray(on_stop)
    if free.all() or not free.any():
        return
    low, high = float(values[free].min()), float(values[free].max())
    pad = 0.1 * (high - low or 1.0)
    ax.set_ylim(low - pad, high + pad)
    k = int(np.argmax(np.abs(values)))
    if not low - pad <= values[k] <= high + pad:
        ax.annotate(f"stop: {values[k]:.4g} (off scale)", xy=(t[k], high + pad if values[k] > 0 else low - pad),
                    xytext=(-4, -12 if values[k] > 0 else 4), textcoords="offset points", ha="right", fontsize=8)
