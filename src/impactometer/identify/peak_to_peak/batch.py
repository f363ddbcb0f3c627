"""The batch peak-to-peak solver: M1 and V0 from a whole record (:func:`identify`, :func:`identify_arrays`) or from
a prepared segment (:func:`solve`; the streaming identifier calls it at every pulse end).

Two variants: ``paper`` (eqs. (3)-(5) as published, :mod:`.paper`) and ``robust`` (default). Both work on the same
prepared segment (:mod:`.segment`): the first impact found by the trigger, offsets removed with the pre-trigger
samples.

``robust`` gives two answers. The **early** one, as soon as the second pulse is past its peak, fits the contact
phase of the first two pulses (:mod:`.early`: a contact-law family with free parameters). The **final** one, and
every later update, is contact-law agnostic (:mod:`.robust`): one generalised least-squares estimate from every
onset, every separation and the stage-B samples of the record. Each answer states the equations it used.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

import numpy as np

from ...constants import STANDARD_GRAVITY
from ...errors import IdentificationError, ImpactometerError, RecordingError
from ...recording import Recording
from ...signals.stage_b import sustained_index
from ..details import EquationsUsed, PeakToPeakDetails, RowsUsed
from ..plausibility import SLIP_GAIN, VELOCITY_SLIPS, acceleration_unit_slip, check_answer, check_segment
from ..result import Identification
from .early import combine, solve_early
from .gls import Equations
from .kinematics import Kinematics
from .options import check_options, check_unfiltered, check_white_noise, filtered_caution
from .paper import solve_paper
from .robust import solve_rows
from .segment import (
    SUSTAINED_FACTOR,
    Segment,
    check_channels,
    check_velocity,
    early_cut,
    early_ready,
    edges,
    extrema,
    need_pulses,
    second_peak,
    segment_bounds,
    segment_of,
    segment_onset,
    segment_separation,
    single_contact,
)

GRAVITY = STANDARD_GRAVITY
#: the separation lag λ is at most this fraction of the first pulse's duration [-]
LAG_FRACTION = 0.5
#: turning points that scatter more than this fraction of V0 beyond their noise (model error, m/s) make the answer
#: suspect: a warning [-]
TURNING_SCATTER_LIMIT = 0.03
#: an answer whose standard error exceeds this fraction of itself says nothing and is refused [-]
MAX_RELATIVE_STD = 0.5


def solve(seg: Segment, variant: str, gravity: float, *, early: Identification | None = None,
          contact_phase: bool = False, stage: str = "final") -> Identification:
    """Identify from a prepared segment with the named variant (``contact_phase``, ``stage``: see
    :func:`solve_robust`).

    The segment passes :func:`.plausibility.check_segment` first, so the batch and the streaming identification,
    their early and final answers, refuse the same data; the answer carries the warnings of
    :func:`answer_warnings`.
    """
    check_segment(seg)
    if variant == "robust":
        result = solve_robust(seg, gravity, early, contact_phase=contact_phase, stage=stage)
    else:
        result = VARIANT_SOLVERS[variant](seg, gravity, early)
    details = details_of(result)
    result = replace(result, details=details)
    reason = None if early is not None or details.stage == "early" else early_refusal(seg, variant)
    return replace(result, warnings=answer_warnings(seg, result, gravity), early_reason=reason)


def answer_warnings(seg: Segment, result: Identification, gravity: float) -> tuple[str, ...]:
    """What makes a peak-to-peak ``result`` implausible for the signals of its segment
    (:func:`.plausibility.check_answer`, and an acceleration unit slip the signals recognise)."""
    details = details_of(result)
    fitted = details.agnostic  # the agnostic equations' χ² measures the fit to noise
    chi2 = details.chi2 / details.dof if fitted and details.chi2 is not None and details.dof else None
    found = check_answer(result.mass, result.velocity, force=seg.force, sample_rate=seg.sample_rate,
                         onset=(result.t00 - seg.start_time) * seg.sample_rate,
                         pulse_ends=[p.end for p in seg.pulses if p.complete], gravity=gravity,
                         noise_force=seg.noise_force, acceleration=seg.acceleration,
                         noise_acceleration=seg.noise_acceleration, reduced_chi2=chi2, mass_std=result.mass_std,
                         velocity_std=result.velocity_std)
    slip = acceleration_unit_slip(seg)
    if slip:
        found += (slip,)
    elif chi2 is not None and chi2 >= SLIP_GAIN:  # below, no slip can fit SLIP_GAIN times better
        found += _unit_slip(seg, gravity, chi2)
    scatter = details.equations.turning_scatter if details.equations is not None else 0.0
    if fitted and scatter > TURNING_SCATTER_LIMIT * abs(result.velocity):
        found += (f"the force's turning points scatter {scatter:.3g} m/s beyond their noise about the answer "
                  f"({scatter / abs(result.velocity):.0%} of V0): neither flights nor a pad's set describe the gaps "
                  "between the pulses, and the answer may be far off",)
    return found


def details_of(result: Identification) -> PeakToPeakDetails:
    """The typed details of a peak-to-peak ``result`` (the paper variant writes a dict: typed here)."""
    details = result.details
    return details if isinstance(details, PeakToPeakDetails) else PeakToPeakDetails.from_mapping(details)


def _unit_slip(seg: Segment, gravity: float, chi2: float) -> tuple[str, ...]:
    """An acceleration unit slip the signals recognise: the onset equations, which hold gravity as a known term,
    fit the noise far better with the acceleration rescaled by the slip's factor, to a plausible answer."""
    for factor, text in VELOCITY_SLIPS.items():
        scaled = replace(seg, acceleration=seg.acceleration / factor, noise_acceleration=seg.noise_acceleration
                         / factor)
        try:
            other = solve_robust(scaled, gravity)
        except IdentificationError:
            continue
        rows = details_of(other)
        if not rows.agnostic or rows.chi2 is None or not rows.dof:
            continue
        better = chi2 / max(rows.chi2 / rows.dof, 1.0)
        if better >= SLIP_GAIN and not check_answer(other.mass, other.velocity):
            return (f"the onset equations fit the noise {math.sqrt(better):.3g} times better with the acceleration "
                    f"multiplied by {1 / factor:.6g}: {text} would give this answer; read so, M1 = "
                    f"{other.mass:.4g} kg and V0 = {other.velocity:.4g} m/s",)
    return ()


