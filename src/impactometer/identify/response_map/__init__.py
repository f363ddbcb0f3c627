"""Response-map identification (paper section 5): impacting mass and velocity from the contact force alone.

The measured features (see :mod:`.features`, eq. (6)) are matched against a database of features over
mass × velocity (× charge pressure), the response map, by minimizing eq. (7) of the paper::

    f(M1, V1) = Σ_i [(Y_i^M - Y_i(M1, V1)) / Y_i^M]²

Building: :func:`build_map_simulated`, :func:`build_map_from_recordings`, :func:`refine`; files: :func:`save_map`,
:func:`load_map`; identification: :func:`identify_features` (features already extracted), :func:`identify_recording`.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np

from ...errors import ParameterError, ResponseMapError, shown
from ...recording import Recording
from ...rig import check_recorded_on
from ...signals.noise import robust_noise_std
from ...validation import check_real, is_real
from ..details import ResponseMapDetails
from ..inspection import inspect_recording
from ..plausibility import check_answer, in_contact
from ..result import Identification
from .build import PRESSURE_TOLERANCE, build_map_from_recordings, build_map_simulated
from .database import ResponseMap, refine
from .features import FEATURE_SETS, extract_features, recording_signal
from .search import EXTENSION, SEARCHES, brute_search, fast_tables, locate
from .store import load_map, save_map

__all__ = ["FEATURE_SETS", "Identification", "ResponseMap", "build_map_from_recordings", "build_map_simulated",
           "identify_features", "identify_recording", "load_map", "refine", "save_map"]

#: samples before first contact from which on they are a pre-trigger that gives the force's offset
PRE_TRIGGER_SAMPLES = 32
#: eq. (7) residual above which the features are said to fit nowhere in the map (≈ 7 % feature mismatch)
MISFIT_RESIDUAL = 0.01
#: eq. (7) residual of the best fit inside the map up to which no fit outside it is sought (≈ 0.7 % mismatch)
INSIDE_RESIDUAL = 1e-4


def _pressure_for(rmap: ResponseMap, pressure_gauge: float | None, allow_extrapolation: bool) -> float:
    axis = rmap.pressures_gauge
    if pressure_gauge is None:
        if axis.size > 1:
            raise ResponseMapError(f"the map has a pressure axis ({axis[0] / 1e3:g}-{axis[-1] / 1e3:g} kPa); give "
                                   "the measured charge pressure (metadata pressure_gauge_Pa)")
        return float(axis[0])
    p = check_real("pressure_gauge", pressure_gauge, unit=" [Pa]")
    lo, hi = axis[0], axis[-1]
    tol = max(PRESSURE_TOLERANCE[0], PRESSURE_TOLERANCE[1] * hi)
    if lo - tol <= p <= hi + tol:
        return min(max(p, lo), hi)
    if axis.size > 1 and allow_extrapolation:
        warnings.warn(f"charge pressure {p / 1e3:g} kPa is outside the map's {lo / 1e3:g}-{hi / 1e3:g} kPa; "
                      "extrapolating along pressure", UserWarning, stacklevel=3)
        return p
    span = f"{lo / 1e3:g} kPa" if axis.size == 1 else f"{lo / 1e3:g}-{hi / 1e3:g} kPa"
    raise ResponseMapError(f"the map was made for a charge pressure of {span}, the measurement is at "
                           f"{p / 1e3:g} kPa; build a map at that pressure (map build --pressure {p / 1e3:g}kPa) or "
                           "one whose pressure axis spans it")


def identify_features(features, rmap: ResponseMap, *, search: str = "fast", pressure_gauge: float | None = None,
                      allow_extrapolation: bool = False, available_at: float | None = None) -> Identification:
    """Mass and velocity whose map features best match ``features`` (eq. (7) of the paper).

    Parameters
    ----------
    features : (m,) array_like
        Measured features, in the order and units of the map's feature set.
    rmap : ResponseMap
        The database.
    search : {"fast", "brute"}
        Continuous inversion of the smooth map (cost independent of its size) or eq. (7) at every node.
    pressure_gauge : float, optional
        Measured charge pressure [Pa gauge]; required for a map with a pressure axis.
    allow_extrapolation : bool
        Answer (with a warning) when the features lie outside the map instead of raising ResponseMapError.
    available_at : float, optional
        When the features were complete [s] (reported; default: the feature window where fixed, else NaN).

    Returns
    -------
    Identification
        Method ``response-map/fast`` or ``response-map/brute``; no standard errors (NaN); details ``residual``
        (eq. (7) at the answer [-]), ``features`` (name -> measured value), ``feature_set``, ``pressure_gauge`` (the
        pressure the map was read at [Pa gauge]) and ``extrapolated`` (the answer lies outside the map).

    Notes
    -----
    Implements eqs. (6)-(7) of the reference paper. Whether the measurement lies inside the map is decided by the
    continuous inversion for both searches (the brute minimum always sits on a node): the best fit inside the map
    is taken when its residual is at most :data:`INSIDE_RESIDUAL`; otherwise the search extends 25 % beyond the
    map's edges, and an answer found out there is refused (or, with ``allow_extrapolation``, returned with a
    warning).
    """
    if not isinstance(search, str) or search not in SEARCHES:
        raise ParameterError(f"search must be one of {list(SEARCHES)}, got {shown(search)}")
    if not isinstance(rmap, ResponseMap):
        raise ParameterError(f"rmap must be a ResponseMap, got {type(rmap).__name__}")
    labels = rmap.labels
    try:
        y = np.asarray(features, dtype=float)
    except (TypeError, ValueError):
        y = np.empty(0)
    if y.shape != (len(labels),) or not all(0.0 < x < math.inf for x in y.tolist()):
        raise ResponseMapError(f"features must be {len(labels)} finite numbers > 0 ({', '.join(labels)}), got "
                               f"{features!r}")
    p = _pressure_for(rmap, pressure_gauge, allow_extrapolation)
    herm, xm, xv, coarse, cm, cv, (m_lo, m_hi, v_lo, v_hi) = fast_tables(rmap)
    mass, velocity, residual, extended = locate(herm, xm, xv, coarse, cm, cv, rmap.pressures_gauge, p, y,
                                                INSIDE_RESIDUAL, EXTENSION)
    outside = extended and not (m_lo <= mass <= m_hi and v_lo <= velocity <= v_hi)
    if outside or residual > MISFIT_RESIDUAL:
        _refuse_or_warn(rmap, y, mass, velocity, residual, outside, allow_extrapolation)
    if search == "brute":
        mass, velocity, residual, _, _ = brute_search(rmap, y, p)  # python floats, like fast_search
    if available_at is None:
        available_at = rmap.feature_params.get("window", math.nan)
    elif not (is_real(available_at) and math.isnan(available_at)):  # NaN: not known
        available_at = check_real("available_at", available_at, unit=" [s] or None")
    details = ResponseMapDetails(residual=residual, features=dict(zip(labels, y.tolist(), strict=False)),
                                 feature_set=rmap.feature_set, pressure_gauge=p, extrapolated=outside)
    return Identification(mass=mass, velocity=velocity, available_at=float(available_at),
                          method=f"response-map/{search}", details=details,
                          warnings=check_answer(mass, velocity))


def _refuse_or_warn(rmap, y, mass, velocity, residual, outside, allow_extrapolation) -> None:
    measured = ", ".join(f"{k} = {v:.4g}" for k, v in zip(rmap.labels, y, strict=False))
    span = (f"mass {rmap.masses[0]:g}-{rmap.masses[-1]:g} kg, velocity {rmap.velocities[0]:.3g}-"
            f"{rmap.velocities[-1]:.3g} m/s")
    if not math.isfinite(residual):  # no answer to give, even by extrapolation
        raise ResponseMapError(f"features ({measured}) fit nowhere in or near the map ({span}): eq. (7) overflows, "
                               "a feature is many orders of magnitude off the map's; expected a map of the same "
                               "stand, contact law and feature parameters as the measurement")
    if residual > MISFIT_RESIDUAL:
        text = (f"features ({measured}) fit nowhere in or near the map ({span}): the best eq. (7) residual is "
                f"{residual:.2g} > {MISFIT_RESIDUAL:g}, at {mass:.3g} kg and {velocity:.3g} m/s")
        hint = "expected a map of the same stand, contact law and feature parameters as the measurement"
    else:
        text = (f"features ({measured}) lie outside the map ({span}); the nearest impact explaining them is about "
                f"{mass:.3g} kg at {velocity:.3g} m/s (eq. (7) residual {residual:.2g})")
        hint = "build a map that spans it (map build --mass/--height) or pass --allow-extrapolation"
    if not allow_extrapolation:
        raise ResponseMapError(f"{text}; {hint}")
    warnings.warn(f"{text}; answering by extrapolation", UserWarning, stacklevel=3)


def check_recording(recording: Recording, rmap: ResponseMap) -> None:
    """Raise ResponseMapError when ``recording`` was not made under the conditions the map describes."""
    where = f"{recording.source}: "
    if abs(recording.sample_rate - rmap.sample_rate) > 1e-6 * rmap.sample_rate:
        raise ResponseMapError(f"{where}sampled at {recording.sample_rate:g} Hz, the map was built from signals at "
                               f"{rmap.sample_rate:g} Hz; expected the same sample rate (build the map with "
                               f"--sample-rate {recording.sample_rate:g}Hz)")
    law = recording.metadata.get("contact_law")
    map_law = rmap.rig.get("contact", {}).get("law")
    if isinstance(law, str) and law != map_law:
        raise ResponseMapError(f"{where}contact law {law!r}, the map was made with {map_law!r}; expected a map "
                               "of the same contact")
    check_recorded_on(recording, rmap.rig, error=ResponseMapError,
                      hint="expected a map of the same stand (map build --rig FILE)")


def recording_pressure(recording: Recording, rmap: ResponseMap, pressure_gauge: float | None = None) -> float:
    """The charge pressure [Pa gauge] of ``recording``: ``pressure_gauge`` where given, else the one its metadata
    states (``pressure_gauge_Pa``).

    ResponseMapError where neither says it (the map's own pressure is not assumed: the features of one impact
    differ by tens of percent between charge pressures, and so would the answer), or where the two differ by more
    than :data:`~.build.PRESSURE_TOLERANCE`.
    """
    stated = recording.truth("pressure_gauge_Pa")
    if pressure_gauge is None:
        if stated is None:
            axis = rmap.pressures_gauge
            span = f"{axis[0] / 1e3:g} kPa" if axis.size == 1 else f"{axis[0] / 1e3:g}-{axis[-1] / 1e3:g} kPa"
            raise ResponseMapError(f"{recording.source}: the charge pressure is not known (the recording states no "
                                   f"pressure_gauge_Pa, the map was made at {span}); give the measured charge "
                                   "pressure (pressure_gauge=, --pressure)")
        return stated
    given = check_real("pressure_gauge", pressure_gauge, low=0.0, unit=" [Pa]")
    if stated is not None and abs(given - stated) > max(PRESSURE_TOLERANCE[0], PRESSURE_TOLERANCE[1] * stated):
        raise ResponseMapError(f"{recording.source}: pressure_gauge {given / 1e3:g} kPa contradicts the recording's "
                               f"pressure_gauge_Pa of {stated / 1e3:g} kPa; expected the same charge pressure (or "
                               "none given)")
    return given


def identify_recording(recording: Recording, map_or_path: ResponseMap | str | Path, *, search: str = "fast",
                       allow_extrapolation: bool = False, pressure_gauge: float | None = None) -> Identification:
    """Identify mass and velocity of the impact in ``recording`` with a response map (or the path of one).

    The recording must have the map's sample rate, contact law and stand (when its metadata states them: the
    stand by the fingerprint of its parameters, see :func:`impactometer.rig.fingerprint`); its charge pressure is
    ``pressure_gauge`` [Pa gauge] or, where not given, the one its metadata states (``pressure_gauge_Pa``): one of
    them is required, and they must agree (:func:`recording_pressure`). The delay of its anti-alias filter
    (``anti_alias_delay_s``) is taken out of its time base.
    """
    if not isinstance(recording, Recording):
        raise ParameterError(f"recording must be a Recording, got {type(recording).__name__}")
    rmap = map_or_path if isinstance(map_or_path, ResponseMap) else load_map(map_or_path)
    check_recording(recording, rmap)
    pressure = recording_pressure(recording, rmap, pressure_gauge)
    time, force = recording_signal(recording)
    check_first_contact(recording, time, force)
    values, available = extract_features(time, force, rmap.feature_set, rmap.feature_params)
    delay = recording.time[0] - time[0]  # the filter delay: the features are complete that much later
    found = identify_features(values, rmap, search=search, pressure_gauge=pressure,
                              allow_extrapolation=allow_extrapolation, available_at=available + delay)
    return replace(found, warnings=force_plausibility(recording, found.mass, found.velocity, rmap.stand.gravity))


def check_first_contact(recording: Recording, time: np.ndarray, force: np.ndarray) -> None:
    """ResponseMapError where the force is not at rest at the record's first contact (t = 0, where every window
    of the features starts): a record whose trigger came late (:func:`.plausibility.in_contact`; 2 ms late gave
    M1 11 % low, without a word)."""
    first = int(np.searchsorted(time, 0.0))
    if first >= force.size:
        return  # no first contact in the record: the features say so
    # the offset before first contact where a pre-trigger records one (not the few samples of a filter's delay)
    level = float(np.median(force[:first])) if first >= PRE_TRIGGER_SAMPLES else 0.0
    why = in_contact(float(force[first]) - level, robust_noise_std(force), float(np.max(force)) - level,
                     f"t = {time[first]:.6g} s (first contact by the record's time base)")
    if why:
        raise ResponseMapError(f"{recording.source}: {why}")


def force_plausibility(recording: Recording, mass: float, velocity: float, gravity: float) -> tuple[str, ...]:
    """What makes an answer implausible for the recording's contact force (:func:`.plausibility.check_answer`;
    the pulses and the offset are those :func:`~impactometer.identify.inspection.inspect_recording` finds)."""
    found = inspect_recording(recording)
    force = recording.contact_force - found.force_offset
    index = [(p.start - recording.start_time) * recording.sample_rate for p in found.pulses]
    ends = [round((p.end - recording.start_time) * recording.sample_rate) for p in found.pulses if not p.sustained]
    return check_answer(mass, velocity, force=force, sample_rate=recording.sample_rate,
                        onset=index[0] if index else 0.0, pulse_ends=ends, gravity=gravity,
                        noise_force=found.channels["contact_force"].noise)
