"""What a drop test and a stand can physically be, and how a stand is known: the fingerprint of its parameters.

- :data:`VELOCITY_RANGE`, :data:`MASS_RANGE`: the impacts a drop test can give (a :class:`~impactometer.rig.Scenario`,
  the known truth of a recording, the plausibility of an identified answer all use them);
- :data:`CYLINDER_LIMITS` and :func:`check_stops`: a stand no one builds (its areas and volumes overflow, its top
  stop yields more than the gas column it closes) is refused when it is created;
- :func:`fingerprint` and :func:`check_recorded_on`: a stand's name is a label; two stands are the same when all
  their parameters are, and a recording states the stand it was made on by their fingerprint.
"""

from __future__ import annotations

import hashlib
import json
import math
import numbers
from typing import TYPE_CHECKING, Any

from .errors import ParameterError

if TYPE_CHECKING:  # annotations only: rig.py imports this module
    from .recording import Recording
    from .rig import Rig

#: gravitational acceleration the velocity range is computed with [m/s²]
_GRAVITY = 9.81
#: free-fall heights of a drop test [m]: from a tenth of a millimetre to a tall drop tower
FREE_FALL_HEIGHTS = (1e-4, 12.0)
#: impact velocities a drop test can have [m/s]: free fall over :data:`FREE_FALL_HEIGHTS`
VELOCITY_RANGE = tuple(math.sqrt(2.0 * _GRAVITY * h) for h in FREE_FALL_HEIGHTS)
#: impacting masses a drop test can have [kg]: from a tenth of a kilogram to ten tonnes
MASS_RANGE = (0.1, 1e4)
#: cylinder parameter -> its largest value [SI]: beyond any drop stand, short of overflowing its areas and volumes
CYLINDER_LIMITS = {"piston_mass": 1e5, "bore": 10.0, "rod_diameter": 10.0, "stroke": 100.0,
                   "rated_pressure_gauge": 1e9, "lower_length": 100.0, "upper_length": 100.0,
                   "dead_volume_lower": 1e4, "dead_volume_upper": 1e4}
#: metadata key holding the fingerprint of the stand a recording was made on
STAND_KEY = "rig_fingerprint"


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


def fingerprint(rig: Rig | dict[str, Any]) -> str:
    """A short hash of every parameter of a stand (a :class:`~impactometer.rig.Rig` or its ``to_dict`` form).

    Two stands with the same parameters have the same fingerprint whatever their names (a name is a label) and
    however their numbers are written (``2e6`` or ``2000000``); any other parameter gives another fingerprint.
    """
    from .rig import Rig, from_dict, to_dict

    stand = rig if isinstance(rig, Rig) else from_dict(rig, source="stand")

    def plain(value: Any) -> Any:
        if isinstance(value, dict):
            return {k: plain(v) for k, v in value.items()}
        return float(value) if isinstance(value, numbers.Real) and not isinstance(value, bool) else value

    data = plain({k: v for k, v in to_dict(stand).items() if k != "name"})
    return hashlib.sha256(json.dumps(data, sort_keys=True).encode()).hexdigest()[:16]


def check_recorded_on(recording: Recording, stand: dict[str, Any], *, hint: str,
                      error: type[Exception] = ParameterError) -> None:
    """``error`` when ``recording`` states a stand (:data:`STAND_KEY`) with other parameters than ``stand``."""
    stated = recording.metadata.get(STAND_KEY)
    if stated is None:
        return
    expected = fingerprint(stand)
    if str(stated) != expected:
        name = recording.metadata.get("rig")
        raise error(f"{recording.source}: recorded on a stand{f' labelled {name!r}' if name else ''} with other "
                    f"parameters (fingerprint {str(stated)[:16]}) than the stand {stand.get('name')!r} (fingerprint "
                    f"{expected}); {hint}")
