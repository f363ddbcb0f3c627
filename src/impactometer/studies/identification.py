"""Shared machinery of the identification studies: simulated recordings, the methods side by side, error rows.

Every identification study compares the peak-to-peak answers per recording: ``paper`` (eqs. 3-5 as published),
``robust-early`` (the robust variant's answer around t11) and ``robust`` (its final answer); the noise and sampling
studies add ``model``, the maximum-likelihood fit of the whole record (:mod:`impactometer.identify.model_fit`),
whose row also says which ``path`` it took (``ml``, or ``fallback`` to the robust answer). A failed identification
(a refusal included) is a row with NaN estimates and the error message, so failures are counted, never dropped.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np

from ..errors import ImpactometerError
from ..recording import Recording
from ..rig import Rig
from ..sensors import apply_sensors, record_batch
from ..tables import finite_values, group_stats, percent_labels, pick
from .base import Row, Setting, StudyOptions, case_seed, relative_error

#: the module the peak-to-peak studies need
REQUIRES = ("impactometer.identify.peak_to_peak",)
#: the modules of the studies that also run the ``model`` method
MODEL_REQUIRES = (*REQUIRES, "impactometer.identify.model_fit")
#: every compared answer, in display order
METHODS = ("paper", "robust-early", "robust", "model")
#: the methods a study may be asked for (``robust`` brings ``robust-early``) -> the answers (rows) each gives
METHOD_ROWS = {"paper": ("paper",), "robust": ("robust-early", "robust"), "model": ("model",)}
#: the peak-to-peak methods (every identification study has them)
PEAK_TO_PEAK = ("paper", "robust")
#: the setting ``STUDY.methods`` of the studies that run the model too, and its default
STUDY_METHODS = Setting("choices", choices=tuple(METHOD_ROWS))
DEFAULT_METHODS = ["paper", "robust", "model"]


def clean_recordings(cases: Sequence[Row], options: StudyOptions, *, sample_rate: float | None = None
                     ) -> list[Recording]:
    """Noise-free recordings of ``cases`` (mass, velocity, pressure_gauge) at ``sample_rate`` [Hz]."""
    return record_batch(np.array([c["mass"] for c in cases]), np.array([c["velocity"] for c in cases]),
                        np.array([c["pressure_gauge"] for c in cases]), options.rig,
                        sample_rate=options.sample_rate if sample_rate is None else sample_rate,
                        duration=options.duration, pre_trigger=options.pre_trigger, noise=0.0)


def with_noise(recording: Recording, noise: Mapping[str, float], seed) -> Recording:
    """``recording`` with Gaussian noise per channel (fractions of each channel's RMS after first contact)."""
    if not any(level > 0 for level in noise.values()):
        return recording
    return apply_sensors(recording, noise=dict(noise), seed=seed)


def methods_of(options: StudyOptions, study: str) -> tuple[str, ...]:
    """The methods ``study`` runs under ``options`` (setting ``methods``), in :data:`METHOD_ROWS` order."""
    chosen = options.param(study, "methods", DEFAULT_METHODS)
    return tuple(m for m in METHOD_ROWS if m in chosen)


def _row(case: Row, method: str, mass: float, velocity: float, available_at: float, failure: str,
         **more) -> Row:
    return {**case, "method": method, "mass_estimate": mass, "velocity_estimate": velocity,
            "mass_error": relative_error(mass, case["mass"]), "velocity_error": relative_error(velocity,
                                                                                              case["velocity"]),
            "available_at": available_at, "failure": failure, **more}


def _failure(exc: Exception) -> str:
    return f"{type(exc).__name__}: {exc}"[:200]


def identify_rows(recording: Recording, case: Row, methods: Sequence[str] = PEAK_TO_PEAK, *,
                  rig: Rig | None = None) -> list[Row]:
    """One row per answer of ``methods`` (see :data:`METHOD_ROWS`) for ``recording`` of the scenario ``case``.

    ``rig`` is the stand the ``model`` method fits (default: the built-in one); its pre-charge comes from the
    recording's metadata, as a lab knows the pressure it charged.
    """
    from ..identify.peak_to_peak import identify  # lazily: one of REQUIRES, absent from some trees

    nan = math.nan
    rows = []
    for variant in (m for m in PEAK_TO_PEAK if m in methods):
        try:
            result = identify(recording, variant=variant)
        except ImpactometerError as exc:
            rows += [_row(case, name, nan, nan, nan, _failure(exc)) for name in METHOD_ROWS[variant]]
            continue
        if variant == "robust":
            early = result.early
            rows.append(_row(case, "robust-early", early.mass, early.velocity, early.available_at, "")
                        if early is not None else _row(case, "robust-early", nan, nan, nan, "no early answer"))
        rows.append(_row(case, variant, result.mass, result.velocity, result.available_at, ""))
    if "model" in methods:
        rows.append(model_row(recording, case, rig=rig))
    return rows


def model_row(recording: Recording, case: Row, *, rig: Rig | None = None) -> Row:
    """The ``model`` row of ``recording``: the fit's answer and its ``path`` (``ml`` or ``fallback``), or a
    failure (a record the fit refuses, no answer) with an empty path."""
    from ..identify.model_fit import identify  # lazily: one of MODEL_REQUIRES

    try:
        result = identify(recording, rig=rig)
    except ImpactometerError as exc:
        return _row(case, "model", math.nan, math.nan, math.nan, _failure(exc), path="")
    return _row(case, "model", result.mass, result.velocity, result.available_at, "",
                path=str(result.details.get("path", "")))


def by_method(rows: Sequence[Row], by: Sequence[str] = ()) -> list[Row]:
    """Mean/max |mass error| and |velocity error| [%] per method (and per ``by`` columns)."""
    return percent_labels(group_stats(rows, (*by, "method"), ("mass_error", "velocity_error")))


def mean_abs(rows: Sequence[Row], column: str, **equal) -> float:
    """Mean |column| [%] over rows matching ``equal`` (NaN when none is finite)."""
    values = finite_values(pick(rows, **equal), column)
    return float(np.mean(np.abs(values))) * 100 if values.size else math.nan


def max_abs(rows: Sequence[Row], column: str, **equal) -> float:
    """Max |column| [%] over rows matching ``equal`` (NaN when none is finite)."""
    values = finite_values(pick(rows, **equal), column)
    return float(np.max(np.abs(values))) * 100 if values.size else math.nan


def failures(rows: Sequence[Row], **equal) -> int:
    """Number of failed identifications among rows matching ``equal``."""
    return sum(1 for r in pick(rows, **equal) if r.get("failure"))


def fallbacks(rows: Sequence[Row], **equal) -> int:
    """Number of ``model`` answers that fell back to the robust one among rows matching ``equal``."""
    return sum(1 for r in pick(rows, method="model", **equal) if r.get("path") == "fallback")


def per_method(rows: Sequence[Row], text) -> str:
    """``text(method)`` joined over the methods present, e.g. 'paper 3.1 %; robust 0.2 %'."""
    present = [m for m in METHODS if pick(rows, method=m)]
    return "; ".join(f"{m} {text(m)}" for m in present)


def failure_line(rows: Sequence[Row]) -> Row:
    """Summary line: failed identifications per method (means above are over the successful ones)."""
    return {"quantity": "failed identifications (excluded from the means above)",
            "ours": per_method(rows, lambda m: f"{failures(rows, method=m)} of {len(pick(rows, method=m))}"),
            "paper": "not stated"}


def fallback_line(rows: Sequence[Row]) -> Row:
    """Summary line: ``model`` answers that are the robust one (the model did not describe the record)."""
    return {"quantity": "model answers that fell back to the robust one (counted in the means above)",
            "ours": f"{fallbacks(rows)} of {len(pick(rows, method='model'))}", "paper": "–"}


def with_failures(summary):
    """``summary`` followed by the :func:`failure_line` of the same rows (and the :func:`fallback_line` where the
    model was run)."""
    def lines(rows: Sequence[Row]) -> list[Row]:
        return [*summary(rows), failure_line(rows), *([fallback_line(rows)] if pick(rows, method="model") else [])]
    return lines


def pct(value: float) -> str:
    """A percentage for the summary."""
    return "–" if not math.isfinite(value) else f"{value:.3g} %"


def evaluate_noisy(study: str, cases: Sequence[Row], options: StudyOptions) -> list[Row]:
    """Rows of ``cases`` recorded at ``options.sample_rate`` with ``options.noise`` on both channels.

    Each case's noise comes from :func:`case_seed` (root seed, study, case index) only.
    """
    rows = []
    for case, clean in zip(cases, clean_recordings(cases, options), strict=False):
        level = options.noise
        recording = with_noise(clean, {"contact_force": level, "piston_acceleration": level},
                               case_seed(options, study, case["case"]))
        rows += identify_rows(recording, {**case, "noise": level})
    return rows


def seeded_grid(scenarios: Sequence[Row], options: StudyOptions) -> list[Row]:
    """``scenarios`` repeated for each noise realisation (``seed_index`` 0 .. seeds-1)."""
    return [{**s, "seed_index": k} for k in range(options.seeds) for s in scenarios]
