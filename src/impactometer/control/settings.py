"""What the controller of valve Z is told: :class:`ControlSettings` (a frozen dataclass with named fields).

The compiled loop reads the settings as a packed vector (:meth:`ControlSettings.packed`, its slots named by
:class:`.state.Settings`); that vector never leaves the control package.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np

from ..errors import ParameterError, shown
from ..validation import check_flag, check_real, is_real
from .state import Strategy, names, pack_settings

#: the strategies of the compiled controller, by name
STRATEGIES = sorted(name.lower() for name in names(Strategy))


@dataclass(frozen=True, kw_only=True)
class ControlSettings:
    """Settings of the digital controller of valve Z (SI units).

    Attributes
    ----------
    strategy : ``closed``, ``constant`` (hold ``opening``), ``realtime`` (force feedback), ``predictive``
        (force feedback on the state predicted over the valve's dead time, with lag compensation) or ``level``
        (the ``predictive`` law holding the contact force at ``force_level``, the program of the achievable
        reference).
    start : Time the controller takes over the valve [s] (``inf``: never).
    opening : Opening of the ``constant`` strategy, fraction of the fully open valve [-].
    mass, mass_std : M1 known at the control start and its standard error [kg]; NaN mass: unknown (the valve
        waits for the stage-B estimate); ``inf`` std: no weight once the stage-B estimate exists; 0: known exactly,
        never refined.
    velocity : V0 known at the control start [m/s].
    usable_stroke : Largest displacement of the mass the absorber may use [m].
    tau_control : Time constant of the gas-force loop [s].
    tau_filter : Time constant of the pressure filters [s].
    pressure_lower_start, temperature_lower_start : Lower-chamber pressure [Pa absolute] and gas temperature [K] at
        first contact (not the charge pressure ``pressure_gauge``, which is gauge and with the piston at the top stop).
    close_on_stop : The ``constant`` strategy closes the valve for good once the mass stops.
    max_force : Largest target force [N].
    bounce_gate, bounce_threshold : The ``realtime`` law acts only while the bodies approach faster than the
        threshold [m/s] (``control.controller.bounce_gate``).
    refine_mass : Refine M1 in sustained contact from M1·(g − a2) = Fc.
    force_level : Contact force held by the ``level`` strategy [N].
    force_noise : Standard deviation of the force sensor's noise [N] (sets the contact detection levels).
    supervise : Keep the valve closed while the closed gas spring is needed to stop the bodies in the stroke.
    observer_bandwidth : Bandwidth of the piston position/velocity observer [rad/s].
    acceleration_noise : Standard deviation of the accelerometer's noise [m/s²] (the noise floor of the stage-B
        mass estimate's standard error).
    early_start : Time from which the controller acts on partial knowledge [s] (``inf``: never): before ``start``
        it takes ``early_mass`` ± ``early_mass_std`` [kg] (a prior over the stand's rated masses) and
        ``early_velocity`` [m/s] (V0 from the first samples of the contact) as M1 and V0, refined by its
        stage-B estimate; from ``start`` on, the identification's answer replaces them.
    mass_floor : Floor of ``mass_std`` as a fraction of ``mass`` [-] where the stage-B estimate refines it: the
        relative standard error the identification that gave ``mass`` is validated to (the closed loop sets it per
        method, :func:`.identified.mass_floor`); 0: ``mass_std`` as given.
    """

    strategy: str = "closed"
    start: float = math.inf
    opening: float = 0.0
    mass: float = math.nan
    mass_std: float = math.inf
    velocity: float = 0.0
    usable_stroke: float = 0.0
    tau_control: float = 2e-3
    tau_filter: float = 5e-4
    pressure_lower_start: float = 1e5
    temperature_lower_start: float = 293.15
    close_on_stop: bool = True
    max_force: float = math.inf
    bounce_gate: bool = False
    bounce_threshold: float = 0.0
    refine_mass: bool = True
    force_level: float = math.nan
    force_noise: float = 0.0
    supervise: bool = True
    observer_bandwidth: float = 2.0 * math.pi * 40.0
    acceleration_noise: float = 0.0
    early_start: float = math.inf
    early_mass: float = math.nan
    early_mass_std: float = math.inf
    early_velocity: float = math.nan
    mass_floor: float = 0.0

    def __post_init__(self) -> None:
        if self.strategy not in STRATEGIES:
            raise ParameterError(f"control.strategy must be one of {STRATEGIES}, got {self.strategy!r}")
        for f in fields(self):
            value = getattr(self, f.name)
            if f.name == "strategy":
                continue
            if f.type in ("bool", bool):
                check_flag(f"control.{f.name}", value)
            elif not is_real(value):
                raise ParameterError(f"control.{f.name} must be a number, got {shown(value)}")
        for name in ("start", "early_start", "usable_stroke", "tau_control", "tau_filter", "pressure_lower_start",
                     "temperature_lower_start",
                     "force_noise", "observer_bandwidth", "acceleration_noise", "mass_floor"):
            check_real(f"control.{name}", getattr(self, name), low=0.0, finite=name not in ("start", "early_start"),
                       state_range=True,
                       low_open=name in ("tau_control", "tau_filter", "pressure_lower_start", "temperature_lower_start",
                                         "observer_bandwidth"))
        if not 0.0 <= self.opening <= 1.0:
            raise ParameterError(f"control.opening must be a fraction within [0, 1], got {self.opening!r}")
        if not (math.isnan(self.mass) or (math.isfinite(self.mass) and self.mass > 0.0)):
            raise ParameterError(f"control.mass must be > 0 [kg] or NaN (unknown), got {self.mass!r}")
        if math.isfinite(self.early_start) and not (math.isfinite(self.early_mass) and self.early_mass > 0.0
                                                    and math.isfinite(self.early_velocity)
                                                    and self.early_velocity > 0.0):
            raise ParameterError(f"control.early_mass [kg] and control.early_velocity [m/s] must be > 0 with a finite "
                                 f"early_start, got {self.early_mass!r} and {self.early_velocity!r}")
        if math.isnan(self.early_mass_std) or self.early_mass_std < 0.0:
            raise ParameterError(f"control.early_mass_std must be >= 0 [kg], got {self.early_mass_std!r}")
        if math.isnan(self.mass_std) or self.mass_std < 0.0:
            raise ParameterError(f"control.mass_std must be >= 0 [kg] (inf: no weight), got {self.mass_std!r}")
        if self.strategy == "level" and not (math.isfinite(self.force_level) and self.force_level > 0.0):
            raise ParameterError(f"control.force_level must be > 0 [N] for the level strategy, got "
                                 f"{self.force_level!r}")

    def packed(self) -> np.ndarray:
        """The settings as the vector the compiled loop reads (:func:`.state.pack_settings`)."""
        return pack_settings(self)
