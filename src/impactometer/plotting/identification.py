"""Figure of an identification (matplotlib imported lazily)."""

from __future__ import annotations

import math

import numpy as np

from . import ACCELERATION_LABEL, _pyplot, legend_outside


def plot_identification(result, recording=None, ax=None):
    """Figure of an :class:`~impactometer.identify.result.Identification`; returns the figure.

    Parameters
    ----------
    result : Identification
        The answer.
    recording : Recording, optional
        With it: contact force [kN] and piston acceleration [m/s²] vs time [ms], with what the answer used marked:
        t00 (first contact, the origin of the integrals) and, for the paper variant, the force peaks t01 and t11;
        for the robust variant the samples its equations read (:func:`used_samples`): onsets, turning points of
        the force in stage A and in stage B, separations, the stage-B span, or the pulses of a contact-phase fit.
        Without it: mass [kg] and velocity [m/s] of the early and the final answer, with their standard errors,
        vs the time they were available [ms].
    ax : Axes or pair of Axes, optional
        Where to draw (one Axes: a twin is added for the second quantity).
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
        _signals(axes, result, recording)
    legend_outside(axes[0])
    name = result.method if recording is None else result.variant
    axes[0].set_title(f"{name}: M1 = {result.mass:.3g} kg, V0 = {result.velocity:.4g} m/s "
                      f"(available at {result.available_at * 1e3:.2f} ms)")
    return fig


def used_samples(result, recording) -> dict[str, np.ndarray] | None:
    """Times [s] of what a robust answer's equations read in ``recording``, or None when there is nothing to mark
    (another method, or a recording that does not give the answer's segment again).

    The answer's details count its rows (``details['equations']``) but keep no sample; the segment is prepared
    again from the recording as :func:`~impactometer.identify.peak_to_peak.identify` prepared it, and its rows
    found again (:func:`~impactometer.identify.peak_to_peak.equations`); it is the answer's segment when its first
    contact is the answer's t00. Keys: ``onsets`` (t00 left out), ``turning_a`` and ``turning_b`` (the force's
    turning points in stage A and in stage B), ``separations``, ``contact_phase`` ((start, end) of each stretch a
    contact-phase fit read), each empty when the answer did not use it; ``onsets_found`` (every onset, used or
    not).
    """
    from ..errors import ImpactometerError
    from ..identify.peak_to_peak import equations
    from ..identify.peak_to_peak.segment import check_channels, segment_bounds, segment_of

    used = result.details.get("equations")
    if result.family != "peak-to-peak" or not isinstance(used, dict):
        return None
    try:
        force, acceleration, rate = check_channels(recording.contact_force, recording.piston_acceleration,
                                                   recording.sample_rate)
        start, stop, _, pre = segment_bounds(force, rate)
        seg = segment_of(force, acceleration, rate, float(recording.start_time), start, stop, pre, {})
        eqs, t00, _ = equations(seg)
    except ImpactometerError:
        return None
    if not math.isclose(seg.time_of(t00), result.t00, abs_tol=0.5 / rate):
        return None

    def times(index, chosen=True) -> np.ndarray:  # times [s] of the chosen fractional sample indices
        index = np.asarray(index, dtype=float)
        return seg.start_time + index[np.broadcast_to(np.asarray(chosen, dtype=bool), index.shape)] / rate

    turning = used.get("extrema", 0) > 0
    stage_b = np.asarray(eqs.stage_b, dtype=bool)
    stretches = []
    fit = used.get("contact_phase")
    if isinstance(fit, dict) and fit.get("samples", 0) > 0:
        ends = (lambda p: p.peak + 1) if fit.get("branches") == "loading" else (lambda p: p.end if p.complete
                                                                                 else seg.force.size - 1)
        stretches = [(seg.time_of(p.zero), seg.time_of(ends(p))) for p in seg.pulses[:2]]
    return {"onsets_found": times(eqs.onsets),
            # the rows count the onsets kept; which of several were dropped is not kept: all, or none, is marked
            "onsets": times(eqs.onsets, used.get("onsets", 0) == eqs.onsets.size and eqs.onsets.size > 0),
            "turning_a": times(eqs.extrema, ~stage_b if turning else False),
            "turning_b": times(eqs.extrema, stage_b if turning else False),
            "separations": times(eqs.separations, used.get("separations", 0) > 0),
            "contact_phase": np.array(stretches, dtype=float).reshape(-1, 2)}


def _signals(axes, result, recording) -> None:
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
    rows = used_samples(result, recording)
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
