"""Figures of recordings (``impactometer inspect --plot``). matplotlib is imported lazily."""

from __future__ import annotations

import numpy as np

from ..identify.inspection import inspect_recording
from ..recording import ACCELERATION, FORCE
from . import _pyplot, legend_outside, shade_pulses


def plot_recording(recording, axes=None, *, inspection=None):
    """Contact force and piston acceleration vs time (ms), contact pulses shaded and their peaks marked.

    Parameters
    ----------
    recording : Recording
    axes : sequence of two matplotlib Axes, optional
    inspection : Inspection, optional
        Result of :func:`impactometer.identify.inspection.inspect_recording` (computed when not given).

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
    if inspection is None:
        inspection = inspect_recording(recording)
    t = recording.time * 1e3
    colors = {FORCE: "k", ACCELERATION: "tab:red"}
    # the two sensor channels are SI inside; drawn as every figure draws them
    labels = {FORCE: ("contact force [kN]", 1e-3), ACCELERATION: ("piston acceleration [km/s²]", 1e-3)}
    for ax, name in zip(axes, names, strict=False):
        unit = recording.unit(name)
        label, scale = labels.get(name, (f"{name.replace('_', ' ')} [{unit}]" if unit else name, 1.0))
        ax.plot(t, recording.channel(name) * scale, color=colors.get(name, "tab:blue"), lw=0.8)
        ax.set_ylabel(label)
        ax.set_xlim(t[0], t[-1])
        ax.grid(alpha=0.3)
        shade_pulses(ax, inspection.pulses)
    if FORCE in names and inspection.pulses:
        ax = axes[names.index(FORCE)]
        ax.plot([p.peak_time * 1e3 for p in inspection.pulses],
                [(p.peak_force + inspection.force_offset) * 1e-3 for p in inspection.pulses], "v", color="tab:blue",
                label="pulse peaks")
        legend_outside(ax)
    axes[-1].set_xlabel("time [ms]")
    axes[0].set_title(f"{recording.source}: {inspection.samples} samples at {recording.sample_rate:g} Hz")
    return fig
