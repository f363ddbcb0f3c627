"""Which built-in stand a record that names none was made on: the evidence of each (its best law's BIC), compared
with the stand the fit takes.

A record that names no stand (no ``rig`` in its metadata, no stand fingerprint) and is identified without ``rig``
is fitted on the default stand; a record of another stand can be explained there down to its noise, the fitted
pressure and contact soaking the difference up (white residuals, answers several σ off). The stand is a discrete
choice between models with the same unknowns, so the record itself tells them apart: every other distinct built-in
stand (:data:`~impactometer.rig.PRESETS`, one per fingerprint) is fitted with the same laws and selection
(:func:`.select._fit_laws`), and its best BIC compared with the default's over the same samples.

The threshold (:func:`_threshold`) comes from the noise. Let two stands predict the record with a difference δ
(weighted by the noise σ, after each fit's own unknowns have taken what they can: the difference neither fit
absorbs). Under the right stand A, to first order, ΔBIC = BIC_A − BIC_B = −‖δ‖² + 2 δ·ε with ε the white weighted
noise: a normal of mean −‖δ‖² and σ 2‖δ‖. It exceeds t > 0 with the probability Φ(−(t + ‖δ‖²)/(2‖δ‖)), largest
at ‖δ‖ = √t, where it is Φ(−√t): whatever the two stands' difference, a right stand loses by more than t in at
most Φ(−√t) of its records. A false alarm rate α over m alternative stands (a union bound) gives t =
(Φ⁻¹(1 − α/m))²; α = :data:`STAND_FALSE_ALARM` = 10⁻³ and one alternative give t = 9.55. The χ² differences are
divided by the default fit's χ²/dof where that exceeds 1 (the noise σ of the pre-trigger understated).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import Any

from scipy.stats import norm

from ...errors import IdentificationError
from ...recording import Recording
from ...rig import PRESETS, STAND_KEY, Rig, fingerprint
from ..details import Adequacy
from .adequacy import _assess
from .engine import LawFit, Observed, _least_bic, fit_law, window
from .select import _fit_laws, _Start

#: the fraction of a right stand's records in which another built-in stand may be preferred by chance [-]
STAND_FALSE_ALARM = 1e-3


@dataclass(frozen=True)
class _StandChoice:
    """The stands compared (name -> evidence: best law, its BIC and ΔBIC to the stand taken over common samples) and
    the stand that explains the record better beyond :func:`_threshold` with its fits and model selection (None
    where the stand taken wins); ``assessed``: :func:`.adequacy._assess` of each stand's best fit by stand name, so
    that the answer's stand is not assessed again."""

    compared: dict[str, Any]
    better: Rig | None = None
    fits: dict[str, LawFit] | None = None
    selection: dict[str, dict] | None = None
    assessed: dict[str, tuple[Adequacy, float, float]] | None = None


def _threshold(alternatives: int) -> float:
    """The ΔBIC [-] by which another stand must explain a record better than the one taken, for ``alternatives``
    other stands compared: (Φ⁻¹(1 − α/m))² with α = :data:`STAND_FALSE_ALARM` (module docstring)."""
    return float(norm.isf(STAND_FALSE_ALARM / max(alternatives, 1))) ** 2


def _names_no_stand(recording: Recording) -> bool:
    """True where ``recording``'s metadata names no stand (neither ``rig`` nor :data:`~impactometer.rig.STAND_KEY`)."""
    return recording.metadata.get("rig") is None and recording.metadata.get(STAND_KEY) is None


def _other_stands(rig: Rig) -> list[Rig]:
    """The built-in stands other than ``rig``, one per distinct set of parameters (``drop-stand`` and
    ``drop-stand-pad`` are the same stand)."""
    seen = {fingerprint(rig)}
    others = []
    for preset in PRESETS.values():
        key = fingerprint(preset)
        if key not in seen:
            seen.add(key)
            others.append(preset)
    return others


