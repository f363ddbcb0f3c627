"""Model-based identification (method ``model``): the maximum-likelihood estimate of M1 and V0 from the whole
record, both channels and every sample, with the stand model of paper eqs. (1)-(2).

The record is predicted through the stand model and the recording's own sensor model (:mod:`.forward`) and fitted
by weighted least squares (:mod:`.engine`, each channel weighted by its noise σ from the pre-trigger), started from the
robust peak-to-peak answer (from a grid of impacts where that fails). Unknowns: M1, V0, the contact instant
(between samples), both sensor offsets, the stand parameters marked uncertain (default: the contact law's parameters
and the seal friction) and the charge pressure unless it is known. Each contact-law family of the project is fitted
(:mod:`.select`); the smallest BIC chooses. Standard errors come from the Fisher information at the optimum
(:mod:`.information`), inflated by sqrt(χ²/dof) where that exceeds 1, where the model explains the record down to
its noise, and widened by the calibrated stand's stated uncertainty of the parameters the fit holds
(:mod:`.stand_prior`: propagated linearly through the fit's Jacobian); :mod:`.adequacy` judges that, gives the fit
of the first span the model explains or a sandwich σ where it does not, and checks the answer against the robust
answer. A record that names no stand, identified without ``rig``, is also fitted on every other built-in stand
(:mod:`.stand_choice`): where one explains it better beyond what chance gives a right stand in 1 record of 1000, the
answer is that stand's, with a warning naming it. When the best law leaves χ²/dof above :data:`MAX_REDUCED_CHI2`
and explains no shorter span, or its answer disagrees with the robust one, the answer is the robust one; its
details say which path was taken and why (``adequacy``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path

from ...errors import IdentificationError, ParameterError, RecordingError, shown
from ...recording import Recording
from ...rig import PRESETS, STAND_KEY, Rig, StandUncertainty, fingerprint, get_rig, load_uncertainty
from ...sensors import anti_alias_delay
from ...validation import check_real, renamed
from ..details import Adequacy, ModelDetails
from ..plausibility import check_answer
from ..result import Identification
from .adequacy import (
    NESTED_SPAN,
    Z_JOINT,
    Z_JOINT_ADEQUATE,
    Z_NESTED,
    _assess,
    _disagreement,
    _nested,
    _robust_inflation,
    _shortened,
)
from .engine import (
    MIN_DURATION,
    LawFit,
    Observed,
    _least_bic,
    anti_alias_design,
    check_channels,
    check_length,
    contact_laws,
    observe,
    weighted_jacobian,
)
from .forward import _check_uncertain, free_parameters, make_layout, stand_values
from .information import CramerRao, _bound_of, covariance
from .select import CRITERION, _fit_laws, _grid_starts, _Start
from .stand_choice import STAND_FALSE_ALARM, _compare_stands, _names_no_stand, _switches
from .stand_prior import _stand_variance

__all__ = ["identify", "cramer_rao", "CramerRao", "MAX_REDUCED_CHI2", "MIN_DURATION"]

#: χ²/dof of the best law above which the model is taken not to describe the record: the robust answer is given
MAX_REDUCED_CHI2 = 1.5
#: χ²/dof above which an answer of the model carries a warning (model error beyond the noise)
WARN_REDUCED_CHI2 = 1.1
#: a stated charge pressure's default σ: this fraction of the reading [-] ...
GAUGE_RELATIVE_STD = 0.02
#: ... and at least this [Pa] (:func:`_gauge_std`)
GAUGE_FLOOR_STD = 1e3
#: a pressure given and one in the metadata contradict each other beyond this many of their combined σ [-]
PRESSURE_CONTRADICTION = 3.0
#: a fitted pressure whose pull (:func:`_pressure_pull`) exceeds this is named in a warning [-]: a right gauge and
#: stand put it there in 4.6 % of records; a misread gauge or another stand (whose difference the pressure soaks
#: up) more often
PRESSURE_PULL = 2.0
#: samples the contact instant starts before the crude trigger when the robust answer fails
TRIGGER_LEAD = 2
#: the points a Cramér-Rao bound is evaluated at (:func:`cramer_rao`'s ``at``)
BOUND_POINTS = ("truth", "estimate")
#: where a fitted pre-charge starts when the recording states none [Pa gauge]
DEFAULT_PRESSURE_GAUGE_START = 200e3


def _gauge_std(pressure_gauge: float) -> float:
    """The default σ [Pa] of a charge pressure [Pa gauge] as a gauge states it: :data:`GAUGE_RELATIVE_STD` (2 %) of
    the reading, at least :data:`GAUGE_FLOOR_STD` (1 kPa). A pressure gauge of a drop stand is typically good to 1-4 %
    of its reading (class 1-2.5 dial gauges on half their span, or a transducer's drift); 2 % is the middle of that
    range, and the floor is a dial's resolution near zero."""
    return max(GAUGE_RELATIVE_STD * abs(pressure_gauge), GAUGE_FLOOR_STD)


def _pressure(recording: Recording, pressure_gauge: float | None, rig: Rig,
              pressure_gauge_std: float | None = None) -> tuple[float | None, float]:
    """The charge pressure [Pa gauge] and its σ [Pa]: the one given, the metadata's, or both combined (their
    inverse-variance mean) where both are stated; (None, 0) when neither states it (fitted). ``pressure_gauge_std`` is
    the σ of the pressure given (else of the metadata's); default :func:`_gauge_std` of each. A σ of 0 holds the
    pressure exactly. A pressure given and the metadata's more than :data:`PRESSURE_CONTRADICTION` combined σ apart
    are refused."""
    stated = recording.metadata.get("pressure_gauge_Pa")
    if stated is not None:
        try:
            stated = float(stated)
        except (TypeError, ValueError):
            raise RecordingError(f"{recording.source}: metadata pressure_gauge_Pa must be a number [Pa gauge], got "
                                 f"{shown(stated)}") from None
    if pressure_gauge_std is not None:
        pressure_gauge_std = check_real("pressure_gauge_std", pressure_gauge_std, low=0.0, unit=" [Pa]",
                                        state_range=True)
    if pressure_gauge is None:
        if stated is None:
            return None, 0.0
        return stated, _gauge_std(stated) if pressure_gauge_std is None else pressure_gauge_std
    pressure_gauge = check_real("pressure_gauge", pressure_gauge, low=0.0, high=rig.cylinder.rated_pressure_gauge,
                          unit=f" [Pa gauge] (the rating of {rig.name!r})", state_range=True)
    given_std = _gauge_std(pressure_gauge) if pressure_gauge_std is None else pressure_gauge_std
    if stated is None:
        return pressure_gauge, given_std
    stated_std = _gauge_std(stated)
    combined = math.hypot(given_std, stated_std)
    if abs(pressure_gauge - stated) > PRESSURE_CONTRADICTION * combined:
        raise ParameterError(f"pressure_gauge {pressure_gauge:g} Pa gauge contradicts the recording's metadata "
                             f"pressure_gauge_Pa = {stated:g} Pa: they differ by "
                             f"{abs(pressure_gauge - stated):.4g} Pa, "
                             f"more than {PRESSURE_CONTRADICTION:g} times their combined σ {combined:.4g} Pa "
                             "(leave pressure_gauge out to use the metadata's, or state its pressure_gauge_std)",
                             field="pressure_gauge",
                             expected=f"contradicts the recording's metadata pressure_gauge_Pa = "
                             f"{stated:g} Pa by more than {PRESSURE_CONTRADICTION:g} times their combined σ "
                             f"{combined:.4g} Pa (leave it out to use the metadata's, or state its pressure_gauge_std)")
    if given_std == 0.0:
        return pressure_gauge, 0.0
    weights = 1.0 / given_std ** 2, 1.0 / stated_std ** 2
    return (float((weights[0] * pressure_gauge + weights[1] * stated) / sum(weights)),
            float(1.0 / math.sqrt(sum(weights))))


def _stand_warning(recording: Recording, rig: Rig) -> tuple[str, ...]:
    """The warning of a recording that states another stand than ``rig``, naming the preset it states (metadata
    ``rig``) to pass instead."""
    stated = recording.metadata.get(STAND_KEY)
    if stated is None or str(stated) == fingerprint(rig):
        return ()
    name = recording.metadata.get("rig")
    preset = isinstance(name, str) and name in PRESETS and name != rig.name and str(stated) == fingerprint(
        PRESETS[name])
    return (f"the recording states a stand with other parameters (fingerprint {str(stated)[:16]}) than "
            f"{rig.name!r}; the fit takes {rig.name!r}'s parameters except those it frees"
            + (f" -- the recording was made on the preset {name!r}: pass rig={name!r}" if preset else ""),)


@renamed(pressure="pressure_gauge", pressure_std="pressure_gauge_std")
def identify(recording: Recording, *, rig: Rig | str | None = None, pressure_gauge: float | None = None,
             pressure_gauge_std: float | None = None, uncertain: Sequence[str] | None = None,
             contact: str | None = "auto",
             max_reduced_chi2: float = MAX_REDUCED_CHI2,
             stand_uncertainty: StandUncertainty | None = None) -> Identification:
    """Identify M1 and V0 by the maximum-likelihood fit of the whole record (method ``model``).

    Parameters
    ----------
    recording : Recording
        Contact force [N] and piston acceleration [m/s²] with a pre-trigger (at least ``MIN_PRE_SAMPLES`` +
        ``GUARD_SAMPLES`` samples before first contact) and at least ``MIN_DURATION`` after it.
    rig : Rig or str, optional
        The stand (a preset name or a TOML file; default ``drop-stand``). Where it is not given and the recording's
        metadata names no stand (``rig``, ``rig_fingerprint``), every other built-in stand is fitted too and the one
        whose best BIC is lower than the default's by more than :func:`.stand_choice._threshold` gives the answer,
        with a warning naming it (details ``stands``: the stands compared and their evidence).
    pressure_gauge : float, optional
        Charge pressure [Pa gauge] as a gauge reads it; default the metadata's ``pressure_gauge_Pa``, else
        fitted freely. Where both are stated they are combined (their inverse-variance mean), and refused when they
        differ by more than :data:`PRESSURE_CONTRADICTION` times their combined σ.
    pressure_gauge_std : float, optional
        σ of the stated pressure [Pa] (of ``pressure_gauge``, else of the metadata's); default :func:`_gauge_std`
        (2 % of the reading, at least 1 kPa). The pressure is fitted with the Gaussian prior stated ± σ, so the σ of
        M1 and V0 (and the Cramér-Rao bound of the details) include the gauge's error; 0 holds it exactly.
    uncertain : sequence of str, optional
        Stand parameters fitted with M1 and V0 (dotted names, ``"contact"`` for the law's parameters); default the
        contact law's parameters and ``friction.force``.
    contact : str, optional
        ``"auto"`` (default): fit every contact law and keep the smallest BIC; or one law's name.
    max_reduced_chi2 : float
        χ²/dof of the best law above which the robust answer is given instead [-].
    stand_uncertainty : StandUncertainty, optional
        σ and correlation of the stand's calibrated parameters; default the ``[uncertainty]`` table of the stand
        file ``rig`` names (a calibrated stand's), none for a preset or a Rig. Those the fit holds widen σ(M1) and
        σ(V0) by their covariance propagated linearly through the fit's Jacobian, S Σ_stand Sᵀ
        (:mod:`.stand_prior`); the answer itself is unchanged.

    Returns
    -------
    Identification
        Method ``model/ml`` (the fit's answer) or ``model/fallback`` (the robust peak-to-peak answer, the model
        not describing the record); details: ``path`` and ``reason``, ``contact_law``, ``model_selection`` (each
        law's χ², BIC and values), ``crb`` (Cramér-Rao σ of M1 and V0 at the estimate), ``robust``, ``stands``
        (the built-in stands compared, where they were).

    Raises
    ------
    ParameterError
        For a pressure that contradicts the metadata, an unknown uncertain parameter or another bad option.
    IdentificationError
        For a record the fit cannot use (too short, no pre-trigger, a filter it cannot reproduce), or when
        neither the robust answer nor the model (started from a grid of impacts when the robust answer fails)
        gives one.
    """
    from ..peak_to_peak import identify_arrays as identify_robust

    check_channels(recording)
    if stand_uncertainty is None and isinstance(rig, (str, Path)) and str(rig) not in PRESETS:
        stand_uncertainty = load_uncertainty(rig) if Path(rig).suffix.lower() == ".toml" else None
    elif stand_uncertainty is not None and not isinstance(stand_uncertainty, StandUncertainty):
        raise ParameterError(f"stand_uncertainty must be a StandUncertainty or None, got {shown(stand_uncertainty)}",
                             field="stand_uncertainty", expected="a StandUncertainty or None")
    given, rig = rig, get_rig(rig)
    laws = contact_laws(contact)
    free_names = _check_uncertain(uncertain, laws)
    max_reduced_chi2 = check_real("max_reduced_chi2", max_reduced_chi2, low=1.0, unit=" [-]", state_range=True)
    gauge, gauge_std = _pressure(recording, pressure_gauge, rig, pressure_gauge_std)
    design = anti_alias_design(recording)
    trigger = check_length(recording)
    pressure_gauge_start = recording.metadata.get("pressure_gauge_Pa") or DEFAULT_PRESSURE_GAUGE_START
    delay = anti_alias_delay(design, recording.sample_rate)
    failed = ""
    try:
        robust = identify_robust(recording.contact_force, recording.piston_acceleration, recording.sample_rate,
                                 recording.start_time, early=False)
    except IdentificationError as exc:
        robust, failed = None, str(exc)
    if robust is not None:
        data = observe(recording, design, robust.t00)
        start = _Start(mass=robust.mass, velocity=robust.velocity, contact_time=robust.t00 - delay,
                       pressure_gauge=gauge,
                      pressure_gauge_start=pressure_gauge_start, pressure_gauge_std=gauge_std)
    else:  # a few samples before the crude trigger: the first window's fit finds the instant
        data = observe(recording, design, trigger)
        start = replace(_grid_starts(data, rig, trigger - delay - TRIGGER_LEAD / recording.sample_rate, gauge,
                                     pressure_gauge_start)[0], pressure_gauge_std=gauge_std)
    fits, selection = _fit_laws(data, rig, laws, free_names, start, rescue=max_reduced_chi2)
    choice = None
    if given is None and _names_no_stand(recording):
        choice = _compare_stands(data, rig, fits, laws, free_names, start,
                                robust.t00 if robust is not None else trigger)
    named: tuple[str, ...] = ()
    on = (rig, fits, selection, stand_uncertainty)  # the stand the answer is taken on, its fits and uncertainty
    if choice is not None and choice.better is not None:
        assert choice.fits is not None and choice.selection is not None  # a better stand comes with its fits
        other = choice.better
        warning = (f"another built-in stand, {other.name!r}, explains the record better than {rig.name!r} by ΔBIC "
                   f"{choice.compared['stands'][other.name]['delta_bic']:.4g} (beyond "
                   f"{choice.compared['threshold']:.3g}: a right stand loses by that in fewer than "
                   f"{STAND_FALSE_ALARM:g} of its records)")
        if _switches(choice, rig):
            on = (other, choice.fits, choice.selection, None)
            warning += (f"; the record names no stand, so the answer is {other.name!r}'s -- pass rig={other.name!r} "
                        f"(--rig {other.name}) if it was made there, or the stand it was made on")
        else:
            warning += (f", and {rig.name!r} does not explain it down to its noise: the record is of neither stand as "
                        f"the model takes them, or of {other.name!r} -- the answer is {rig.name!r}'s; pass "
                        f"rig={other.name!r} (--rig {other.name}) if it was made there, or the stand it was made on")
        named = (warning,)
    assessed = None if choice is None or choice.assessed is None else choice.assessed.get(on[0].name)
    answer = _conclude(recording, on[0], data, start, robust, failed, on[1], on[2], design, trigger,
                       (gauge, gauge_std), max_reduced_chi2, on[3], None if choice is None else choice.compared,
                       assessed)
    return replace(answer, warnings=(*named, *answer.warnings)) if named else answer

def _conclude(recording: Recording, rig: Rig, data: Observed, start: _Start, robust: Identification | None,
              failed: str, fits: dict[str, LawFit], selection: dict[str, dict], design: str, trigger: float,
              stated: tuple[float | None, float], max_reduced_chi2: float,
              stand_uncertainty: StandUncertainty | None, stands: dict | None,
              assessed: tuple[Adequacy, float, float] | None = None) -> Identification:
    """The answer of the fits ``fits`` of every law on ``rig`` (model selection ``selection``): the adequacy test,
    the shortened or nested fit, the check against the robust answer ``robust`` (None where it failed, why in
    ``failed``) or the fall-back; ``stands`` the stands compared (:func:`.stand_choice._compare_stands`) and
    ``assessed`` the adequacy test of the best fit there (None: it is made here)."""
    gauge, gauge_std = stated
    common = ModelDetails(
        path="", reason="", contact_law=None, model_selection=selection, criterion=CRITERION,
        start={"mass_kg": start.mass, "velocity_m_s": start.velocity, "contact_time_s": start.contact_time,
               "from": "robust" if robust is not None else "grid"},
        robust={"error": failed} if robust is None else
        {"mass_kg": robust.mass, "velocity_m_s": robust.velocity, "mass_std_kg": robust.mass_std,
         "velocity_std_m_s": robust.velocity_std},
        noise_force=float(data.noise[0]), noise_acceleration=float(data.noise[1]), anti_alias=design, stands=stands)
    best = _least_bic(fits.values())

    def fell_back(adequacy: Adequacy | None, reason: str, model: Identification | None = None) -> Identification:
        """The robust answer (:func:`_fallback`), the verdict ``fell back`` for ``reason``."""
        verdict = Adequacy(verdict="fell back", reason=reason) if adequacy is None else replace(
            adequacy, verdict="fell back", reason=reason)
        return _fallback(recording, rig, common, best, verdict, model)

    if robust is None and (best is None or best.reduced_chi2 > max_reduced_chi2):
        raise IdentificationError(f"{recording.source}: no answer: the robust method failed ({failed}) and the "
                                  "model fit, started from a grid, " + (
                                      "failed for every contact law" if best is None else
                                      f"leaves chi2/dof = {best.reduced_chi2:.3g} > {max_reduced_chi2:g}"))
    if best is None:
        assert robust is not None  # without a robust answer the case was refused above
        reason = "every contact law's fit failed: " + "; ".join(f"{k}: {v.get('error')}" for k, v in selection.items())
        return fell_back(None, reason)
    quiet = robust.t00 if robust is not None else trigger  # the noise σ was measured before it (observe)
    adequacy, mass_std, velocity_std = _assess(data, best, quiet) if assessed is None else assessed
    if adequacy.verdict != "adequate" and (short := _shortened(data, best, quiet)) is not None:
        whole = adequacy.reason
        best, adequacy, mass_std, velocity_std = short
        assert best.span is not None  # a shortened fit states its span
        adequacy = replace(adequacy, verdict="shortened", reason=f"the {best.law} model explains the first "
                           f"{best.span[0] * 1e3:g} ms after contact down to the noise ({adequacy.reason}), not the "
                           f"whole record, so the answer is the fit of that span; over the whole record {whole}")
    if adequacy.verdict == "adequate" and (nested := _nested(data, best)) is not None and (
            max(abs(nested[0]), abs(nested[1])) > Z_NESTED):
        plain = mass_std, velocity_std
        # explained down to the noise, yet with another parameter set than its first span: the stand or the pressure
        # is not the one the model takes, and the fit soaks up the difference; σ spans both answers
        mass_std, velocity_std = math.hypot(mass_std, nested[2]), math.hypot(velocity_std, nested[3])
        reason = (f"the {best.law} model explains the record down to its noise, but its fit of the first "
                  f"{NESTED_SPAN * 1e3:g} ms differs from the whole record's by {nested[0]:+.3g} σ in M1 and "
                  f"{nested[1]:+.3g} σ in V0 (beyond {Z_NESTED:g} σ of their difference): the record is not of the "
                  "stand the model takes or not at the pressure stated -- pass rig (--rig) the stand it was made on, "
                  "or pressure_gauge (--pressure) as the gauge reads it with its pressure_gauge_std "
                  "(--pressure-std); σ is widened to span both fits")
        adequacy = replace(adequacy, verdict="widened", reason=reason, nested_z=(nested[0], nested[1]),
                           widening=(mass_std / plain[0], velocity_std / plain[1]))
    if adequacy.verdict == "widened" and best.reduced_chi2 > max_reduced_chi2:
        assert robust is not None  # without a robust answer the case was refused above
        reason = (f"the best model ({best.law}) leaves chi2/dof = {best.reduced_chi2:.3g} > {max_reduced_chi2:g} and "
                  "explains no shorter span down to the noise: it does not describe this record, so the robust answer "
                  "is given")
        return fell_back(adequacy, reason)
    stand = _stand_variance(data, best, rig, stand_uncertainty)
    answer = _answer(recording, rig, best, replace(common, adequacy=adequacy), (gauge, gauge_std), mass_std,
                     velocity_std, stand)
    if robust is None:
        return answer
    z = _disagreement(answer, robust)
    adequacy = replace(adequacy, robust_z=z)
    # a shortened fit is adequate over its span: a disagreement counts from Z_JOINT_ADEQUATE where it is the more
    # precise answer (where it is not, the robust answer is given below whether or not they agree)
    limit = Z_JOINT_ADEQUATE if adequacy.verdict == "shortened" else Z_JOINT
    if adequacy.verdict == "adequate" and z <= Z_JOINT_ADEQUATE or z <= limit and (
            answer.mass_std <= robust.mass_std and answer.velocity_std <= robust.velocity_std):
        return _with_adequacy(answer, adequacy)
    mismatch = (f"differ by {z:.3g} of their joint σ: the record is not of the stand the model takes (pass rig the "
                "stand it was made on), or its charge pressure is not the one stated (pass pressure_gauge as the gauge "
                "reads it, with its pressure_gauge_std), or its pad is outside the contact laws")
    if adequacy.verdict == "adequate":
        # the model explains the record down to its noise: its answer stands, with a σ that reaches the robust one
        # (the robust answer's own σ can be short; a stand or pressure the fit absorbs leaves no misfit)
        reason = (f"the model's answer ({_said(answer)}) explains the record down to its noise, and it and the robust "
                  f"answer ({_said(robust)}) {mismatch}; the model's σ is widened to reach the robust answer")
        widened = replace(_widened(answer, robust), warnings=(*answer.warnings, reason))
        verdict = replace(adequacy, verdict="widened", reason=reason,
                          widening=(widened.mass_std / answer.mass_std, widened.velocity_std / answer.velocity_std))
        return _with_adequacy(widened, verdict)
    if z <= Z_JOINT and adequacy.verdict != "adequate":  # they agree; the model's answer is the less precise
        reason = (f"{adequacy.reason}; its answer ({_said(answer)}) agrees with the robust answer (within "
                  f"{z:.2g} of their joint σ) and is the less precise, so the robust answer is given")
        return fell_back(adequacy, reason)
    reason = (f"the model's answer ({_said(answer)}, {adequacy.verdict}: the model does not explain the whole "
              f"record) and the robust answer ({_said(robust)}) {mismatch}; the robust answer is given, its σ widened "
              "to reach the model's answer")
    return fell_back(adequacy, reason, answer)


def _said(answer: Identification) -> str:
    """M1 and V0 of ``answer`` with their σ, as a message states them."""
    return (f"M1 {answer.mass:.5g} ± {answer.mass_std:.2g} kg, V0 {answer.velocity:.5g} ± {answer.velocity_std:.2g} "
            "m/s")


def _widened(answer: Identification, other: Identification) -> Identification:
    """``answer`` with each σ widened to sqrt(σ² + Δ²), Δ its difference to ``other``."""
    return replace(answer, mass_std=math.hypot(answer.mass_std, other.mass - answer.mass),
                   velocity_std=math.hypot(answer.velocity_std, other.velocity - answer.velocity))


def _with_adequacy(answer: Identification, adequacy: Adequacy) -> Identification:
    """``answer`` (of :func:`_answer`) with its details' adequacy replaced."""
    assert isinstance(answer.details, ModelDetails)
    return replace(answer, details=replace(answer.details, adequacy=adequacy))


def _fallback(recording: Recording, rig: Rig, common: ModelDetails, best: LawFit | None, adequacy: Adequacy,
              model: Identification | None = None) -> Identification:
    """The robust answer (with its early answer) in place of the model's, its σ widened by sqrt(χ²/dof) of its
    rows where they scatter beyond their noise (:func:`.adequacy._robust_inflation`: a record the model does not
    describe may break the robust method's assumptions too); with the ``model``'s answer, each σ then widened to
    sqrt(σ² + Δ²), Δ the difference to the model's answer: the two disagree beyond their joint σ and the record does
    not say which is off."""
    from ..peak_to_peak import identify_arrays as identify_robust

    robust = identify_robust(recording.contact_force, recording.piston_acceleration, recording.sample_rate,
                             recording.start_time)
    reason = adequacy.reason
    scale = _robust_inflation(robust)
    if scale > 1.0:
        robust = replace(robust, mass_std=robust.mass_std * scale, velocity_std=robust.velocity_std * scale)
        reason = (f"{reason}; the robust answer's rows scatter beyond their noise (χ²/dof {scale ** 2:.3g}), so its "
                  f"σ is widened by {scale:.3g}")
        adequacy = replace(adequacy, reason=reason, robust_inflation=scale)
    if model is not None:
        robust = _widened(robust, model)
    return replace(robust, method="model/fallback",
                   warnings=(*_stand_warning(recording, rig), *robust.warnings, reason),
                   details=replace(common, path="fallback", reason=reason, fallback=robust.details, adequacy=adequacy,
                                   contact_law=None if best is None else best.law))


def _answer(recording: Recording, rig: Rig, best: LawFit, common: ModelDetails,
            stated: tuple[float | None, float], log_mass_std: float | None = None,
            log_velocity_std: float | None = None,
            stand: tuple[float, float, tuple[str, ...], tuple[str, ...]] = (0.0, 0.0, (), ())) -> Identification:
    """The :class:`Identification` of the chosen fit (its details ``common``'s, with the fit's); ``stated`` the
    stated pressure [Pa gauge] and its σ [Pa] (None, 0 where it is fitted freely); the σ of ln M1 and ln V0 from
    :func:`.adequacy._assess` (default: the Fisher information's, inflated by sqrt(χ²/dof) where that exceeds 1);
    ``stand`` the variance of ln M1 and ln V0 the stand's stated uncertainty adds, its parameters and those not
    carried (:func:`.stand_prior._stand_variance`)."""
    mass, velocity = best.values["mass"], best.values["velocity"]
    inflation = math.sqrt(max(1.0, best.reduced_chi2))
    crb = _bound_of(best.cov, mass, velocity, law=best.law, at="estimate", unknowns=_unknowns(best.layout.names))
    found = list(_stand_warning(recording, rig))
    found += check_answer(mass, velocity)
    rated = rig.cylinder.rated_pressure_gauge
    if "pressure_gauge" in best.values and (
            best.values["pressure_gauge"] - PRESSURE_CONTRADICTION * best.std("pressure_gauge") * inflation > rated):
        found.append(f"the fitted charge pressure {best.values['pressure_gauge']:.4g} Pa exceeds the rated "
                     f"{rated:g} Pa of {rig.name!r} beyond {PRESSURE_CONTRADICTION:g} of its σ: "
                     "pass pressure_gauge as the gauge reads it, with its pressure_gauge_std")
    pressure_gauge, pressure_gauge_std = stated
    pull = _pressure_pull(best, pressure_gauge, pressure_gauge_std, inflation)
    if pull is not None and abs(pull) > PRESSURE_PULL:
        found.append(f"the fit moves the charge pressure to {best.values['pressure_gauge']:.5g} Pa from the stated "
                     f"{pressure_gauge:.5g} ± {pressure_gauge_std:.3g} Pa, a pull of {pull:+.3g} (beyond "
                     f"{PRESSURE_PULL:g}): the stated pressure or the stand is off -- pass pressure_gauge "
                     "(--pressure) as the gauge reads it with its pressure_gauge_std (--pressure-std), or pass rig "
                     "(--rig) the stand the record was made on")
    if not best.converged:
        found.append(f"the {best.law} fit stopped after {best.evaluations} evaluations before it converged")
    if best.rank < best.unknowns:
        found.append(f"the record determines {best.rank} of the {best.unknowns} unknowns only")
    adequacy = common.adequacy
    if adequacy is not None and adequacy.verdict != "adequate":
        found.append(adequacy.reason)
    elif best.reduced_chi2 > WARN_REDUCED_CHI2:
        found.append(f"the {best.law} model leaves chi2/dof = {best.reduced_chi2:.3g}: model error beyond the noise; "
                     f"the standard errors are inflated by {inflation:.3g}")
    end = recording.start_time + (recording.contact_force.size - 1) / recording.sample_rate
    t00 = best.values["contact_time"]
    details = replace(
        common, path="ml", reason=f"the {best.law} model has the smallest BIC and fits the record to chi2/dof = "
        f"{best.reduced_chi2:.3g}", contact_law=best.law, t00=t00, reduced_chi2=best.reduced_chi2, chi2=best.chi2,
        dof=best.dof, crb=crb.to_dict(), fit_span=None if best.span is None else best.span[0],
        fit_span_reason=None if best.span is None else best.span[1],
        parameters={name: {"value": best.values[name], "std": best.std(name) * inflation}
                    for name in best.layout.names[3:]})
    mass_std = crb.mass_std * inflation if log_mass_std is None else mass * log_mass_std
    velocity_std = crb.velocity_std * inflation if log_velocity_std is None else velocity * log_velocity_std
    added_mass, added_velocity = mass * math.sqrt(stand[0]), velocity * math.sqrt(stand[1])
    mass_std, velocity_std = math.hypot(mass_std, added_mass), math.hypot(velocity_std, added_velocity)
    if stand[2] or stand[3]:
        details = replace(details, stand_uncertainty={"parameters": list(stand[2]), "mass_std_kg": added_mass,
                                                      "velocity_std_m_s": added_velocity,
                                                      "not_carried": list(stand[3])})
    if stand[3]:
        found.append(f"the stand's stated σ of {', '.join(stand[3])} is not carried into σ(M1), σ(V0): the model "
                     "cannot be integrated with it moved from the calibrated value")
    return Identification(mass=mass, velocity=velocity, mass_std=mass_std, velocity_std=velocity_std,
                          available_at=end, method="model/ml", warnings=tuple(found), details=details)


def _pressure_pull(best: LawFit, pressure_gauge: float | None, pressure_gauge_std: float,
                   inflation: float = 1.0) -> float | None:
    """The pull [-] of the fitted charge pressure against the stated one: (p_fit − p_stated)/sqrt(σ_stated² −
    σ_fit²), σ_fit its Fisher σ times ``inflation``; None where the pressure is not fitted with a prior (none stated,
    or held) or the record adds no information on it (σ_fit >= σ_stated).

    The fit combines the stated pressure (its prior) with what the record says of it, so the two are correlated:
    under a right stand and gauge, p_fit − p_stated has the variance σ_stated² − σ_fit² (the pull of a constrained
    fit), a standard normal pull. Dividing by σ_stated alone would understate it exactly where the record tells the
    pressure least, and a stiffer stand or a misread gauge the pressure soaks up would pass unnamed."""
    if pressure_gauge is None or pressure_gauge_std <= 0.0 or "pressure_gauge" not in best.values:
        return None
    fitted_std = best.std("pressure_gauge") * inflation
    spread = pressure_gauge_std ** 2 - fitted_std ** 2
    if not (math.isfinite(spread) and spread > 0.0):
        return None
    return (best.values["pressure_gauge"] - pressure_gauge) / math.sqrt(spread)


def _unknowns(names: Sequence[str]) -> tuple[str, ...]:
    return (*names[2:], "offset.contact_force", "offset.piston_acceleration")


@renamed(pressure="pressure_gauge", pressure_std="pressure_gauge_std", pressure_unknown="pressure_gauge_unknown")
def cramer_rao(recording: Recording, *, mass: float | None = None, velocity: float | None = None,
               contact_time: float = 0.0, rig: Rig | str | None = None,
               pressure_gauge: float | None = None, pressure_gauge_std: float | None = None,
               uncertain: Sequence[str] | None = None,
               pressure_gauge_unknown: bool = False, at: str = "truth") -> CramerRao:
    """Cramér-Rao bound of M1 and V0 for ``recording`` under the stand model, at a given impact.

    Every unknown of the fit is estimated alongside (the contact instant, the stand parameters marked uncertain,
    the charge pressure when it is not known, both offsets), so the bound is that of any unbiased estimate from the
    whole record. The noise σ of each channel is measured on the record's pre-trigger.

    Parameters
    ----------
    recording : Recording
        The record (its sample instants, sensor model and noise).
    mass, velocity : float, optional
        The impact at which to evaluate [kg], [m/s]; default the metadata's truth (``mass_kg``,
        ``velocity_m_s``, as a simulated record holds).
    contact_time : float
        First contact on the recording's clock [s] (0 for a simulated record).
    rig : Rig or str, optional
        The stand, with the contact law and the values of its parameters (default ``drop-stand``).
    pressure_gauge, pressure_gauge_std, uncertain
        As in :func:`identify`; the pressure is where the bound is evaluated [Pa gauge] (default the metadata's), and
        its prior (the stated pressure ± ``pressure_gauge_std``, as :func:`identify` fits it) is part of the
        information.
    pressure_gauge_unknown : bool
        Count the pre-charge among the unknowns (as :func:`identify` does when neither ``pressure_gauge`` nor the
        metadata gives it).
    at : str
        Label of the point: ``"truth"`` or ``"estimate"``.

    Returns
    -------
    CramerRao
    """
    check_channels(recording)
    if not (isinstance(at, str) and at in BOUND_POINTS):
        raise ParameterError(f"at must be one of {list(BOUND_POINTS)}, got {shown(at)}")
    rig = get_rig(rig)
    law = rig.contact.law
    free = free_parameters(law, _check_uncertain(uncertain, (law,)))
    given = {"mass": recording.metadata.get("mass_kg") if mass is None else mass,
             "velocity": recording.metadata.get("velocity_m_s") if velocity is None else velocity}
    values = {name: check_real(name, value, low=0.0, low_open=True, state_range=True,
                               unit=f" [{'kg' if name == 'mass' else 'm/s'}] (or stated in the recording's metadata)")
              for name, value in given.items()}
    gauge, gauge_std = _pressure(recording, pressure_gauge, rig, pressure_gauge_std)
    if gauge is None:
        raise ParameterError("pressure_gauge must be given [Pa gauge] (the recording's metadata states none): the "
                             "bound is evaluated at a known impact on a known stand")
    design = anti_alias_design(recording)
    data = observe(recording, design, contact_time + anti_alias_delay(design, recording.sample_rate))
    layout = make_layout(rig, law, free, pressure_gauge=None if pressure_gauge_unknown else gauge,
                         contact_time=contact_time,
                         sample_rate=recording.sample_rate, pressure_gauge_std=gauge_std)
    point = {**values, "contact_time": contact_time, **stand_values(rig, law, free), "pressure_gauge": gauge}
    cov, _ = covariance(weighted_jacobian(data, layout, point))
    return _bound_of(cov, values["mass"], values["velocity"], law=law, at=at, unknowns=_unknowns(layout.names))
