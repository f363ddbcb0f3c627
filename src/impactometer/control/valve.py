"""Valve Z and its drive: compressible orifice flow, actuator lag and rate limit, opening in [0, A_max].

The valve itself (opening area, A_max, discharge coefficient) is ``rig.valve``; what the stand description does not
hold -- where the valve vents, how fast its actuator follows a command, and how much of the stroke the absorber may
use -- lives in :class:`ValveDrive` and :class:`Absorber` here.

Usable stroke
-------------
The lower gas column of the built-in stand (0.20 m) equals the piston stroke, so the closed gas spring can never
reach the bottom stop: its force grows without bound as the column shrinks. An absorber that opens the valve can,
however, drive the piston into the stop. The absorber is therefore allowed to move the impacting mass by at most
``usable_stroke = cylinder.stroke - stroke_margin`` (mass displacement from the piston's top-stop position), the
margin (default 10 mm) covering the contact compression and the estimation error of the controller.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import ParameterError, shown
from ..model import dynamics as d
from ..model.actuated import ROUTES
from ..model.forces import ISO_REFERENCE_DENSITY, ISO_REFERENCE_TEMPERATURE
from ..model.setup import pack
from ..rig import Rig, Scenario, get_rig
from ..validation import check_flag, check_real, is_real

#: largest dead time of a valve drive [s]
MAX_DEAD_TIME = 0.05


def _positive(name: str, value, *, allow_zero: bool = False, allow_inf: bool = False, unit: str = "") -> None:
    check_real(name, value, low=0.0, low_open=not allow_zero, finite=not allow_inf, unit=unit, state_range=True)


@dataclass(frozen=True, kw_only=True)
class ValveDrive:
    """Actuator of valve Z, as a data sheet gives it: a dead time, then a first-order lag with an optional rate
    limit, from the commanded to the actual opening (a fraction of the fully open valve).

    Attributes
    ----------
    dead_time : Delay between a command and the start of the valve's response [s].
    time_constant : First-order lag between the commanded and the actual opening [s].
    max_rate : Largest rate of change of the opening [1/s] (fraction of the full opening per second; ``inf`` = lag
        only; a rate-limited valve that moves from closed to open in 4 ms has 250/s).
    route : ``"upper"`` (lower -> upper chamber, as on the stand) or ``"atmosphere"`` (lower chamber vented).
    """

    dead_time: float = 5e-4
    time_constant: float = 1.4e-3
    max_rate: float = math.inf
    route: str = "upper"

    def __post_init__(self) -> None:
        _positive("valve_drive.dead_time", self.dead_time, allow_zero=True, unit=" [s]")
        _positive("valve_drive.time_constant", self.time_constant, unit=" [s]")
        _positive("valve_drive.max_rate", self.max_rate, allow_inf=True, unit=" [1/s]")
        if self.dead_time > MAX_DEAD_TIME:
            raise ParameterError(f"valve_drive.dead_time must be <= {MAX_DEAD_TIME:g} s, got {shown(self.dead_time)}")
        if not isinstance(self.route, str) or self.route not in ROUTES:
            raise ParameterError(f"valve_drive.route must be one of {sorted(ROUTES)}, got {self.route!r}")

    @property
    def response_time(self) -> float:
        """10-90 % response time of a full opening step [s] (dead time excluded): 2.2·τ for the lag alone; with a
        rate limit, from the step response of the lag and the limit together."""
        if math.isinf(self.max_rate):
            return self.time_constant * math.log(9.0)
        dt = min(self.time_constant, 1.0 / self.max_rate) * 1e-3
        x, t, t10 = 0.0, 0.0, math.nan
        while x < 0.9:
            x += min(self.max_rate * dt, (1.0 - x) * (1.0 - math.exp(-dt / self.time_constant)))
            t += dt
            if math.isnan(t10) and x >= 0.1:
                t10 = t
        return t - t10


@dataclass(frozen=True, kw_only=True)
class Absorber:
    """What the absorber may do on a stand.

    Attributes
    ----------
    stroke_margin : Part of the piston stroke kept free in front of the bottom stop [m].
    rated_force : Highest contact force the absorber is meant to apply after the control starts [N]; an impact
        whose energy needs more than ``rated_force × usable stroke`` is reported as over capacity.
    drive : The valve actuator.
    bounce_gate : The real-time strategy lowers the gas force only while the mass and the piston approach each
        other (``control.controller.bounce_gate``); off by default: on the built-in stand it raises the peak force
        after the control start (see docs/absorption.md).
    rated_masses : The stand's rated range of M1 [kg] (low, high): the prior of M1 of a controller that acts
        before the mass is identified (``absorb(early=True)``), uniform over it.
    """

    stroke_margin: float = 0.01
    rated_force: float = 5e3
    drive: ValveDrive = ValveDrive()
    bounce_gate: bool = False
    rated_masses: tuple[float, float] = (10.0, 50.0)

    def __post_init__(self) -> None:
        _positive("absorber.stroke_margin", self.stroke_margin, allow_zero=True, unit=" [m]")
        _positive("absorber.rated_force", self.rated_force, unit=" [N]")
        if not isinstance(self.drive, ValveDrive):
            raise ParameterError(f"absorber.drive must be a ValveDrive, got {self.drive!r}")
        check_flag("absorber.bounce_gate", self.bounce_gate)
        masses = self.rated_masses
        if not (isinstance(masses, tuple) and len(masses) == 2 and all(is_real(m) for m in masses)
                and 0.0 < masses[0] <= masses[1] < math.inf):
            raise ParameterError(f"absorber.rated_masses must be (low, high) with 0 < low <= high [kg], got "
                                 f"{masses!r}")

    def mass_prior(self) -> tuple[float, float]:
        """Mean and standard deviation [kg] of the uniform prior of M1 over :attr:`rated_masses`."""
        low, high = self.rated_masses
        return 0.5 * (low + high), (high - low) / math.sqrt(12.0)

    def usable_stroke(self, rig: Rig) -> float:
        """Largest displacement of the mass the absorber may use on ``rig`` [m]."""
        usable = rig.cylinder.stroke - self.stroke_margin
        if usable <= 0.0:
            raise ParameterError(f"absorber.stroke_margin must be < the stroke ({rig.cylinder.stroke!r} m), "
                                 f"got {self.stroke_margin!r}")
        return usable


def valve_mass_flow(pressure_up, temperature_up, pressure_down, area, *, rig: Rig | None = None):
    """Mass flow through valve Z [kg/s] from the upstream to the downstream side (zero for reverse pressure).

    Parameters
    ----------
    pressure_up, pressure_down : float or array_like
        Absolute pressures on either side [Pa].
    temperature_up : float or array_like
        Temperature of the upstream gas [K].
    area : float or array_like
        Opening area, within [0, rig.valve.max_area] [m²].
    rig : Rig or str, optional
        Supplies the flow law (orifice: C_d; ISO 6358: C and b), A_max and the gas (default: the built-in stand).

    Notes
    -----
    Orifice: choked when p_down/p_up <= (2/(γ+1))^(γ/(γ−1)), isentropic above. ISO 6358: choked when
    p_down/p_up <= b, elliptic above, with the conductance C·area/A_max. Both fall linearly to zero above
    p_down/p_up = 0.999 (see ``model.forces``).
    """
    rig = get_rig(rig)
    arrays = [np.asarray(a, dtype=float) for a in (pressure_up, temperature_up, pressure_down, area)]
    for name, arr in zip(("pressure_up", "temperature_up", "pressure_down"), arrays, strict=False):
        if not np.all(np.isfinite(arr)) or np.any(arr <= 0):
            raise ParameterError(f"{name} must be finite and > 0, got {arr!r}")
    if not np.all(np.isfinite(arrays[3])) or np.any(arrays[3] < 0) or np.any(arrays[3] > rig.valve.max_area):
        raise ParameterError(f"area must be within [0, {rig.valve.max_area:g}] m², got {arrays[3]!r}")
    shape = np.broadcast_shapes(*(a.shape for a in arrays))
    flat = [np.broadcast_to(a, shape).ravel() for a in arrays]
    p = pack(rig, Scenario(mass=1.0, velocity=1.0, pressure_gauge=0.0))
    out = np.array([d.valve_mass_flow(pu, tu, pd, ar, p) for pu, tu, pd, ar in zip(*flat, strict=True)])
    return out.reshape(shape) if shape else float(out[0])


def _choked_flow_function(gamma: float) -> float:
    """ψ* = sqrt(γ·(2/(γ+1))^((γ+1)/(γ−1))), the flow function of a choked orifice [-]."""
    return math.sqrt(gamma * (2.0 / (gamma + 1.0)) ** ((gamma + 1.0) / (gamma - 1.0)))


def effective_area(rig: Rig | str | None = None) -> float:
    """Effective (sonic) area of the fully open valve Z of ``rig`` [m²]: the orifice that passes the same choked
    flow, C_d·A_max for the orifice law, C·ρ0·sqrt(R·T0)/ψ* for the ISO 6358 law (about 5 mm² per dm³/(s·bar)
    for air)."""
    rig = get_rig(rig)
    valve, gas = rig.valve, rig.gas
    if valve.law == "orifice":
        return valve.discharge_coefficient * valve.max_area
    return float(valve.sonic_conductance) * ISO_REFERENCE_DENSITY * math.sqrt(  # type: ignore[arg-type]
        gas.gas_constant * ISO_REFERENCE_TEMPERATURE) / _choked_flow_function(gas.gamma)


def iso6358_valve(area: float, *, rig: Rig | str | None = None, critical_ratio: float = 0.3) -> Rig:
    """``rig`` with an ISO 6358 valve Z of effective area ``area`` [m²] (its sonic conductance from
    :func:`effective_area`'s relation) and critical pressure ratio ``critical_ratio`` [-]."""
    rig = get_rig(rig)
    _positive("area", area, unit=" [m²]")
    gas = rig.gas
    conductance = area * _choked_flow_function(gas.gamma) / (
        ISO_REFERENCE_DENSITY * math.sqrt(gas.gas_constant * ISO_REFERENCE_TEMPERATURE))
    return rig.replace(**{"valve.law": "iso6358", "valve.sonic_conductance": conductance,
                          "valve.critical_ratio": critical_ratio})
