"""Bring your own stand: calibrate a stand model from a few drops of known mass, and validate it on others.

:func:`calibrate` fits the stand parameters a lab does not know (default: the contact law and its parameters, the
seal friction and both dead volumes) jointly over every drop of a calibration set by maximum likelihood
(:mod:`.joint`, the engine of the model-based identification), chooses the contact-law family by BIC, states each
parameter with its standard error and correlations, names the parameters the drops cannot tell apart with the drop
that would separate them (:mod:`.separation`), and gives a :class:`Calibration` whose stand file loads wherever a
stand is accepted. :func:`validate` (:mod:`.validate`) reproduces held-back drops with a stand and reports how
well.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence
from datetime import UTC, datetime
from pathlib import Path

import numpy as np

from ..errors import IdentificationError, ParameterError, ParameterTypeError, shown
from ..identify.model_fit import MAX_REDUCED_CHI2, MIN_DURATION
from ..identify.model_fit.engine import Residuals, contact_laws, window
from ..identify.model_fit.forward import STAND_PARAMETERS, contact_parameters, free_parameters
from ..identify.model_fit.information import covariance
from ..identify.model_fit.select import SCREEN_MARGIN
from ..recording import Recording
from ..rig import Rig, get_rig, parameter_names
from ..validation import check_flag
from .drops import _ObservedDrop, _read_drops
from .influence import MISFIT_LIMIT, _drop_figures, _inconsistent, _limit, _set_misfit_sigma
from .joint import NUISANCES, SCREEN_STAGE, _Family, _fit_family, _stages_for, _starts
from .result import Calibration, DropFit
from .separation import CORRELATION_LIMIT, _correlation, _flagged, _suggest
from .validate import DropValidation, Validation, _force_nrmse, validate

__all__ = ["calibrate", "validate", "Calibration", "DropFit", "Validation", "DropValidation", "DEFAULT_FIT",
           "VELOCITY_SIGMA", "FIT_DURATION", "MAX_REDUCED_CHI2"]

#: relative σ of a light gate's velocity, the default prior of each drop's V0 [-]
VELOCITY_SIGMA = 0.005
#: the stand parameters fitted by default (``"contact"``: every parameter of the law fitted)
DEFAULT_FIT = ("contact", "friction.force", "cylinder.dead_volume_lower", "cylinder.dead_volume_upper")
#: length of each record fitted after its first contact [s]. Later, where the piston returns to its top stop and
#: the mass leaves the rod, brief grazing contacts come and go with the parameters: the likelihood is not smooth
#: there (a change of 1e-4 in ln k moved one drop's residuals by 4 times their linear prediction) and, at 1 %
#: noise, 100 ms records left dead volumes 10-25 stated σ off while 60 ms records recovered every parameter
#: within 1 σ
FIT_DURATION = 0.06
#: fewest drops of a calibration set, and fitted stand parameters per drop at most
MIN_DROPS = 3
PARAMETERS_PER_DROP = 2


def _check_fit(fit: Sequence[str] | str | None) -> tuple[str, ...]:
    """The stand parameters to fit, checked: dotted names of :data:`STAND_PARAMETERS`, ``"contact"`` (every
    parameter of the law) and ``"default"`` (:data:`DEFAULT_FIT`). ParameterError names an unknown parameter or
    one the fit cannot free, with the ones it can."""
    if fit is None:
        return DEFAULT_FIT
    fittable = ["default", "contact", *STAND_PARAMETERS]
    if isinstance(fit, str):
        fit = [name.strip() for name in fit.split(",") if name.strip()]
    if not isinstance(fit, (Sequence, set, frozenset)) or not all(isinstance(n, str) for n in fit):
        raise ParameterTypeError(f"fit must be stand parameter names (a str or a sequence of str), got {shown(fit)}",
                                 field="fit", expected=f"must be names of {fittable}")
    names: list[str] = []
    for name in fit:
        if name == "default":
            names += DEFAULT_FIT
        elif name in fittable:
            names.append(name)
        elif name in parameter_names() or name in ("contact.law", "valve.law", "name"):
            raise ParameterError(f"fit names {name!r}, a stand parameter the calibration cannot fit; it fits "
                                 f"{fittable}", field="fit", expected=f"cannot be fitted; expected any of {fittable}")
        else:
            raise ParameterError(f"fit names an unknown stand parameter {name!r}; expected any of {fittable}",
                                 field="fit", expected=f"unknown parameter {name!r}; expected any of {fittable}")
    if not names:
        raise ParameterError(f"fit must name at least one stand parameter, got {shown(fit)}", field="fit",
                             expected="at least one stand parameter")
    return tuple(dict.fromkeys(names))


def _check_types(contact: object, name: object, progress: object, drop_outliers: object) -> None:
    """ParameterTypeError for an argument of :func:`calibrate` of the wrong type, before any work."""
    if contact is not None and not isinstance(contact, str):
        raise ParameterTypeError(f"contact must be 'auto' or a contact-law name (str), got {shown(contact)}",
                                 field="contact", expected="must be 'auto' or a contact-law name")
    if name is not None and not isinstance(name, str):
        raise ParameterTypeError(f"name must be a str (the calibrated stand's name), got {shown(name)}",
                                 field="name", expected="must be a str")
    if progress is not None and not callable(progress):
        raise ParameterTypeError(f"progress must be a function called with (stages done, stages in all), or None, "
                                 f"got {shown(progress)}", field="progress", expected="must be a function or None")
    check_flag("drop_outliers", drop_outliers, error=ParameterTypeError)


def _excluded(recordings: Sequence[Recording], exclude: Sequence[str | int] | str | int | None) -> list[int]:
    """Indices of the recordings ``exclude`` names (by index, file name or source); ParameterError naming one that
    is not in the set, with the ones that are."""
    if exclude is None:
        return []
    if isinstance(exclude, (str, int)) and not isinstance(exclude, bool):
        exclude = [exclude]
    if not isinstance(exclude, Sequence) or not all(isinstance(e, (str, int)) and not isinstance(e, bool)
                                                    for e in exclude):
        raise ParameterTypeError(f"exclude must be file names or indices of the drops, got {shown(exclude)}",
                                 field="exclude", expected="must be file names or indices of the drops")
    sources = [str(r.source) for r in recordings]
    out = []
    for item in exclude:
        found = [i for i, source in enumerate(sources) if item in (source, Path(source).name)] \
            if isinstance(item, str) else ([item] if -len(sources) <= item < len(sources) else [])
        if not found:
            raise ParameterError(f"exclude names {item!r}, not a drop of the set; its drops: "
                                 f"{[Path(p).name for p in sources]}", field="exclude",
                                 expected=f"must name drops of the set ({len(sources)} drops)")
        out += [i % len(sources) for i in found]
    return sorted(set(out))


def _check_options(velocity_sigma: float, duration: float | None) -> None:
    if not (isinstance(velocity_sigma, (int, float)) and 0.0 < velocity_sigma <= 0.2):
        raise ParameterError(f"velocity_sigma must be a fraction in (0, 0.2] [-], got {shown(velocity_sigma)}",
                             field="velocity_sigma", expected="must be a fraction in (0, 20 %]")
    if duration is not None and not (isinstance(duration, (int, float)) and math.isfinite(duration)
                                     and duration >= MIN_DURATION):
        raise ParameterError(f"duration must be >= {MIN_DURATION:g} [s] (or None: whole records), got "
                             f"{shown(duration)}", field="duration", expected=f"must be >= {MIN_DURATION:g} s")


def _check_count(drops: Sequence[_ObservedDrop], laws: Sequence[str], names: tuple[str, ...]) -> tuple[str, ...]:
    """The laws of ``laws`` whose families the drops have enough of to fit (at least MIN_DROPS, and one drop per
    PARAMETERS_PER_DROP parameters); IdentificationError when there is none."""
    counts = {law: len(free_parameters(law, names)) for law in laws}
    kept = tuple(law for law, count in counts.items()
                 if len(drops) >= max(MIN_DROPS, math.ceil(count / PARAMETERS_PER_DROP)))
    if not kept:
        fewest = min(counts.values())
        need = max(MIN_DROPS, math.ceil(fewest / PARAMETERS_PER_DROP))
        raise IdentificationError(f"the calibration set holds {len(drops)} drop(s); fitting {fewest} stand "
                                  f"parameters needs at least {need} (at least {MIN_DROPS}, and one drop per "
                                  f"{PARAMETERS_PER_DROP} parameters)")
    return kept


def check_inputs(recordings: Sequence[Recording], *, rig: Rig | str | None = None,
                 fit: Sequence[str] | str | None = None, contact: str | None = "auto",
                 velocity_sigma: float = VELOCITY_SIGMA, duration: float | None = FIT_DURATION,
                 name: str | None = None, progress: Callable[[int, int], None] | None = None,
                 exclude: Sequence[str | int] | str | int | None = None, drop_outliers: bool = False):
    """Check the input of :func:`calibrate` before any fit (the errors it raises are :func:`calibrate`'s); returns
    the base stand, the parameters fitted, the laws and the drops (those ``exclude`` names left out)."""
    _check_types(contact, name, progress, drop_outliers)
    base = get_rig(rig)
    names = _check_fit(fit)
    laws = contact_laws(contact)
    for law in laws:  # a contact parameter named must belong to a law fitted
        unknown = [n for n in names if n.startswith("contact.") and n not in contact_parameters(law)]
        if len(laws) == 1 and unknown:
            raise ParameterError(f"fit names {unknown[0]!r}, not a parameter of the {law} law; its parameters: "
                                 f"{list(contact_parameters(law))}", field="fit",
                                 expected=f"not a parameter of the {law} contact law")
    _check_options(velocity_sigma, duration)
    if not isinstance(recordings, Sequence) or isinstance(recordings, (str, bytes)):
        raise ParameterTypeError(f"recordings must be a sequence of Recording, got {shown(recordings)}",
                                 field="recordings", expected="must be a sequence of Recording")
    left_out = _excluded(recordings, exclude)
    drops = _read_drops([r for i, r in enumerate(recordings) if i not in left_out])
    return base, names, _check_count(drops, laws, names), drops


def calibrate(recordings: Sequence[Recording], *, rig: Rig | str | None = None,
              fit: Sequence[str] | str | None = None, contact: str | None = "auto",
              velocity_sigma: float = VELOCITY_SIGMA, duration: float | None = FIT_DURATION,
              name: str | None = None, progress: Callable[[int, int], None] | None = None,
              exclude: Sequence[str | int] | str | int | None = None, drop_outliers: bool = False) -> Calibration:
    """Calibrate a stand from drops of known M1, V0 (a light gate's) and p0.

    Parameters
    ----------
    recordings : sequence of Recording
        The drops (contact force [N], piston acceleration [m/s²], a pre-trigger), each with ``mass_kg``,
        ``velocity_m_s`` and ``pressure_gauge_Pa`` in its metadata (:func:`impactometer.io.read_calibration_set`
        puts the manifest's there); recordings of one stand.
    rig : Rig or str, optional
        The base stand: its geometry, piston mass and gas are taken as known, its values of the fitted parameters
        start the fit (a preset name or a TOML file; default ``drop-stand``).
    fit : sequence of str or str, optional
        Stand parameters fitted (:func:`_check_fit`; default :data:`DEFAULT_FIT`), e.g.
        ``["default", "cylinder.piston_mass"]``.
    contact : str, optional
        ``"auto"`` (every contact-law family, the smallest BIC kept) or one law.
    velocity_sigma : float
        Relative σ of the light-gate velocities [-] (the prior of each drop's V0).
    duration : float or None
        Length of each record fitted after its first contact [s] (see :data:`FIT_DURATION`); None: whole records.
    name : str, optional
        Name of the calibrated stand (default the base's with ``-calibrated``).
    progress : callable, optional
        Called with (stages done, stages in all).
    exclude : sequence of str or int, optional
        Drops left out of the fit: file names (or sources) or indices into ``recordings``.
    drop_outliers : bool
        Fit the stand once more without the drops named inconsistent with the others
        (:mod:`impactometer.calibrate.influence`), and return that fit (``excluded`` says which and why).

    Returns
    -------
    Calibration

    Raises
    ------
    ParameterError
        For an unknown or unfittable parameter, a base stand that does not load, another bad option (a
        ParameterTypeError, also a TypeError, for an argument of the wrong type).
    RecordingError
        For a drop without its truth, a truth stated in another unit (a pressure in kPa, a mass in lb, a velocity
        in km/h), one drop given twice, drops of different stands, a recording the fit cannot use.
    IdentificationError
        For fewer drops than the parameters need, or when every family's fit fails.
    """
    base, names, laws, drops = check_inputs(recordings, rig=rig, fit=fit, contact=contact,
                                            velocity_sigma=velocity_sigma, duration=duration, name=name,
                                            progress=progress, exclude=exclude, drop_outliers=drop_outliers)
    asked = tuple({"file": str(recordings[i].source), "reason": "left out by exclude"}
                  for i in _excluded(recordings, exclude))
    result = _calibrate(drops, base, names, laws, velocity_sigma=velocity_sigma, duration=duration, name=name,
                        progress=progress)
    named = [i for i, d in enumerate(result.drops) if d.inconsistent]
    if not drop_outliers or not named:
        return dataclasses.replace(result, excluded=asked)
    rest = [d for i, d in enumerate(drops) if i not in named]
    again = _calibrate(rest, base, names, _check_count(rest, laws, names), velocity_sigma=velocity_sigma,
                       duration=duration, name=name, progress=progress)
    reasons = tuple({"file": d.source, "reason": d.verdict()} for d in result.drops if d.inconsistent)
    return dataclasses.replace(again, excluded=(*asked, *reasons), warnings=(
        *again.warnings, *(f"{r['file']} left out (drop_outliers): {r['reason']}" for r in reasons)))


def _calibrate(drops: Sequence[_ObservedDrop], base: Rig, names: tuple[str, ...], laws: Sequence[str], *,
               velocity_sigma: float, duration: float | None, name: str | None,
               progress: Callable[[int, int], None] | None) -> Calibration:
    """The calibration of checked drops (see :func:`calibrate`)."""
    stages = _stages_for(duration)
    total, done = len(laws) * len(stages), 0

    def step() -> None:
        nonlocal done
        done += 1
        if progress is not None:
            progress(done, total)

    families, report = _fit_families(drops, base, laws, names, velocity_sigma, stages, step)
    if not families:
        raise IdentificationError("no contact-law family could be fitted to the drops: " + "; ".join(
            f"{law}: {entry.get('error')}" for law, entry in report.items()))
    best = min(families.values(), key=lambda f: f.bic)
    return _result(best, drops, base, report, velocity_sigma=velocity_sigma, duration=duration, name=name)


def _fit_families(drops: Sequence[_ObservedDrop], base: Rig, laws: Sequence[str], names: tuple[str, ...],
                  velocity_sigma: float, stages, step: Callable[[], None]) -> tuple[dict[str, _Family], dict]:
    """Each family through the screening window, the ones within ``SCREEN_MARGIN`` of the best BIC to the end.

    Each family is screened from the stand's own values first; a family with further starts
    (:func:`.joint._starts`) is screened from those too, the lowest χ² kept, where it is a contender (its BIC within
    ``SCREEN_MARGIN`` of the best) or no family explains the drops (χ²/dof ≤ :data:`MAX_REDUCED_CHI2` on the
    screening window): a second minimum cannot matter to a family the data has already ruled out by far."""
    screened: dict[str, tuple[_Family, np.ndarray]] = {}
    errors: dict[str, list[str]] = {law: [] for law in laws}
    report: dict[str, dict] = {}
    head, tail = stages[:SCREEN_STAGE + 1], stages[SCREEN_STAGE + 1:]
    starts = {law: _starts(base, law, free_parameters(law, names)) for law in laws}

    def screen_from(law: str, start: dict[str, float], progress: Callable[[], None] | None) -> None:
        try:
            fit = _fit_family(drops, base, law, free_parameters(law, names), velocity_sigma=velocity_sigma,
                              stages=head, final=not tail, progress=progress, start=start)
        except IdentificationError as exc:
            errors[law].append(str(exc))
            return
        if law not in screened or fit[0].chi2 < screened[law][0].chi2:
            screened[law] = fit

    for law in laws:  # the progress counts the stand's own start
        screen_from(law, starts[law][0], step)
    explained = any(family.reduced_chi2 <= MAX_REDUCED_CHI2 for family, _ in screened.values())
    lowest = min((family.bic for family, _ in screened.values()), default=math.inf)
    for law in laws:
        if not explained or law in screened and screened[law][0].bic <= lowest + SCREEN_MARGIN:
            for start in starts[law][1:]:
                screen_from(law, start, None)
    for law in laws:
        if law not in screened:
            report[law] = {"error": "; ".join(dict.fromkeys(errors[law]))}
    families: dict[str, _Family] = {}
    if not screened:
        return families, report
    lowest = min(family.bic for family, _ in screened.values())
    window_ms = (head[-1][0] or 0.0) * 1e3
    for law, (family, x) in screened.items():
        screen = {"screen_window_ms": window_ms, "screen_bic": family.bic,
                  "screen_reduced_chi2": family.reduced_chi2}
        if family.bic > lowest + SCREEN_MARGIN or not tail:
            if tail:
                report[law] = {**screen, "dropped": f"BIC on the first {window_ms:g} ms exceeds the best family's "
                                                    f"by {family.bic - lowest:.4g} > {SCREEN_MARGIN:g}"}
                continue
            families[law] = family
        else:
            try:
                families[law], _ = _fit_family(drops, base, law, family.free, velocity_sigma=velocity_sigma,
                                              stages=tail, x0=x, progress=step)
            except IdentificationError as exc:
                report[law] = {**screen, "error": str(exc)}
                continue
        report[law] = {**families[law].summary(), **screen, "parameters": list(family.free)}
    return families, report


def _result(best: _Family, drops: Sequence[_ObservedDrop], base: Rig, report: dict, *, velocity_sigma: float,
            duration: float | None, name: str | None) -> Calibration:
    """The :class:`Calibration` of the chosen family."""
    cov, rank = covariance(best.root)
    inflation = math.sqrt(max(1.0, best.reduced_chi2))
    s = len(best.free)
    layout = best.layouts[0]
    values = layout.values(best.local(0))
    parameters = {n: values[n] for n in best.free}
    std = {n: abs(layout.derivative(n, float(best.x[j]))) * math.sqrt(cov[j, j]) * inflation
           for j, n in enumerate(best.free)}
    warnings = []
    misfit = _set_misfit_sigma(best, drops)
    if best.reduced_chi2 > MAX_REDUCED_CHI2:
        warnings.append(f"the best family ({best.law}) leaves chi2/dof = {best.reduced_chi2:.3g} > "
                        f"{MAX_REDUCED_CHI2:g}: the stand model does not describe these drops")
    elif misfit > MISFIT_LIMIT:
        warnings.append(f"the best family ({best.law}) leaves chi2/dof = {best.reduced_chi2:.4g}, {misfit:.3g} "
                        f"sigma beyond what the noise explains (limit {MISFIT_LIMIT:g}): the stand model does not "
                        "describe these drops")
    if not best.converged:
        warnings.append(f"the {best.law} fit stopped after {best.evaluations} evaluations before it converged")
    pairs, lost = _flagged(best.free, cov[:s, :s])
    if rank < best.unknowns:
        warnings.append(f"the drops determine {rank} of the {best.unknowns} unknowns only")
    hint = _suggest(best, drops, base, pairs, velocity_sigma=velocity_sigma, end=duration)
    indistinct = [{"parameters": [a, b], "correlation": c, "limit": CORRELATION_LIMIT, "suggestion": hint}
                  for a, b, c in pairs]
    indistinct += [{"parameters": [n], "undetermined": True, "suggestion": None} for n in lost]
    figures = _drop_figures(best, drops, velocity_sigma=velocity_sigma, duration=duration)
    named = _inconsistent(figures)
    fits = []
    for i, drop in enumerate(drops):
        data = drop.data if duration is None else window(drop.data, drop.contact_time + duration)
        local = best.local(i)
        own = best.layouts[i].values(local)
        simulated = Residuals(data, best.layouts[i]).predicted(local)
        j = s + len(NUISANCES) * i
        fits.append(DropFit(source=drop.source, mass=drop.mass, pressure_gauge=drop.pressure_gauge,
                            velocity_gate=drop.velocity,
                            velocity=own["velocity"],
                            velocity_std=own["velocity"] * math.sqrt(cov[j, j]) * inflation,
                            contact_time=own["contact_time"], offsets=tuple(local[-2:] * data.noise),
                            reduced_chi2=best.drop_reduced_chi2(i), time=data.grid.start_time + np.arange(
                                data.grid.size) / data.grid.sample_rate, measured=data.channels,
                            simulated=simulated, force_nrmse=_force_nrmse(data, simulated, own["contact_time"])[0],
                            **figures[i], inconsistent=i in named, limit=_limit(len(drops))))
        if fits[-1].inconsistent:
            warnings.append(f"{drop.source} is inconsistent with the other drops: {fits[-1].verdict()}; check its "
                            "mass, velocity, pressure and stand (drop_outliers / --drop-outliers fits without it)")
        elif fits[-1].reduced_chi2 > MAX_REDUCED_CHI2:
            warnings.append(f"{drop.source}: chi2/dof = {fits[-1].reduced_chi2:.3g} > {MAX_REDUCED_CHI2:g}: the "
                            "calibrated stand does not reproduce this drop")
    stand = base if base.contact.law == best.law else base.with_contact(best.law)
    stand = stand.replace(name=name or f"{base.name}-calibrated", **parameters)
    criterion = (f"BIC = chi2 + k ln N over every drop; families more than {SCREEN_MARGIN:g} above the best on "
                 "the screening window dropped")
    return Calibration(rig=stand, base=base.name, law=best.law, parameters=parameters, std=std,
                       correlation=_correlation(cov[:s, :s]), reduced_chi2=best.reduced_chi2, chi2=best.chi2,
                       dof=best.dof, bic=best.bic, inflation=inflation, families=report, criterion=criterion,
                       drops=tuple(fits), indistinct=tuple(indistinct), warnings=tuple(warnings),
                       velocity_sigma=velocity_sigma, duration=duration,
                       created=datetime.now(UTC).replace(microsecond=0).isoformat(),
                       max_reduced_chi2=MAX_REDUCED_CHI2, misfit_sigma=misfit, misfit_limit=MISFIT_LIMIT)

