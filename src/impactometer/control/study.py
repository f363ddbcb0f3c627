"""The absorber over a grid of impacts: every strategy, identified and oracle, side by side (one row each).

Used by ``impactometer study absorption`` (the studies package) and by ``scripts/absorption_acceptance.py``.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np

from ..errors import ParameterError
from ..rig import Rig, Scenario, get_rig
from .loop import absorb
from .valve import Absorber

#: the paper's scenario ranges: M1 [kg], V0 [m/s], p0 [Pa gauge]
RANGES = {"mass": (10.0, 50.0), "velocity": (1.0, 3.0), "pressure_gauge": (20e3, 400e3)}
#: label of the oracle run of the real-time strategy
ORACLE = "realtime (oracle)"


def grid_cases(points: int = 5) -> list[dict[str, float]]:
    """The M1 × V0 × p0 grid over the paper's ranges, ``points`` values per axis (5 gives the 125 cases)."""
    if isinstance(points, bool) or not isinstance(points, (int, np.integer)) or points < 1:
        raise ParameterError(f"points must be an integer >= 1, got {points!r}")
    axes = [np.linspace(*RANGES[name], points) if points > 1 else np.array([np.mean(RANGES[name])])
            for name in ("mass", "velocity", "pressure_gauge")]
    return [{"mass": float(m), "velocity": float(v), "pressure_gauge": float(p)}
            for m in axes[0] for v in axes[1] for p in axes[2]]


def case_rows(case: dict[str, float], rig: Rig, *, noise: float, seed: int, identification: str,
              absorber: Absorber | None, sample_rate: float) -> list[dict[str, Any]]:
    """Rows of one case: ``closed``, ``constant`` and ``realtime`` with the identified M1 and V0, and the real-time
    strategy with the oracle, started at the same instant."""
    scenario = Scenario(mass=case["mass"], velocity=case["velocity"], pressure_gauge=case["pressure_gauge"])
    identified = absorb(scenario, rig, strategy="all", identification=identification, noise=noise, seed=seed,
                        absorber=absorber, sample_rate=sample_rate)
    start = identified.control_start if math.isfinite(identified.control_start) else None
    oracle = absorb(scenario, rig, strategy="realtime", identification="oracle", noise=noise, seed=seed,
                    absorber=absorber, sample_rate=sample_rate, control_start=start)
    rows = []
    for result, label in ((identified, None), (oracle, ORACLE)):
        summary = result.to_dict()
        ident = summary["identification"]
        for name, metrics in summary["strategies"].items():
            rows.append({"mass_kg": scenario.mass, "velocity_m_s": scenario.velocity,
                         "pressure_gauge_Pa": scenario.pressure_gauge, "strategy": label or name,
                         "identification": ident["method"], "identified_mass_kg": ident["mass_kg"],
                         "identified_velocity_m_s": ident["velocity_m_s"], "identification_error": ident["error"],
                         "valve_area_m2": None, **metrics, "efficiency_max": summary["efficiency_max"],
                         "bound_force_N": summary["bound_force_N"],
                         "first_collision_peak_N": summary["first_collision_peak_N"],
                         "efficiency_first_collision": summary["efficiency_first_collision"],
                         "over_capacity": summary["over_capacity"],
                         "contact_law": rig.contact.law, "noise": noise, "seed": seed})
    return rows


def absorption_table(cases: Iterable[dict[str, float]] | None = None, rig: Rig | str | None = None, *,
                     noise: float = 0.02, seed: int = 0, identification: str = "robust",
                     absorber: Absorber | None = None, sample_rate: float = 50e3) -> list[dict[str, Any]]:
    """Absorb every case with every strategy; one row per case and strategy.

    Parameters
    ----------
    cases : iterable of dict, optional
        Each with ``mass`` [kg], ``velocity`` [m/s], ``pressure_gauge`` [Pa]; default the 125-case grid.
    rig : Rig or str, optional
        The stand (default ``drop-stand``).
    noise : float
        Sensor noise, fraction of each channel's RMS [-].
    seed : int
        Root seed; case ``i`` uses ``seed + i``.
    identification : str
        Identification of the non-oracle runs (see :func:`~impactometer.control.loop.absorb`).
    absorber : Absorber, optional
        Usable stroke, rated force and valve drive.
    sample_rate : float
        Sensor and controller rate [Hz].

    Returns
    -------
    list of dict
        Rows with the case, ``strategy`` (``closed``, ``constant``, ``realtime``, ``realtime (oracle)``), the
        identification, the metrics (``peak_force_controlled_N``, ``efficiency``, ``bottomed_out``, ...) and the
        bound ``efficiency_max``.
    """
    rig = get_rig(rig)
    cases = grid_cases() if cases is None else list(cases)
    rows: list[dict[str, Any]] = []
    for i, case in enumerate(cases):
        missing = {"mass", "velocity", "pressure_gauge"} - set(case)
        if missing:
            raise ParameterError(f"case {i} lacks {sorted(missing)}; expected mass, velocity, pressure_gauge")
        rows += case_rows(case, rig, noise=noise, seed=seed + i, identification=identification,
                          absorber=absorber, sample_rate=sample_rate)
    return rows