def equations(seg: Segment) -> tuple[Equations, float, float]:
    """Every row the segment holds: (equations, t00 and its standard error [samples])."""
    sustained = sustained_index(seg.pulses, size=seg.force.size, factor=SUSTAINED_FACTOR)
    ready, single = early_ready(seg), single_contact(seg)
    pulses = [p for k, p in enumerate(seg.pulses) if p.complete or k == sustained or (k == 1 and ready) or single]
    onsets, stds = edges(seg, pulses)
    gaps = np.array([[max(prev.end, prev.peak), int(o)] for prev, o in zip(seg.pulses, onsets[1:], strict=False)],
                    dtype=int)
    complete = [p for p in seg.pulses if p.complete]
    seps = [segment_separation(seg, p) for p in complete]
    times, time_std, stage, span = extrema(seg)
    eqs = Equations(onsets=onsets[1:], onset_std=stds[1:], extrema=times, extremum_std=time_std, stage_b=stage,
                    separations=np.array([s[0] for s in seps]), separation_std=np.array([s[1] for s in seps]),
                    peaks=np.array([float(p.peak) for p in complete]), stage_b_samples=span,
                    gaps=gaps.reshape(-1, 2))
    return eqs, float(onsets[0]), float(stds[0])


def used_samples(result, recording) -> dict[str, np.ndarray] | None:
    """Times [s] of what a robust answer's equations read in ``recording``, or None when there is nothing to mark
    (another method, or a recording that does not give the answer's segment again).

    The answer's details count its rows (``details['equations']``) but keep no sample; the segment is prepared
    again from the recording as :func:`identify` prepared it, and its rows found again (:func:`equations`); it is
    the answer's segment when its first contact is the answer's t00. Keys: ``onsets`` (t00 left out),
    ``turning_a`` and ``turning_b`` (the force's turning points in stage A and in stage B), ``separations``,
    ``contact_phase`` ((start, end) of each stretch a contact-phase fit read), each empty when the answer did not
    use it; ``onsets_found`` (every onset, used or not). The answer's figure marks them:
    ``result.plot(recording, used=used_samples(result, recording))``.
    """
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


