"""The drops of a calibration set as the joint fit reads them: each recording with its truth (M1 weighed, V0 from
the light gate, p0 set by the operator), checked, and observed as the model-based identification observes a record
(:func:`impactometer.identify.model_fit.engine.observe`: both channels, their noise σ from the pre-trigger, the sensor
model of the samples)."""

from __future__ import annotations

import hashlib
import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import ImpactometerError, RecordingError, shown
from ..identify.model_fit import TRIGGER_LEAD
from ..identify.model_fit.engine import Observed, anti_alias_design, check_channels, check_length, observe
from ..recording import Recording
from ..rig import MASS_RANGE, STAND_KEY, VELOCITY_RANGE
from ..sensors import anti_alias_delay
from ..units import UNITS, likely_units

#: metadata that names the stand a recording was made on: drops that state different values were made on
#: different stands and are not calibrated together
STAND_METADATA = ("rig", STAND_KEY, "contact_law")
#: truth a drop must state (manifest or file metadata) -> its unit
TRUTH = {"mass_kg": "kg", "velocity_m_s": "m/s", "pressure_gauge_Pa": "Pa gauge"}
#: relative distance between a stated M1 or V0 and the record's own answer beyond which the stated value is taken
#: as contradicted (and examined for another unit): far beyond the peak-to-peak answer's error on a foreign stand
#: (a few %) and far below the factors of a unit slip (lb 2.2, km/h 3.6)
UNIT_SLIP_TOLERANCE = 0.15
#: a drop's contact instant is started from the back-extrapolated force rise (:func:`_rise_onset`) where that lies
#: more than this many samples before the trigger [-]: the force of a pad that stiffens as it is compressed
#: (F ∝ δ^n, n > 1) crosses a trigger threshold of a few noise σ a millisecond after contact, a start the joint fit
#: did not come back from (a power-law pad of another simulator, started 1.2 ms late: chi2/dof 15 from the true
#: stand; started within a sample: 0.76 from the built-in stand's values); the start of a pad whose force rises
#: linearly or jumps at contact stays where the trigger puts it
ONSET_LEAD = 10
#: the share of the first pulse's peak force between which the rise is extrapolated back [-]
RISE_BAND = (0.05, 0.5)


@dataclass(frozen=True)
class _ObservedDrop:
    """One drop of a calibration set.

    ``mass`` [kg] (exact), ``velocity`` [m/s] (the light gate's), ``pressure_gauge`` [Pa gauge]; ``data`` the observed
    channels; ``contact_time`` [s] where the fit starts the contact instant (on the recording's clock, the
    anti-alias delay taken off); ``source`` the file.
    """

    source: str
    mass: float
    velocity: float
    pressure_gauge: float
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
    pressure_gauge = out["pressure_gauge_Pa"]
    meant = likely_units(pressure_gauge, "pressure")
    if meant:  # a charge pressure below 1 kPa gauge: written in kPa (or bar) under a column in Pa
        raise RecordingError(f"{recording.source}: pressure_gauge_Pa = {pressure_gauge:g} Pa gauge, below any charge "
                             f"pressure; did you mean {' or '.join(f'{pressure_gauge:g}{u}' for u in meant)}? (the "
                             "manifest column is in Pa)")
    low, high = MASS_RANGE
    if not low <= out["mass_kg"] <= high:
        raise RecordingError(f"{recording.source}: mass_kg must be within [{low:g}, {high:g}] kg, got "
                             f"{out['mass_kg']:g}")
    if out["velocity_m_s"] > VELOCITY_RANGE[1]:
        raise RecordingError(f"{recording.source}: velocity_m_s must be <= {VELOCITY_RANGE[1]:.3g} m/s, got "
                             f"{out['velocity_m_s']:g}")
    return out


def _stated_in_other_units(recording: Recording, truth: dict[str, float]) -> None:
    """RecordingError when the stated M1 or V0 of ``recording`` contradicts the record and reads as it in another
    unit (a mass in lb, a velocity in km/h).

    The record's own M1 and V0 come from the peak-to-peak identification (the force and the piston acceleration
    only, no stand model: :func:`impactometer.identify.peak_to_peak.identify`). A stated value counts as
    contradicted when it lies more than :data:`UNIT_SLIP_TOLERANCE` (relative) and 5 of that answer's σ away, and as
    in another unit when, converted from one of :data:`impactometer.units.UNITS`' other units of its dimension, it
    lies within both. Where the record gives no answer, nothing is said here (the joint fit judges the drop).
    """
    from ..identify.peak_to_peak import identify

    try:
        with warnings.catch_warnings():  # the record's answer is only a cross-check here: its own cautions aside
            warnings.simplefilter("ignore")
            answer = identify(recording)
    except ImpactometerError:
        return
    for key, dimension, found, std in (("mass_kg", "mass", answer.mass, answer.mass_std),
                                       ("velocity_m_s", "velocity", answer.velocity, answer.velocity_std)):
        if not (math.isfinite(found) and found > 0):
            continue
        band = max(UNIT_SLIP_TOLERANCE * found, 5.0 * std) if math.isfinite(std) else UNIT_SLIP_TOLERANCE * found
        stated = truth[key]
        if abs(stated - found) <= band:
            continue
        meant = [unit for unit, factor in UNITS[dimension].items() if factor != 1.0
                 and abs(stated * factor - found) <= band]
        if meant:
            si = TRUTH[key]
            raise RecordingError(f"{recording.source}: {key} = {stated:g} {si}, but the record itself says "
                                 f"{found:.3g} {si} (peak-to-peak identification); did you mean "
                                 f"{' or '.join(f'{stated:g}{u}' for u in meant)}? (the manifest column is in {si})")


