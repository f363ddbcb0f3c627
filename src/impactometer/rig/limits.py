"""What a drop test and a stand can physically be.

- :data:`VELOCITY_RANGE`, :data:`MASS_RANGE`: the impacts a drop test can give (a :class:`~impactometer.rig.Scenario`,
  the known truth of a recording, the plausibility of an identified answer all use them);
- :data:`CYLINDER_LIMITS`: a cylinder no one builds (its areas and volumes overflow) is refused when it is created
  (a stand whose top stop cannot hold the piston is refused by :class:`~impactometer.rig.Rig` itself).
"""

from __future__ import annotations

import math

from ..constants import STANDARD_GRAVITY

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