def _determined(eqs: Equations, dof: int = 1) -> bool:
    """Whether the agnostic rows leave ``dof`` degrees of freedom once (V0, w) and the nuisances are fitted
    (extrema bring one nuisance, separations two; see :func:`~impactometer.identify.peak_to_peak.robust.solve_rows`)."""
    n_ext, n_sep = eqs.extrema.size, eqs.separations.size
    rows = eqs.onsets.size + (n_ext - 1 if n_ext >= 2 else 0) + (n_sep - 2 if n_sep >= 3 else 0)
    return rows >= 2 + dof


def solve_robust(seg: Segment, gravity: float, early: Identification | None = None, *,
                 contact_phase: bool = False, stage: str = "final") -> Identification:
    """The robust variant's answer from a prepared segment.

    ``stage="early"``: the contact-phase fit of the first two pulses (:func:`.early.solve_early`).
    ``stage="final"``: the agnostic rows of :func:`.robust.solve_rows` --
    every onset, turning point of the force and separation -- where they leave at least one degree of freedom,
    else the contact-phase fit. With ``contact_phase`` the agnostic answer is combined with the contact-phase fit
    (best linear unbiased, with the shared acceleration noise), at the price of depending on the contact-law
    family.
    """
    check_white_noise(seg)
    single = single_contact(seg)
    if not single and (not seg.pulses or not seg.pulses[0].complete or len(seg.pulses) < 2):
        need_pulses(seg, 2, "the robust variant")
    eqs, t00, std0 = equations(seg)
    agnostic = stage == "final" and _determined(eqs)
    if single and not agnostic:
        raise IdentificationError(
            "the record holds one contact that never ended (the mass did not rebound off the rod) with "
            f"{eqs.extrema.size} turning points of the force; without a second pulse the robust variant needs at "
            "least 4 turning points in that contact (a longer record), or use the response-map method")
    if not agnostic and not (seg.pulses[1].complete or early_ready(seg)):
        need_pulses(seg, 2, "the robust variant")
    kin = Kinematics(seg.force, seg.acceleration, 1.0 / seg.sample_rate, t00, gravity, onset_std0=std0)
    noise: dict[str, Any] = dict(noise_force=seg.noise_force, noise_acceleration=seg.noise_acceleration,
                                 pre_samples=seg.pre_samples)
    second = seg.pulses[1] if len(seg.pulses) > 1 else None
    peak2 = second_peak(seg) or (second.peak if second is not None else None)
    readings = None
    if agnostic:
        first = seg.pulses[0]
        lag_max = LAG_FRACTION * ((first.end if first.complete else seg.force.size) - first.zero) / seg.sample_rate
        sol = solve_rows(kin, eqs, lag_max=lag_max, **noise)
        theta, cov, chi2, dof = sol.theta, sol.cov, sol.chi2, sol.dof
        readings = sol.readings
        used = EquationsUsed(rows=sol.used, nuisances=sol.nuisances, gap_readings=readings)
        if contact_phase and second is not None and peak2 is not None:
            contact = _contact_phase(seg, kin, peak2, noise)
            joined = combine((theta, cov, (sol.gain, sol.tau)), (contact.theta, contact.cov,
                                                                 (contact.weights, contact.taus)),
                             noise_acceleration=seg.noise_acceleration, pre_samples=seg.pre_samples, dt=kin.dt)
            if joined is not None:
                theta, cov = joined
            # without a contact-phase fit, or one whose covariance cannot be joined, the agnostic answer stands
            used = replace(used, contact_phase={**contact.info, "combined": joined is not None})
        last = max([p.end if p.complete else seg.force.size - 1 for p in seg.pulses])
    else:
        stage = "early" if stage == "early" else "final"
        assert second is not None and peak2 is not None  # a single contact is answered above or refused
        contact = _contact_phase(seg, kin, peak2, noise)
        theta, cov, chi2, dof, info = contact.theta, contact.cov, contact.chi2, contact.dof, contact.info
        if info["branches"] == "none":
            raise IdentificationError(f"the contact phase does not determine the mass here: {info['refusal']}")
        used = EquationsUsed(rows=RowsUsed(onsets=int(info["onset_row"])), contact_phase=info)
        last = second.end if second.complete else seg.force.size - 1
    velocity, w = float(theta[0]), float(theta[1])
    if not (w > 0.0 and math.isfinite(w)) or not math.isfinite(velocity) or not np.all(np.isfinite(cov)):
        raise IdentificationError(f"the equations give no positive mass (1/M1 = {w:.4g} 1/kg); the pulses found "
                                  "are not contact separations of a falling mass")
    check_velocity(velocity, f"the {stage} equations")
    spread = max(float(np.sqrt(cov[1, 1])) / w, float(np.sqrt(cov[0, 0])) / max(abs(velocity), 1e-12))
    if spread > MAX_RELATIVE_STD:
        why = "more of the record is needed"
        if readings is not None:  # the spread is the two readings of the gaps
            (v_f, m_f), (v_s, m_s) = readings.flights, readings.kept_set
            why = (f"the gaps between the pulses read as flights give M1 = {m_f:.3g} kg, V0 = {v_f:.3g} m/s, read "
                   f"as a contact that kept a set {m_s:.3g} kg, {v_s:.3g} m/s, and both fit the turning points "
                   "alike; a longer stage B tells them apart")
        raise IdentificationError(f"the {stage} equations do not determine the impact: the standard error is "
                                  f"{spread:.0%} of the answer (at most {MAX_RELATIVE_STD:.0%} is an answer); "
                                  f"{why}")
    return Identification(
        mass=1.0 / w, velocity=velocity, mass_std=float(np.sqrt(cov[1, 1])) / w ** 2,
        velocity_std=float(np.sqrt(cov[0, 0])), early=early, available_at=seg.time_of(last),
        method="peak-to-peak/robust",
        details=PeakToPeakDetails(t00=seg.time_of(t00), t01=seg.time_of(seg.pulses[0].peak),
                                  t11=math.nan if peak2 is None else seg.time_of(peak2),
                                  onsets=tuple(seg.time_of(o) for o in np.r_[t00, eqs.onsets]), stage=stage,
                                  equations=used, chi2=chi2, dof=dof, noise_force=seg.noise_force,
                                  noise_acceleration=seg.noise_acceleration, pre_trigger_samples=seg.pre_samples))


