"""What a drop test and a stand can physically be.

- :data:`VELOCITY_RANGE`, :data:`MASS_RANGE`: the impacts a drop test can give (a :class:`~impactometer.rig.Scenario`,
  the known truth of a recording, the plausibility of an identified answer all use them);
- :data:`CYLINDER_LIMITS` and :func:`check_stops`: a stand no one builds (its areas and volumes overflow, its top
  stop yields more than the gas column it closes) is refused when it is created;

How a stand is known (the fingerprint of its parameters) is in :mod:`impactometer.rig.stand`.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from ..constants import STANDARD_GRAVITY
from ..errors import ParameterError

if TYPE_CHECKING:  # annotations only: stand.py imports this module
    from .stand import Rig

#: free-fall heights of a drop test [m]: from a tenth of a millimetre to a tall drop tower
FREE_FALL_HEIGHTS = (1e-4, 12.0)
#: impact velocities a drop test can have [m/s]: free fall over :data:`FREE_FALL_HEIGHTS`
VELOCITY_RANGE = tuple(math.sqrt(2.0 * STANDARD_GRAVITY * h) for h in FREE_FALL_HEIGHTS)
#: impacting masses a drop test can have [kg]: from a tenth of a kilogram to ten tonnes
MASS_RANGE = (0.1, 1e4)
#: cylinder parameter -> its largest value [SI]: beyond any drop stand, short of overflowing its areas and volumes
CYLINDER_LIMITS = {"piston_mass": 1e5, "bore": 10.0, "rod_diameter": 10.0, "stroke": 100.0,
                   "rated_pressure_gauge": 1e9, "lower_length": 100.0, "upper_length": 100.0,
                   "dead_volume_lower": 1e4, "dead_volume_upper": 1e4}


def check_stops(rig: Rig) -> None:
    """ParameterError for a stand whose top stop cannot hold the piston within its upper gas column.

    Charged to the rated pressure, the gas pushes the piston into the top stop with up to the rated pressure on the
    full piston area (plus its weight, ten times over for the blow of a bounce); a stop yielding more than the upper
    gas column under that load would compress the gas to a negative volume: a simulation would show a negative
    stroke and negative absolute pressures.
    """
    c = rig.cylinder
    load = c.rated_pressure_gauge * c.area + 10.0 * c.piston_mass * max(rig.gravity, 1.0)
    yielding = load / rig.stops.stiffness
    column = c.upper_length + c.dead_volume_upper / c.annulus_area
    if yielding >= column:
        raise ParameterError(f"stops.stiffness {rig.stops.stiffness:g} N/m lets the top stop yield {yielding:.3g} m "
                             f"under the rated {c.rated_pressure_gauge:g} Pa on the {c.bore:g} m bore, more than the "
                             f"upper gas column ({column:.3g} m); expected a stand whose stops hold the piston within "
                             "its gas columns (stiffer stops, a smaller bore or a lower rated pressure)")
