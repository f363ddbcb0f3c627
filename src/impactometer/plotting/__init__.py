"""Every figure of impactometer, one module per subject; matplotlib is imported once, lazily, by :func:`_pyplot`.

- :mod:`.simulation`: histories of a simulated drop test (``SimulationResult.plot``)
- :mod:`.recordings`: a recording with its pulses and stages (``impactometer inspect --plot``)
- :mod:`.identification`: the instants and equations an identification used (``Identification.plot``)
- :mod:`.absorption`: the absorber's force histories (the paper's Fig. 10b) and metrics
- :mod:`.studies`: the figures of the studies (the paper's Figs. 3-9 and beyond)

The computation never imports this package at module level: a result's ``.plot()`` imports the function it needs.
"""

from __future__ import annotations

import numpy as np


def _pyplot():
    import matplotlib

    if matplotlib.get_backend().lower() not in ("agg", "module://matplotlib_inline.backend_inline"):
        matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


#: the piston acceleration as every figure draws it: SI, m/s² (the tables print m/s² too)
ACCELERATION_LABEL = "piston acceleration [m/s²]"


def legend_outside(ax, **options) -> None:
    """Legend to the right of ``ax``, off the data."""
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0, fontsize=8, **options)


def labelled(label: str, *values) -> str | None:
    """``label`` when any of ``values`` holds a finite number, else None: a series without data stays out of the
    legend (:func:`figure_legend` names it with ``no_answer``)."""
    return label if any(np.isfinite(np.asarray(v, dtype=float)).any() for v in values) else None


def figure_legend(fig, *, no_answer=(), extra=None) -> None:
    """One legend for the whole (constrained-layout) figure, below its panels (off every panel's data and off the
    title): each label of every panel once, the ``extra`` entries (label -> handle: keys to a style), then one line
    ``NAME: no answer`` per name of ``no_answer`` (a series with no finite data, left out of the panels' legends)."""
    from matplotlib.lines import Line2D

    entries: dict[str, object] = {}
    for ax in fig.axes:
        for handle, label in zip(*ax.get_legend_handles_labels(), strict=True):
            entries.setdefault(label, handle)
    entries.update(extra or {})
    for name in no_answer:
        entries[f"{name}: no answer"] = Line2D([], [], ls="none")
    if entries:
        columns = max(1, min(len(entries), int(fig.get_figwidth() // 3.2)))
        fig.legend(list(entries.values()), list(entries), loc="outside lower center", ncols=columns, fontsize=8)


def shade_pulses(ax, pulses, *, scale: float = 1e3) -> None:
    """Shade contact pulses (stage A, blue) and sustained contact (stage B, orange) on ``ax`` (time in ms)."""
    first_a = first_b = True
    for p in pulses or []:
        end = ax.get_xlim()[1] / scale if p.sustained else p.end
        label = None
        if p.sustained and first_b:
            label, first_b = "stage B (sustained contact)", False
        elif not p.sustained and first_a:
            label, first_a = "stage A (contact pulses)", False
        ax.axvspan(p.start * scale, end * scale, color="tab:orange" if p.sustained else "tab:blue",
                   alpha=0.12, lw=0, label=label)