def _check_distinct(recordings: Sequence[Recording]) -> None:
    """RecordingError naming both when two recordings are one file (by resolved path) or hold the same samples
    (a hash of the sample rate, start time and channels): a drop given twice would count twice."""
    seen: dict[str, str] = {}
    for recording in recordings:
        path = Path(str(recording.source))
        keys = [("the same file", str(path.resolve()))] if path.is_file() else []
        digest = hashlib.sha256(np.array([recording.sample_rate, recording.start_time], dtype=float).tobytes())
        for name in sorted(recording.channels):
            digest.update(name.encode())
            digest.update(np.ascontiguousarray(recording.channels[name], dtype=float).tobytes())
        keys.append(("the same samples", digest.hexdigest()))
        for what, key in keys:
            if key in seen:
                raise RecordingError(f"the calibration set holds one drop twice: {seen[key]} and "
                                     f"{recording.source} are {what}; expected distinct drops")
            seen[key] = str(recording.source)


def _check_one_stand(recordings: Sequence[Recording]) -> None:
    """RecordingError when the recordings state different stands (:data:`STAND_METADATA`); sample rates, channel
    sets and files of other formats are fine."""
    for key in STAND_METADATA:
        stated = {str(r.metadata[key]): r.source for r in recordings if r.metadata.get(key) is not None}
        if len(stated) > 1:
            (a, first), (b, second) = list(stated.items())[:2]
            raise RecordingError(f"recordings of different stands: {first} states {key} = {a!r}, {second} states "
                                 f"{key} = {b!r}; expected one stand in a calibration set")


def _rise_onset(recording: Recording, trigger: float) -> float | None:
    """The instant [s] at which the power law a·(t − t0)^n through the rising contact force of the first pulse
    (the run of samples within :data:`RISE_BAND` of its peak that ends below the peak; the peak is the largest force
    up to 10 ms after the ``trigger`` [s]) reaches zero, t0 found
    on a grid of a tenth of a sample period up to 5 ms before the rise; None where the rise holds fewer than four
    samples or the exponent is outside 0.5-5."""
    rate = recording.sample_rate
    force = np.asarray(recording.contact_force, dtype=float)
    time = recording.start_time + np.arange(force.size) / rate
    first = int(np.searchsorted(time, trigger))
    end = min(force.size, first + int(0.01 * rate))
    if end - first < 4:
        return None
    peak = first + int(np.argmax(force[first:end]))
    below = np.flatnonzero(force[:peak] <= RISE_BAND[1] * force[peak])
    if below.size == 0:
        return None
    top = bottom = int(below[-1])
    while bottom > 0 and force[bottom - 1] >= RISE_BAND[0] * force[peak]:
        bottom -= 1
    rising = np.arange(bottom, top + 1)
    if rising.size < 4:
        return None
    t, y = time[rising], np.log(force[rising])
    onsets = t[0] - np.arange(1, int(0.005 * rate) * 10 + 1) / (10.0 * rate)
    x = np.log(t[None, :] - onsets[:, None])
    xc, yc = x - x.mean(axis=1, keepdims=True), y - y.mean()
    slope = (xc @ yc) / np.einsum("ij,ij->i", xc, xc)
    residual = np.einsum("ij,ij->i", yc[None, :] - slope[:, None] * xc, yc[None, :] - slope[:, None] * xc)
    best = int(np.argmin(residual))
    return float(onsets[best]) if 0.5 <= slope[best] <= 5.0 else None


def _read_drops(recordings: Sequence[Recording]) -> list[_ObservedDrop]:
    """The :class:`_ObservedDrop` of each recording, checked: the channels the fit needs, the truth, a pre-trigger
    and the length after contact, one stand, no drop twice. Each drop's ``source`` is its recording's, numbered
    (``memory #3``) where recordings share one."""
    if not isinstance(recordings, Sequence) or isinstance(recordings, (str, bytes)):
        raise RecordingError(f"recordings must be a sequence of Recording, got {type(recordings).__name__}")
    for recording in recordings:
        if not isinstance(recording, Recording):
            raise RecordingError(f"recordings must hold Recording objects, got {type(recording).__name__}")
        check_channels(recording)
    _check_distinct(recordings)
    _check_one_stand(recordings)
    truths = [_truth(recording) for recording in recordings]
    for recording, truth in zip(recordings, truths, strict=True):
        _stated_in_other_units(recording, truth)
    sources = [str(r.source) for r in recordings]
    labels = [s if sources.count(s) == 1 else f"{s} #{i + 1}" for i, s in enumerate(sources)]
    drops = []
    for recording, truth, label in zip(recordings, truths, labels, strict=True):
        design = anti_alias_design(recording)
        trigger = check_length(recording)
        data = observe(recording, design, trigger)
        delay = anti_alias_delay(design, recording.sample_rate)
        start = trigger - delay - TRIGGER_LEAD / recording.sample_rate
        onset = _rise_onset(recording, trigger)
        if onset is not None and onset - delay < start - ONSET_LEAD / recording.sample_rate:
            start = onset - delay
        drops.append(_ObservedDrop(source=label, mass=truth["mass_kg"], velocity=truth["velocity_m_s"],
                          pressure_gauge=truth["pressure_gauge_Pa"], data=data, contact_time=start))
    return drops
