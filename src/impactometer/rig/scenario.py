"""One drop test, :class:`Scenario`: the impacting mass, its impact velocity and the charge pressure."""

from __future__ import annotations

import math
from dataclasses import dataclass

from ..constants import STANDARD_GRAVITY
from ..errors import ParameterError
from ..validation import check_real
from .limits import MASS_RANGE, VELOCITY_RANGE
from .stand import Rig


@dataclass(frozen=True, kw_only=True)
class Scenario:
    """One drop test: impacting mass M1 [kg], impact velocity V0 [m/s], charge pressure p0 [Pa gauge]."""

    mass: float
    velocity: float
    pressure_gauge: float = 200e3

    def __post_init__(self) -> None:
        check_real("mass", self.mass, low=MASS_RANGE[0], high=MASS_RANGE[1], unit=" [kg]")
        check_real("velocity", self.velocity, low=0.0, low_open=True, high=VELOCITY_RANGE[1], unit=" [m/s]")
        check_real("pressure_gauge", self.pressure_gauge, low=0.0, unit=" [Pa]")

    @classmethod
    def from_height(cls, *, mass: float, height: float, pressure_gauge: float = 200e3,
                    gravity: float = STANDARD_GRAVITY) -> Scenario:
        """Scenario of a free drop from ``height`` [m]: V0 = sqrt(2·g·h)."""
        check_real("height", height, low=0.0, low_open=True, unit=" [m]")
        return cls(mass=mass, velocity=math.sqrt(2.0 * gravity * height), pressure_gauge=pressure_gauge)

    def check_against(self, rig: Rig) -> None:
        """Raise unless the charge pressure is within the rating of ``rig``."""
        if self.pressure_gauge > rig.cylinder.rated_pressure_gauge:
            raise ParameterError(f"pressure_gauge must be <= the rated {rig.cylinder.rated_pressure_gauge:g} Pa "
                                 f"of {rig.name!r}, got {self.pressure_gauge!r}")