def _contact_phase(seg: Segment, kin: Kinematics, peak2: int, noise: dict):
    """The contact-phase fit of the first two pulses (:func:`~impactometer.identify.peak_to_peak.early.solve_early`)."""
    first, second = seg.pulses[0], seg.pulses[1]
    onset, onset_std = segment_onset(seg, second)
    running = second if second.complete else replace(second, end=seg.force.size)
    return solve_early(kin, [first, running], onset, onset_std, peaks=[first.peak, peak2],
                       gap=(max(first.end, first.peak), int(onset)), **noise)


VARIANT_SOLVERS = {"robust": solve_robust, "paper": solve_paper}


#: key of a segment's onset cache that keeps why the early answer was refused: the cache is shared by the segments
#: cut from one impact (the early cut and the whole record in the batch function, every estimate of an impact in
#: the streaming identifier), so the later answers say why they have no early one
EARLY_REFUSAL = ("early answer", "refusal")
#: why there is no early answer where the data never allowed one
NO_EARLY_DATA = ("the early answer needs a complete first contact pulse and a second one past its peak; the record "
                 "holds none")


def early_answer(cut: Segment | None, gravity: float) -> Identification | None:
    """The robust variant's early answer from the data up to the second pulse, or None when that data allows
    none (the reason kept for :func:`early_refusal`)."""
    if cut is None:
        return None
    try:
        return solve(cut, "robust", gravity, stage="early")
    except IdentificationError as exc:
        cut.onset_cache[EARLY_REFUSAL] = str(exc)
        return None