def acceptance_summary(rows: Sequence[dict[str, Any]]) -> dict[str, Any]:
    """The acceptance figures of the absorber over ``rows`` of :func:`absorption_table`.

    Medians of the efficiency per strategy and of the bound η_max; cases where the identified real-time strategy
    bottoms out and the oracle does not; the relative difference of the identified and oracle peak force after the
    control start (median and largest; cases where the oracle's mass never touches the rod again after the control
    start are left out).
    """
    by: dict[tuple, dict[str, dict]] = {}
    for row in rows:
        key = (row["mass_kg"], row["velocity_m_s"], row["pressure_gauge_Pa"])
        by.setdefault(key, {})[row["strategy"]] = row

    def median(strategy: str, quantity: str) -> float:
        values = [r[strategy][quantity] for r in by.values() if strategy in r and _finite(r[strategy][quantity])]
        return float(np.median(values)) if values else math.nan

    bound = [r["realtime"]["efficiency_max"] for r in by.values() if "realtime" in r
             and _finite(r["realtime"]["efficiency_max"])]
    extra_bottoming = [key for key, r in by.items() if "realtime" in r and ORACLE in r
                       and r["realtime"]["bottomed_out"] and not r[ORACLE]["bottomed_out"]]
    peak_ratio = [r["realtime"]["peak_force_controlled_N"] / r[ORACLE]["peak_force_controlled_N"] - 1.0
                  for r in by.values() if "realtime" in r and ORACLE in r
                  and _finite(r["realtime"]["peak_force_controlled_N"])
                  and _finite(r[ORACLE]["peak_force_controlled_N"])
                  and r[ORACLE]["peak_force_controlled_N"] > 0.0]
    failed = sum(1 for r in by.values() if any(row["identification_error"] for name, row in r.items()
                                                   if name != ORACLE))
    reference = [r["realtime"]["efficiency_first_collision"] for r in by.values() if "realtime" in r
                 and _finite(r["realtime"].get("efficiency_first_collision"))]
    out = {"cases": len(by), "identification_failed": failed, "efficiency_max_median": float(np.median(bound))
           if bound else math.nan,
           "efficiency_first_collision_median": float(np.median(reference)) if reference else math.nan,
           "bottomed_out_identified_not_oracle": len(extra_bottoming),
           "peak_vs_oracle_median": float(np.median(np.abs(peak_ratio))) if peak_ratio else math.nan,
           "peak_vs_oracle_max": float(np.max(np.abs(peak_ratio))) if peak_ratio else math.nan,
           "peak_vs_oracle_within_10pct": int(np.sum(np.abs(peak_ratio) <= 0.1)) if peak_ratio else 0}
    for strategy in ("closed", "constant", "realtime", ORACLE):
        for quantity in ("efficiency", "efficiency_cfc60", "peak_force_controlled_N", "stroke_used_m"):
            out[f"{strategy}: median {quantity}"] = median(strategy, quantity)
        out[f"{strategy}: bottomed out"] = sum(1 for r in by.values() if strategy in r and r[strategy]["bottomed_out"])
        out[f"{strategy}: rebounded"] = sum(1 for r in by.values() if strategy in r and r[strategy]["rebounded"])
    return out


def _finite(value) -> bool:
    return value is not None and not isinstance(value, bool) and math.isfinite(float(value))


def read_table(path) -> list[dict[str, Any]]:
    """Rows of an absorption table saved as CSV (numbers, booleans and empty cells restored)."""
    import csv

    def value(text: str):
        if text == "":
            return None
        if text in ("True", "False"):
            return text == "True"
        try:
            return float(text)
        except ValueError:
            return text

    with open(path, newline="") as handle:
        return [{key: value(text) for key, text in row.items()} for row in csv.DictReader(handle)]
