"""Figures of recordings (``impactometer inspect --plot``). matplotlib is imported lazily."""

from __future__ import annotations

import numpy as np

from ..recording import ACCELERATION, FORCE
from . import ACCELERATION_LABEL, _pyplot, legend_outside, shade_pulses


def plot_recording(recording, inspection, axes=None):
    """Contact force and piston acceleration vs time (ms), contact pulses shaded and their peaks marked
    (``Inspection.plot``).

    Parameters
    ----------
    recording : Recording
    inspection : Inspection
        What :func:`impactometer.identify.inspection.inspect_recording` found in ``recording``: its pulses.
    axes : sequence of two matplotlib Axes, optional

    Returns
    -------
    matplotlib.figure.Figure
    """

    plt = _pyplot()
    names = [name for name in (FORCE, ACCELERATION) if name in recording.channels] or list(recording.channels)[:2]
    if axes is None:
        fig, axes = plt.subplots(len(names), 1, figsize=(9, 3.2 * len(names) + 0.5), sharex=True,
                                 constrained_layout=True, squeeze=False)
        axes = axes[:, 0]
    else:
        axes = np.atleast_1d(axes)
        fig = axes[0].figure
    t = recording.time * 1e3
    colors = {FORCE: "k", ACCELERATION: "tab:red"}
    # the two sensor channels are SI inside; drawn as every figure draws them
    labels = {FORCE: ("contact force [kN]", 1e-3), ACCELERATION: (ACCELERATION_LABEL, 1.0)}
    filtered = recording.metadata.get("cfc")
    filtered = filtered if isinstance(filtered, dict) else {}  # CFC class per channel (filters.filter_recording)
    for ax, name in zip(axes, names, strict=False):
        unit = recording.unit(name)
        label, scale = labels.get(name, (f"{name.replace('_', ' ')} [{unit}]" if unit else name, 1.0))
        cfc = f", CFC {filtered[name]} filtered" if name in filtered else ""
        ax.plot(t, recording.channel(name) * scale, color=colors.get(name, "tab:blue"), lw=0.8,
                label=f"{name.replace('_', ' ')}{cfc}" if cfc else None)
        ax.set_ylabel(label)
        ax.set_xlim(t[0], t[-1])
        ax.grid(alpha=0.3)
        shade_pulses(ax, inspection.pulses)
    if FORCE in names and inspection.pulses:
        axes[names.index(FORCE)].plot([p.peak_time * 1e3 for p in inspection.pulses],
                                      [(p.peak_force + inspection.force_offset) * 1e-3 for p in inspection.pulses],
                                      "v", color="tab:blue", label="pulse peaks")
    for ax, name in zip(axes, names, strict=False):
        if (name == FORCE or name in filtered) and ax.get_legend_handles_labels()[0]:
            legend_outside(ax)
    axes[-1].set_xlabel("time [ms]")
    classes = {}  # CFC class -> the channels filtered with it
    for name in names:
        if name in filtered:
            classes.setdefault(filtered[name], []).append(name.replace("_", " "))
    shown = "; ".join(f"CFC {cfc} filtered ({', '.join(drawn)})" for cfc, drawn in classes.items())
    axes[0].set_title(f"{recording.source}: {inspection.samples} samples at {recording.sample_rate:g} Hz\n"
                      f"{shown or 'no CFC filter applied'}", fontsize=10)
    return fig