def early_refusal(seg: Segment, variant: str) -> str:
    """Why an answer from ``seg`` has no early answer."""
    if variant != "robust":
        return f"the {variant} variant gives no early answer (the robust variant does)"
    return seg.onset_cache.get(EARLY_REFUSAL, NO_EARLY_DATA)


def identify_arrays(force, acceleration, sample_rate: float, start_time: float = 0.0, *, variant: str = "robust",
                    gravity: float = GRAVITY, contact_phase: bool = False, early: bool = True) -> Identification:
    """Identify M1 and V0 from contact force [N] and kinematic piston acceleration [m/s²] arrays.

    Parameters
    ----------
    force, acceleration : array_like
        Contact force [N] (positive in compression) and piston acceleration [m/s²] (down, gravity removed).
    sample_rate : float
        Sample rate [Hz].
    start_time : float
        Time of the first sample [s].
    variant : {"robust", "paper"}
        The robust method (default) or eqs. (3)-(5) of the reference paper.
    gravity : float
        Gravitational acceleration [m/s²].
    contact_phase, early : bool
        ``robust`` only: combine the onset equations with the contact-phase fit of the first two pulses
        (see :func:`solve_robust`); give the early answer (default True; the model fit needs the final one only).

    Returns
    -------
    Identification
        For ``robust`` with an ``early`` answer (data up to the end of the second pulse).

    Notes
    -----
    The first impact in the data is used: the trigger finds it, up to ``PRE_SAMPLES`` samples before it give the
    offsets and noise of both channels, and it ends after ``QUIET_TIME`` without contact or ``MAX_DURATION``.
    """
    variant, gravity, start_time = check_options(variant, gravity, start_time)
    f, a, fs = check_channels(force, acceleration, sample_rate)
    start, stop, ends, pre = segment_bounds(f, fs)
    seg = segment_of(f, a, fs, float(start_time), start, stop, pre, {})
    first = early_answer(early_cut(f, a, fs, float(start_time), start, ends, pre, seg.onset_cache),
                         gravity) if variant == "robust" and early else None
    return solve(seg, variant, gravity, early=first, contact_phase=contact_phase)


def identify(recording: Recording, *, variant: str = "robust", gravity: float = GRAVITY,
             contact_phase: bool = False) -> Identification:
    """Identify M1 and V0 from a :class:`~impactometer.recording.Recording` (see :func:`identify_arrays`)."""
    if not isinstance(recording, Recording):
        raise IdentificationError(f"recording must be a Recording, got {type(recording).__name__}")
    check_unfiltered(recording, variant)
    channels = {}
    for name in ("contact_force", "piston_acceleration"):
        try:
            channels[name] = recording.channel(name)
        except RecordingError:
            raise IdentificationError(f"{recording.source}: channel {name!r} is missing; peak-to-peak needs "
                                      f"contact_force and piston_acceleration, found {sorted(recording.channels)}"
                                      ) from None
    note = recording.units_note
    try:
        answer = identify_arrays(channels["contact_force"], channels["piston_acceleration"], recording.sample_rate,
                                 recording.start_time, variant=variant, gravity=gravity, contact_phase=contact_phase)
    except IdentificationError as exc:
        if note:
            raise IdentificationError(f"{exc}; {note}") from None
        raise
    caution = filtered_caution(recording, variant)
    if caution:
        details = details_of(answer)
        earlier = details.caution
        answer = replace(answer, details=replace(details, caution=f"{caution}; {earlier}" if earlier else caution))
    return replace(answer, warnings=(*answer.warnings, note)) if note else answer
