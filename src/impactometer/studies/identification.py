"""Shared machinery of the peak-to-peak studies: simulated recordings, both variants side by side, error rows.

Every peak-to-peak study compares three answers per recording: ``paper`` (eqs. 3-5 as published), ``robust-early``
(the robust variant's answer around t11) and ``robust`` (its final answer). A failed identification is a row
with NaN estimates and the error message, so failures are counted, never dropped.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np

from ..errors import ImpactometerError
from ..recording import Recording
from ..sensors import apply_sensors, record_batch
from .base import Row, StudyOptions, case_seed, relative_error
from .tables import finite_values, group_stats, percent_labels, pick

#: the module the peak-to-peak studies need
REQUIRES = ("impactometer.identify.peak_to_peak",)
#: compared answers, in display order
METHODS = ("paper", "robust-early", "robust")


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


def _row(case: Row, method: str, mass: float, velocity: float, available_at: float, failure: str) -> Row:
    return {**case, "method": method, "mass_estimate": mass, "velocity_estimate": velocity,
            "mass_error": relative_error(mass, case["mass"]), "velocity_error": relative_error(velocity,
                                                                                              case["velocity"]),
            "available_at": available_at, "failure": failure}


def identify_rows(recording: Recording, case: Row) -> list[Row]:
    """One row per compared answer (see :data:`METHODS`) for ``recording`` of the scenario ``case``."""
    from ..identify.peak_to_peak import identify  # lazily: one of REQUIRES, absent from some trees

    nan = math.nan
    rows = []
    for variant in ("paper", "robust"):
        try:
            result = identify(recording, variant=variant)
        except ImpactometerError as exc:
            message = f"{type(exc).__name__}: {exc}"[:200]
            names = ("robust-early", "robust") if variant == "robust" else ("paper",)
            rows += [_row(case, name, nan, nan, nan, message) for name in names]
            continue
        if variant == "robust":
            early = result.early
            rows.append(_row(case, "robust-early", early.mass, early.velocity, early.available_at, "")
                        if early is not None else _row(case, "robust-early", nan, nan, nan, "no early answer"))
        rows.append(_row(case, variant, result.mass, result.velocity, result.available_at, ""))
    return rows


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


def per_method(rows: Sequence[Row], text) -> str:
    """``text(method)`` joined over the methods present, e.g. 'paper 3.1 %; robust 0.2 %'."""
    present = [m for m in METHODS if pick(rows, method=m)]
    return "; ".join(f"{m} {text(m)}" for m in present)


def failure_line(rows: Sequence[Row]) -> Row:
    """Summary line: failed identifications per method (means above are over the successful ones)."""
    return {"quantity": "failed identifications (excluded from the means above)",
            "ours": per_method(rows, lambda m: f"{failures(rows, method=m)} of {len(pick(rows, method=m))}"),
            "paper": "not stated"}


def with_failures(summary):
    """``summary`` followed by the :func:`failure_line` of the same rows."""
    def lines(rows: Sequence[Row]) -> list[Row]:
        return [*summary(rows), failure_line(rows)]
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
