"""Simulation results: one scenario (:class:`SimulationResult`) or a batch (:class:`BatchResult`)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..rig import Rig, Scenario


@dataclass(frozen=True, kw_only=True)
class SimulationResult:
    """Histories of one simulated drop test, sampled at ``time`` [s] (t = 0 at first contact).

    Displacements ``u1``, ``u2`` [m] (axis down, from the piston's top-stop position), velocities ``v1``, ``v2``
    [m/s], kinematic accelerations ``a1``, ``a2`` [m/s²], forces [N], chamber pressures [Pa absolute], gas masses
    [kg], energies [J] (changes since t = 0, except ``dissipated_energy`` which starts at 0) and the set of a
    hysteretic contact ``contact_set`` [m] (zero for the other contact laws).
    """

    time: np.ndarray
    u1: np.ndarray
    v1: np.ndarray
    u2: np.ndarray
    v2: np.ndarray
    a1: np.ndarray
    a2: np.ndarray
    contact_force: np.ndarray
    pneumatic_force: np.ndarray
    friction_force: np.ndarray
    top_stop_force: np.ndarray
    bottom_stop_force: np.ndarray
    pressure_lower: np.ndarray
    pressure_upper: np.ndarray
    gas_mass_lower: np.ndarray
    gas_mass_upper: np.ndarray
    kinetic_energy: np.ndarray
    potential_energy: np.ndarray
    gas_energy: np.ndarray
    elastic_energy: np.ndarray
    dissipated_energy: np.ndarray
    contact_set: np.ndarray
    rig: Rig
    scenario: Scenario
    integrator: str
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def sample_rate(self) -> float:
        """Sample rate of the histories [Hz]."""
        return 1.0 / (self.time[1] - self.time[0])

    @property
    def total_energy(self) -> np.ndarray:
        """Kinetic + elastic energy, changes of potential and gas energy from t = 0, and dissipated energy [J];
        constant up to integration error."""
        return (self.kinetic_energy + self.potential_energy + self.gas_energy + self.elastic_energy
                + self.dissipated_energy)

    @property
    def energy_balance_error(self) -> float:
        """Largest drift of :attr:`total_energy` relative to the initial kinetic energy [-]."""
        initial = 0.5 * self.scenario.mass * self.scenario.velocity**2
        return float(np.max(np.abs(self.total_energy - self.total_energy[0])) / initial)

    def to_dict(self) -> dict[str, Any]:
        """Arrays by channel name plus the scenario, for saving."""
        arrays = {name: getattr(self, name) for name in ARRAY_FIELDS}
        return {**arrays, "mass": self.scenario.mass, "velocity": self.scenario.velocity,
                "pressure_gauge": self.scenario.pressure_gauge, "integrator": self.integrator}

    def plot(self, ax=None, *, pulses=None):
        """Figure of contact force, piston acceleration, displacements and pressures (see plotting)."""
        from ..plotting.simulation import plot_simulation

        return plot_simulation(self, axes=ax, pulses=pulses)


ARRAY_FIELDS = ("time", "u1", "v1", "u2", "v2", "a1", "a2", "contact_force", "pneumatic_force", "friction_force",
                "top_stop_force", "bottom_stop_force", "pressure_lower", "pressure_upper", "gas_mass_lower",
                "gas_mass_upper", "kinetic_energy", "potential_energy", "gas_energy", "elastic_energy",
                "dissipated_energy", "contact_set")


@dataclass(frozen=True, kw_only=True)
class BatchResult:
    """Histories of a batch: ``data[name]`` has shape (n_scenarios, n_samples).

    ``mass``, ``velocity``, ``pressure_gauge`` are the scenario arrays [kg, m/s, Pa gauge]; ``params`` the packed
    parameter rows (stand overrides included); ``steps`` the accepted integrator steps per scenario.
    """

    time: np.ndarray
    data: dict[str, np.ndarray]
    mass: np.ndarray
    velocity: np.ndarray
    pressure_gauge: np.ndarray
    params: np.ndarray
    steps: np.ndarray
    rig: Rig

    def __getitem__(self, name: str) -> np.ndarray:
        return self.data[name]

    def __len__(self) -> int:
        return self.mass.size
