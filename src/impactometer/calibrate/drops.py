"""The drops of a calibration set as the joint fit reads them: each recording with its truth (M1 weighed, V0 from
the light gate, p0 set by the operator), checked, and observed as the model-based identification observes a record
(:func:`impactometer.identify.model_fit.engine.observe`: both channels, their noise σ from the pre-trigger, the sensor
model of the samples)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from ..errors import RecordingError, shown
from ..identify.model_fit import TRIGGER_LEAD
from ..identify.model_fit.engine import Observed, anti_alias_design, check_channels, check_length, observe
from ..recording import Recording
from ..rig import MASS_RANGE, STAND_KEY, VELOCITY_RANGE
from ..sensors import anti_alias_delay

#: metadata that names the stand a recording was made on: drops that state different values were made on
#: different stands and are not calibrated together
STAND_METADATA = ("rig", STAND_KEY, "contact_law")
#: truth a drop must state (manifest or file metadata) -> its unit
TRUTH = {"mass_kg": "kg", "velocity_m_s": "m/s", "pressure_gauge_Pa": "Pa gauge"}


@dataclass(frozen=True)
class ObservedDrop:
    """One drop of a calibration set.

    ``mass`` [kg] (exact), ``velocity`` [m/s] (the light gate's), ``pressure`` [Pa gauge]; ``data`` the observed
    channels; ``contact_time`` [s] where the fit starts the contact instant (on the recording's clock, the
    anti-alias delay taken off); ``source`` the file.
    """

    source: str
    mass: float
    velocity: float
    pressure: float
    data: Observed
    contact_time: float


def _truth(recording: Recording) -> dict[str, float]:
    """M1, V0 and p0 of ``recording`` from its metadata (the manifest completes it); RecordingError without."""
    out = {}
    for key, unit in TRUTH.items():
        value = recording.metadata.get(key)
        if value is None:
            raise RecordingError(f"{recording.source}: no {key} [{unit}]; every drop of a calibration set needs its "
                                 f"mass, light-gate velocity and charge pressure (manifest.csv columns "
                                 f"file,{','.join(TRUTH)})")
        try:
            number = float(value)
        except (TypeError, ValueError):
            number = math.nan
        if not math.isfinite(number) or number < 0 or (number == 0 and key != "pressure_gauge_Pa"):
            raise RecordingError(f"{recording.source}: {key} must be a number > 0 [{unit}], got {shown(value)}")
        out[key] = number
    low, high = MASS_RANGE
    if not low <= out["mass_kg"] <= high:
        raise RecordingError(f"{recording.source}: mass_kg must be within [{low:g}, {high:g}] kg, got "
                             f"{out['mass_kg']:g}")
    if out["velocity_m_s"] > VELOCITY_RANGE[1]:
        raise RecordingError(f"{recording.source}: velocity_m_s must be <= {VELOCITY_RANGE[1]:.3g} m/s, got "
                             f"{out['velocity_m_s']:g}")
    return out


def check_one_stand(recordings: Sequence[Recording]) -> None:
    """RecordingError when the recordings state different stands (:data:`STAND_METADATA`); sample rates, channel
    sets and files of other formats are fine."""
    for key in STAND_METADATA:
        stated = {str(r.metadata[key]): r.source for r in recordings if r.metadata.get(key) is not None}
        if len(stated) > 1:
            (a, first), (b, second) = list(stated.items())[:2]
            raise RecordingError(f"recordings of different stands: {first} states {key} = {a!r}, {second} states "
                                 f"{key} = {b!r}; expected one stand in a calibration set")


def read_drops(recordings: Sequence[Recording]) -> list[ObservedDrop]:
    """The :class:`ObservedDrop` of each recording, checked: the channels the fit needs, the truth, a pre-trigger
    and the length after contact, one stand."""
    if not isinstance(recordings, Sequence) or isinstance(recordings, (str, bytes)):
        raise RecordingError(f"recordings must be a sequence of Recording, got {type(recordings).__name__}")
    for recording in recordings:
        check_channels(recording)
    check_one_stand(recordings)
    drops = []
    for recording in recordings:
        truth = _truth(recording)
        design = anti_alias_design(recording)
        trigger = check_length(recording)
        data = observe(recording, design, trigger)
        start = trigger - anti_alias_delay(design, recording.sample_rate) - TRIGGER_LEAD / recording.sample_rate
        drops.append(ObservedDrop(source=str(recording.source), mass=truth["mass_kg"], velocity=truth["velocity_m_s"],
                          pressure=truth["pressure_gauge_Pa"], data=data, contact_time=start))
    return drops
