"""Every figure of impactometer, one module per subject; matplotlib is imported once, lazily, by :func:`_pyplot`.

- :mod:`.simulation`: histories of a simulated drop test (``SimulationResult.plot``)
- :mod:`.recordings`: a recording with its pulses and stages (``impactometer inspect --plot``)
- :mod:`.identification`: the instants and equations an identification used (``Identification.plot``)
- :mod:`.absorption`: the absorber's force histories (the paper's Fig. 10b) and metrics
- :mod:`.studies`: the figures of the studies (the paper's Figs. 3-9 and beyond)

The computation never imports this package at module level: a result's ``.plot()`` imports the function it needs.
"""

from __future__ import annotations


def _pyplot():
    import matplotlib

    if matplotlib.get_backend().lower() not in ("agg", "module://matplotlib_inline.backend_inline"):
        matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def legend_outside(ax, **options) -> None:
    """Legend to the right of ``ax``, off the data."""
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0, fontsize=8, **options)


def figure_legend(fig, ax) -> None:
    """The legend of ``ax`` to the right of the whole (constrained-layout) figure, off every panel's data."""
    handles, labels = ax.get_legend_handles_labels()
    if handles:
        fig.legend(handles, labels, loc="outside right upper", fontsize=8)


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
