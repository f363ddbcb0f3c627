"""Study ``peak-force``: first contact-pulse peak of the simulator and of the DAQ vs the two-body closed form.

A sanity check of the model over the scenario grid: during the first, short contact pulse the piston behaves as a
free body held up by a constant preload (gas force and friction), so the contact is a two-body impact of reduced
mass μ = M1·M2/(M1 + M2). Undamped and without preload its peak force is V0·sqrt(k·μ) for the Kelvin-Voigt
spring and k^(2/5)·(5/4·μ·V0²)^(3/5) for the Hertz spring of Hunt-Crossley; the preload adds a few percent.
The table compares the simulated peak (1 MHz) with the closed form -- contact damping explains the remaining
difference -- and with the peak a DAQ records at ``options.sample_rate`` with the base noise
(anti-alias filter, sampling and noise lower or raise it: what the response map's ``peaks`` features see).
"""

from __future__ import annotations

import numpy as np

from ..errors import ParameterError
from ..model import simulate_batch
from ..rig import Rig
from ..sensors import record_batch
from ..signals.pulses import contact_pulses
from ..tables import finite_values, group_stats, percent_labels
from .base import Row, Study, StudyOptions, case_seed, plotted_by, register, scenario_grid

NAME = "peak-force"


def piston_preload(rig: Rig, pressure_gauge) -> np.ndarray:
    """Force holding the piston up when the contact starts [N]: net gas force (or the piston weight when the gas
    cannot hold it at the top stop) plus Coulomb friction once it moves."""
    p0 = np.asarray(pressure_gauge, dtype=float)
    return np.maximum(p0 * rig.cylinder.rod_area, rig.cylinder.piston_mass * rig.gravity) + rig.friction.force


def closed_form_peak_force(rig: Rig, mass, velocity, pressure_gauge=0.0) -> np.ndarray:
    """Undamped two-body peak contact force [N] for impacting mass [kg], velocity [m/s] and charge pressure.

    The relative motion obeys μ·δ'' = −F(δ) + μ·F0/M2 with the piston preload F0 (:func:`piston_preload`), so the
    maximum compression solves ½·μ·V0² + μ·F0/M2·δ = E(δ) with the spring energy E = ½·k·δ² (Kelvin-Voigt) or
    (2/5)·k·δ^(5/2) (Hertz spring of Hunt-Crossley). Without preload this is V0·sqrt(k·μ) and
    k^(2/5)·(5/4·μ·V0²)^(3/5).
    """
    try:
        m1, v0, p0 = np.broadcast_arrays(np.asarray(mass, dtype=float), np.asarray(velocity, dtype=float),
                                         np.asarray(pressure_gauge, dtype=float))
    except (TypeError, ValueError):
        raise ParameterError(f"mass, velocity and pressure_gauge must be numbers or arrays of one shape, got "
                             f"{mass!r}, {velocity!r}, {pressure_gauge!r}") from None
    for name, values, low in (("mass", m1, 0.0), ("velocity", v0, None), ("pressure_gauge", p0, None)):
        if not np.all(np.isfinite(values)) or np.any(values < 0) or (low is not None and np.any(values <= low)):
            raise ParameterError(f"{name} must be finite and {'> 0' if low is not None else '>= 0'}, got {values!r}")
    m2 = rig.cylinder.piston_mass
    mu = m1 * m2 / (m1 + m2)
    k = rig.contact.stiffness
    push = mu * piston_preload(rig, p0) / m2  # [N]
    if rig.contact.law != "hunt-crossley":
        return push + np.sqrt(push ** 2 + k * mu * v0 ** 2)
    energy = 0.5 * mu * v0 ** 2
    delta = (energy / (0.4 * k)) ** 0.4  # no-preload compression, then Newton on the energy balance
    for _ in range(50):
        residual = 0.4 * k * delta ** 2.5 - push * delta - energy
        delta = delta - residual / (k * delta ** 1.5 - push)
    return k * delta ** 1.5


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
    recordings = record_batch(mass, velocity, pressure, rig, sample_rate=options.sample_rate, duration=window,
                              noise=options.noise, seeds=[case_seed(options, NAME, c["case"]) for c in cases])
    closed = closed_form_peak_force(rig, mass, velocity, pressure)
    rows = []
    for i, case in enumerate(cases):
        pulses = contact_pulses(batch.time, batch.data["contact_force"][i])
        simulated = pulses[0].peak_force if pulses else float("nan")
        end = pulses[0].end if pulses else window
        recorded = recordings[i]
        first = recorded.time <= end
        measured = float(recorded.contact_force[first].max()) if first.any() else float("nan")
        rows.append({**case, "contact_law": rig.contact.law, "simulated_peak_force": simulated,
                     "recorded_peak_force": measured, "closed_form_peak_force": float(closed[i]),
                     "ratio_error": simulated / float(closed[i]) - 1.0,
                     "recorded_error": measured / simulated - 1.0})
    return rows


def _aggregate(rows: list[Row]) -> list[Row]:
    return percent_labels(group_stats(rows, ("contact_law", "mass"), ("ratio_error", "recorded_error")))


def _summary(rows: list[Row]) -> list[Row]:
    err = finite_values(rows, "ratio_error")
    rec = finite_values(rows, "recorded_error")
    return [{"quantity": "first-pulse peak force, simulated vs two-body closed form with preload (max deviation)",
             "ours": f"{np.max(np.abs(err)) * 100:.2f} % over {err.size} cases" if err.size else "no data",
             "paper": "model check (no figure); the closed form is undamped, contact damping lowers the peak"},
            {"quantity": "first-pulse peak as recorded by the DAQ vs simulated (mean deviation)",
             "ours": f"{np.mean(np.abs(rec)) * 100:.2f} %" if rec.size else "no data",
             "paper": "not stated (the response map's peaks feature depends on it)"}]


STUDY = register(Study(name=NAME, title="First-pulse peak force: simulator vs two-body closed form", figure="",
                       cases=_cases, evaluate=_evaluate, aggregate=_aggregate, summary=_summary,
                       drawing=plotted_by("plot_peak_force"), chunk_size=25))
