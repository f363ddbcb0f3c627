"""Study ``peak-force``: first contact-pulse peak of the simulator vs the two-body closed form.

A sanity check of the model over the scenario grid: during the first, short contact pulse the piston behaves as a
free body, so the contact is a two-body impact of reduced mass μ = M1·M2/(M1 + M2). Undamped, its peak force is
V0·sqrt(k·μ) for the Kelvin-Voigt spring and k^(2/5)·(5/4·μ·V0²)^(3/5) for the Hertz spring of Hunt-Crossley.
The table compares the simulated peak with the closed form; damping, friction and the gas preload explain the
small differences.
"""

from __future__ import annotations

import numpy as np

from ..identify.pulses import contact_pulses
from ..model import simulate_batch
from ..rig import Rig
from .base import Row, Study, StudyOptions, register, scenario_grid
from .tables import finite_values, group_stats

NAME = "peak-force"


def closed_form_peak_force(rig: Rig, mass, velocity) -> np.ndarray:
    """Undamped two-body peak contact force [N] for impacting mass [kg] and velocity [m/s] on ``rig``."""
    m2 = rig.cylinder.piston_mass
    mu = np.asarray(mass, dtype=float) * m2 / (np.asarray(mass, dtype=float) + m2)
    v0 = np.asarray(velocity, dtype=float)
    k = rig.contact.stiffness
    if rig.contact.law == "hunt-crossley":
        return k ** 0.4 * (1.25 * mu * v0 ** 2) ** 0.6
    return v0 * np.sqrt(k * mu)


def first_pulse_duration(rig: Rig, mass: float) -> float:
    """Undamped first-pulse duration bound [s] used to size the simulated window (Kelvin-Voigt half period)."""
    m2 = rig.cylinder.piston_mass
    mu = mass * m2 / (mass + m2)
    if rig.contact.law == "hunt-crossley":
        return 0.01  # Hertz pulses at these speeds last a few ms; a fixed bound is enough
    return float(np.pi * np.sqrt(mu / rig.contact.stiffness))


def _cases(options: StudyOptions) -> list[Row]:
    return scenario_grid(options)


def _evaluate(cases: list[Row], options: StudyOptions) -> list[Row]:
    rig = options.rig
    mass = np.array([c["mass"] for c in cases])
    velocity = np.array([c["velocity"] for c in cases])
    pressure = np.array([c["pressure_gauge"] for c in cases])
    window = 2.0 * max(first_pulse_duration(rig, m) for m in mass)
    batch = simulate_batch(mass, velocity, pressure, rig, duration=window, sample_rate=1e6,
                           channels=("contact_force",))
    closed = closed_form_peak_force(rig, mass, velocity)
    rows = []
    for i, case in enumerate(cases):
        pulses = contact_pulses(batch.time, batch.data["contact_force"][i])
        simulated = pulses[0].peak_force if pulses else float("nan")
        rows.append({**case, "contact_law": rig.contact.law, "simulated_peak_force": simulated,
                     "closed_form_peak_force": float(closed[i]), "ratio": simulated / float(closed[i]),
                     "ratio_error": simulated / float(closed[i]) - 1.0})
    return rows


def _aggregate(rows: list[Row]) -> list[Row]:
    return group_stats(rows, ("contact_law", "mass"), ("ratio_error",))


def _summary(rows: list[Row]) -> list[Row]:
    err = finite_values(rows, "ratio_error")
    return [{"quantity": "first-pulse peak force, simulated vs closed form V0·sqrt(k·μ) (max deviation)",
             "ours": f"{np.max(np.abs(err)) * 100:.2f} % over {err.size} cases" if err.size else "no data",
             "paper": "model check (no figure)"}]


def _plot(rows: list[Row], options: StudyOptions):
    from .plots import plot_peak_force
    return plot_peak_force(rows)


STUDY = register(Study(name=NAME, title="First-pulse peak force: simulator vs two-body closed form", figure="",
                       cases=_cases, evaluate=_evaluate, aggregate=_aggregate, summary=_summary, plot=_plot,
                       chunk_size=25))
