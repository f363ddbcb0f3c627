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
from ..model.forces import orifice_mass_flow
from ..rig import Rig

#: where the valve discharges the lower chamber: into the upper chamber (the stand of the paper) or to atmosphere
ROUTES = {"upper": 0, "atmosphere": 1}


def _positive(name: str, value, *, allow_zero: bool = False, allow_inf: bool = False, unit: str = "") -> None:
    ok_type = isinstance(value, (int, float)) and not isinstance(value, bool)
    if not ok_type or math.isnan(value) or (math.isinf(value) and not allow_inf) \
            or (value < 0 if allow_zero else value <= 0):
        bound = ">= 0" if allow_zero else "> 0"
        raise ParameterError(f"{name} must be a {'' if allow_inf else 'finite '}number {bound}{unit}, got "
                             f"{shown(value)}")


@dataclass(frozen=True, kw_only=True)
class ValveDrive:
    """Actuator of valve Z.

    Attributes
    ----------
    time_constant : First-order lag between the commanded and the actual opening [s].
    max_rate : Largest rate of change of the opening [m²/s] (``inf`` = lag only).
    route : ``"upper"`` (lower -> upper chamber, as on the stand) or ``"atmosphere"`` (lower chamber vented).
    """

    time_constant: float = 1e-3
    max_rate: float = math.inf
    route: str = "upper"

    def __post_init__(self) -> None:
        _positive("valve_drive.time_constant", self.time_constant, unit=" [s]")
        _positive("valve_drive.max_rate", self.max_rate, allow_inf=True, unit=" [m²/s]")
        if not isinstance(self.route, str) or self.route not in ROUTES:
            raise ParameterError(f"valve_drive.route must be one of {sorted(ROUTES)}, got {self.route!r}")


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
    """

    stroke_margin: float = 0.01
    rated_force: float = 5e3
    drive: ValveDrive = ValveDrive()
    bounce_gate: bool = False

    def __post_init__(self) -> None:
        _positive("absorber.stroke_margin", self.stroke_margin, allow_zero=True, unit=" [m]")
        _positive("absorber.rated_force", self.rated_force, unit=" [N]")
        if not isinstance(self.drive, ValveDrive):
            raise ParameterError(f"absorber.drive must be a ValveDrive, got {self.drive!r}")
        if not isinstance(self.bounce_gate, bool):
            raise ParameterError(f"absorber.bounce_gate must be True or False, got {self.bounce_gate!r}")

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
    rig : Rig, optional
        Supplies the discharge coefficient, A_max and the gas (default: the built-in stand).

    Notes
    -----
    Choked when p_down/p_up <= (2/(γ+1))^(γ/(γ−1)), isentropic otherwise (ISO 6358 orifice form).
    """
    from ..rig import get_rig

    rig = get_rig(rig)
    arrays = [np.asarray(a, dtype=float) for a in (pressure_up, temperature_up, pressure_down, area)]
    for name, arr in zip(("pressure_up", "temperature_up", "pressure_down"), arrays, strict=False):
        if not np.all(np.isfinite(arr)) or np.any(arr <= 0):
            raise ParameterError(f"{name} must be finite and > 0, got {arr!r}")
    if not np.all(np.isfinite(arrays[3])) or np.any(arrays[3] < 0) or np.any(arrays[3] > rig.valve.max_area):
        raise ParameterError(f"area must be within [0, {rig.valve.max_area:g}] m², got {arrays[3]!r}")
    shape = np.broadcast_shapes(*(a.shape for a in arrays))
    flat = [np.broadcast_to(a, shape).ravel() for a in arrays]
    out = np.array([orifice_mass_flow(pu, tu, pd, ar, rig.valve.discharge_coefficient, rig.gas.gamma,
                                      rig.gas.gas_constant) for pu, tu, pd, ar in zip(*flat, strict=False)])
    return out.reshape(shape) if shape else float(out[0])
