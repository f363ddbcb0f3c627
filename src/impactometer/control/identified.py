"""M1 and V0 as the closed loop gets them: the streaming identification of the noisy closed-valve record (or a
response map, or the oracle), and what the controller may trust of it.

Until the control starts the valve is closed, so the identification reads a record of the closed-valve impact (made
by :func:`impactometer.sensors.record`, anti-alias filter and noise included).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from ..errors import IdentificationError, ParameterError
from ..identify.peak_to_peak.streaming import StreamingIdentifier
from ..rig import Rig, Scenario
from ..sensors import record

if TYPE_CHECKING:  # for annotations only: the map module is imported where it is used
    from ..identify.response_map import MapIdentification
    from ..identify.result import Identification

#: length of the closed-valve record given to the identification [s], and the quiet record before first contact
#: [s] (a streaming DAQ has it; the identification takes the offsets and the noise level from its last ~1000
#: samples: with 2 ms instead of 25 ms it gave no estimate in 7 of the 125 grid impacts and 2.5× the mass error)
IDENTIFICATION_WINDOW = 0.1
PRE_TRIGGER = 0.025
#: samples per chunk pushed into the streaming identifier (a DAQ block)
STREAM_CHUNK = 16
#: the controller trusts an identified mass whose standard error is below this fraction of it, and a velocity
#: whose standard error is below this fraction of it [-]
MASS_TRUST, VELOCITY_TRUST = 1.0, 0.5


@dataclass(frozen=True, kw_only=True)
class Identified:
    """What the loop acted on: M1 [kg], V0 [m/s], their standard errors, when they were known [s], by which method
    (and why it failed). ``usable_mass`` / ``usable_velocity`` are what the controller takes: NaN where the
    estimate is not trustworthy (the controller then waits for its stage-B estimate)."""

    method: str
    mass: float
    velocity: float
    available_at: float
    mass_std: float = math.nan
    velocity_std: float = math.nan
    error: str | None = None

    @property
    def usable_mass(self) -> float:
        """The mass if finite, positive and with a standard error below ``MASS_TRUST`` of it, else NaN [kg]."""
        ok = math.isfinite(self.mass) and self.mass > 0.0 and not self.mass_std >= MASS_TRUST * self.mass
        return self.mass if ok else math.nan

    @property
    def usable_velocity(self) -> float:
        """The velocity if finite, positive and with a standard error below ``VELOCITY_TRUST`` of it, else NaN
        [m/s]."""
        ok = math.isfinite(self.velocity) and self.velocity > 0.0 \
            and not self.velocity_std >= VELOCITY_TRUST * self.velocity
        return self.velocity if ok else math.nan

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready mapping (NaN -> None)."""
        def num(x):
            return None if x is None or not math.isfinite(x) else float(x)

        return {"method": self.method, "mass_kg": num(self.mass), "velocity_m_s": num(self.velocity),
                "mass_std_kg": num(self.mass_std), "velocity_std_m_s": num(self.velocity_std),
                "available_at_s": num(self.available_at), "error": self.error}


def identify_impact(scenario: Scenario, rig: Rig, *, method: str, noise: float, seed: int,
                    sample_rate: float, response_map=None) -> Identified:
    """Identify M1 and V0 from a noisy closed-valve record, as a real-time system would: the record streams
    through :class:`~impactometer.identify.peak_to_peak.streaming.StreamingIdentifier` and the first estimate (the early
    answer, at the end of the second contact pulse) is taken when it arrives. A response map is applied to the
    whole record and reports its own ``available_at``. A failed identification is returned with ``error`` set."""
    rec = record(scenario, rig, sample_rate=sample_rate, duration=IDENTIFICATION_WINDOW, noise=noise, seed=seed,
                 pre_trigger=PRE_TRIGGER)
    found: Identification | MapIdentification | None
    try:
        if method == "response-map":
            from ..identify.response_map import identify_recording

            if response_map is None:
                raise ParameterError("identification 'response-map' needs response_map= (a map or its file)")
            found = identify_recording(rec, response_map)
        else:
            stream = StreamingIdentifier(rec.sample_rate, variant=method, gravity=rig.gravity,
                                         start_time=rec.start_time)
            found = None
            for k in range(0, rec.time.size, STREAM_CHUNK):
                estimates = stream.push(rec.contact_force[k:k + STREAM_CHUNK],
                                        rec.piston_acceleration[k:k + STREAM_CHUNK])
                if estimates:
                    found = estimates[0]
                    break
            if found is None:
                raise IdentificationError(f"no estimate within the first {IDENTIFICATION_WINDOW * 1e3:g} ms "
                                          "of the impact")
    except IdentificationError as exc:
        return Identified(method=method, mass=math.nan, velocity=math.nan, available_at=math.inf, error=str(exc))
    std = tuple(math.nan if x is None else float(x) for x in (found.mass_std, found.velocity_std))
    if not math.isfinite(found.available_at):
        return Identified(method=method, mass=float(found.mass), velocity=float(found.velocity),
                          available_at=math.inf, mass_std=std[0], velocity_std=std[1],
                          error="identification gave no time of availability")
    return Identified(method=method, mass=float(found.mass), velocity=float(found.velocity),
                      available_at=max(float(found.available_at), 0.0), mass_std=std[0], velocity_std=std[1])