def _until(data: Observed, fit: LawFit, end: float) -> LawFit:
    """``fit`` refitted on ``data`` up to the instant ``end`` [s] (the shorter span of two stands' fits), from its
    own answer; ``fit`` itself where it read no further."""
    if fit.end <= end:
        return fit
    return fit_law(window(data, end), fit.layout, fit.values, offsets=fit.offsets, information=False)


def _compare_stands(data: Observed, rig: Rig, fits: Mapping[str, LawFit], laws: tuple[str, ...],
                   uncertain: tuple[str, ...] | None, start: _Start, quiet: float) -> _StandChoice | None:
    """Fit the record ``data`` on every other built-in stand (:func:`_other_stands`) with the laws, unknowns and start
    of the fit on ``rig`` (whose whole-record fits are ``fits``) and compare each one's best BIC with ``rig``'s over
    the samples both read; None where ``rig``'s fits failed. A stand better beyond :func:`_threshold` is taken only
    where it explains the record down to its noise (:func:`.adequacy._assess`, ``quiet`` the instant [s] the noise
    was measured up to): a record of a built-in stand is, and one of neither stand (a pad outside every family) can
    be explained better, not well, by another stand's friction and volumes. Whether ``rig`` explains it down to its
    noise is stated too (``compared['stands'][rig.name]['adequate']``): the answer switches stands only where it does
    (:func:`_switches`)."""
    taken = _least_bic(fits.values())
    if taken is None:
        return None
    others = _other_stands(rig)
    limit = _threshold(len(others))
    scale = max(1.0, taken.reduced_chi2)
    assessed = {rig.name: _assess(data, taken, quiet)}
    compared: dict[str, Any] = {rig.name: {"law": taken.law, "bic": taken.bic, "reduced_chi2": taken.reduced_chi2,
                                           "adequate": assessed[rig.name][0].verdict == "adequate", "taken": True}}
    choice = _StandChoice(compared={"stands": compared, "threshold": limit, "false_alarm": STAND_FALSE_ALARM,
                                   "chi2_scale": scale}, assessed=assessed)
    margin = limit
    for other in others:
        other_fits, selection = _fit_laws(data, other, laws, uncertain, start)
        best = _least_bic(other_fits.values())
        if best is None:
            compared[other.name] = {"error": "every contact law's fit failed"}
            continue
        end = min(taken.end, best.end)
        try:
            mine, theirs = _until(data, taken, end), _until(data, best, end)
        except IdentificationError as exc:
            compared[other.name] = {"law": best.law, "error": str(exc)}
            continue
        delta = (mine.bic - theirs.bic) / scale
        assessed[other.name] = _assess(data, best, quiet)
        adequate = assessed[other.name][0].verdict == "adequate"
        compared[other.name] = {"law": best.law, "bic": best.bic, "reduced_chi2": best.reduced_chi2,
                                "residuals": mine.residuals, "delta_bic": delta, "adequate": adequate, "taken": False}
        if delta > margin and adequate:
            margin = delta
            choice = replace(choice, better=other, fits=other_fits, selection=selection)
    if choice.better is not None:
        compared[choice.better.name]["better"] = True
    return choice


def _switches(choice: _StandChoice, rig: Rig) -> bool:
    """Whether the answer is taken on ``choice.better`` instead of ``rig``: only where ``rig``, too, explains the
    record down to its noise, so that the two stands differ by what the fit soaks up (a stand the record names
    nowhere, explained on the wrong one with white residuals). Where ``rig`` does not, the record is of neither
    stand as the model takes them or of the better one: a pad outside every family on the stand taken was explained
    down to its noise by the stiff stand's friction and volumes in 3 of 15 records (``scripts/foreign_pads.py``),
    its answer 3-4.6 σ off. Then ``rig``'s own path (shortened, widened or the robust fall-back) answers, with a
    warning naming the better stand."""
    return choice.better is not None and bool(choice.compared["stands"][rig.name]["adequate"])
