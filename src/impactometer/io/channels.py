"""Channel and unit maps shared by the readers: what a file holds (:class:`RawData`) -> a :class:`Recording`.

Every reader turns its file into a :class:`RawData` (named columns with their unit strings, an optional time
column, an optional sample rate, metadata); :func:`assemble` then finds the force and acceleration channels,
converts units to SI, applies sign flips and gravity removal, checks the time base and builds the Recording.
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..constants import STANDARD_GRAVITY
from ..errors import RecordingError, UnitError
from ..jsonable import plain
from ..recording import (
    ACCELERATION,
    CHANNEL_UNITS,
    FORCE,
    SAMPLE_RATE_RANGE,
    START_TIME_LIMIT,
    TRUTH_KEYS,
    TRUTH_UNITS,
    Recording,
    check_sample_rate,
    samples,
    time_base,
    truth_value,
    unit_statement,
)
from ..units import UNITS, find_unit

#: standard channel -> case-insensitive name fragments that identify it (pvlib VARIABLE_MAP in spirit)
CHANNEL_PATTERNS = {FORCE: ("force", "fc"), ACCELERATION: ("acc", "a2")}
#: names of a time column (case-insensitive, unit stripped)
TIME_NAMES = ("time", "t", "zeit", "temps", "timestamp", "x_time")
#: unit spellings found in lab files (lower case, spaces removed) -> symbol of :data:`impactometer.units.UNITS`
UNIT_ALIASES = {"m/s**2": "m/s^2", "ms^-2": "m/s^2", "ms-2": "m/s^2", "m/s/s": "m/s^2", "gn": "g", "g0": "g",
                "sec": "s", "seconds": "s", "msec": "ms", "newton": "N", "newtons": "N", "kilonewton": "kN",
                "pascal": "Pa"}
#: units of lab files not in impactometer.units.UNITS (same layout: dimension -> symbol -> factor to SI)
EXTRA_UNITS = {"acceleration": {"mm/s^2": 1e-3}, "force": {"lbf": 4.4482216152605, "kgf": STANDARD_GRAVITY}}
#: the dimension each standard channel must have
CHANNEL_DIMENSIONS = {FORCE: "force", ACCELERATION: "acceleration"}
#: SI unit of each dimension a channel may have
SI_UNITS = {"force": "N", "acceleration": "m/s^2", "pressure": "Pa", "length": "m", "velocity": "m/s",
            "time": "s", "mass": "kg", "frequency": "Hz"}

_UNIT_IN_NAME = re.compile(r"^\s*(.*?)\s*[\[(]\s*([^\])]*?)\s*[\])]\s*$")


@dataclass(kw_only=True)
class RawData:
    """What a reader found in a file, before channel selection and unit conversion.

    Attributes
    ----------
    columns : Column name as found -> (samples, unit string or None).
    time : Time column (samples, unit) or None.
    sample_rate : Sample rate stated by the file [Hz] or None.
    start_time : Time of the first sample stated by the file [s] or None.
    metadata : Metadata stated by the file.
    source : File name used in messages.
    """

    columns: dict[str, tuple[np.ndarray, str | None]]
    source: str
    time: tuple[np.ndarray, str | None] | None = None
    sample_rate: float | None = None
    start_time: float | None = None
    metadata: dict[str, Any] = field(default_factory=dict)


def split_unit(name: str) -> tuple[str, str | None]:
    """``"Force [kN]"`` -> ``("Force", "kN")``; ``"Acceleration (g)"`` -> ``("Acceleration", "g")``."""
    match = _UNIT_IN_NAME.match(name)
    if match and match.group(1):
        return match.group(1), match.group(2) or None
    return name.strip(), None


def unreadable_name(name: str) -> str | None:
    """Why a channel written under ``name`` would come back under another name or as the time base (None where
    it would not): reading strips surrounding spaces, takes a bracketed end for a unit and a time name for the
    time column (:func:`split_unit`, :data:`TIME_NAMES`)."""
    bare, unit = split_unit(name)
    if name != name.strip():
        return "reading strips the spaces around it"
    if unit is not None or bare != name:
        return f"reading takes its end for a unit ({bare!r} in {unit!r})"
    if bare.lower() in TIME_NAMES:
        return "reading takes it for the time column"
    return None


def unit_factor(unit: str | None, *, dimension: str | None, field: str, source: str) -> tuple[str, float] | None:
    """(dimension, factor to SI) of ``unit``; None for no unit, or for an unknown unit when ``dimension`` is None.

    With ``dimension`` given, a unit of another dimension, an unknown or an ambiguous unit raises a RecordingError.
    """
    if unit is None or not unit.strip():
        return None
    bare = unit.strip().replace(" ", "")
    bare = UNIT_ALIASES.get(bare.lower(), bare)
    try:
        known = find_unit(bare, dimension, field=f"channel {field!r}", extra=EXTRA_UNITS)
    except UnitError as exc:
        if dimension is None:
            return None
        raise RecordingError(f"{source}: {exc}") from None
    if known is not None and known[0] not in SI_UNITS:
        known = None
    if known is None and dimension is not None:
        valid = list(UNITS.get(dimension, {})) + list(EXTRA_UNITS.get(dimension, {}))
        raise RecordingError(f"{source}: channel {field!r} has unit {unit!r}; expected a {dimension} unit "
                             f"({', '.join(valid)})")
    return known


def _matches(name: str, standard: str) -> bool:
    bare = split_unit(name)[0].lower()
    return bare == standard or any(fragment in bare for fragment in CHANNEL_PATTERNS[standard])


def pick_channel(names: list[str], standard: str, explicit: str | None, *, option: str, source: str,
                 required: bool, taken: tuple[str | None, ...] = ()) -> str | None:
    """The column holding ``standard``: ``explicit`` (exact or without unit, case-insensitive) or by pattern."""
    if explicit is not None:
        wanted = explicit.strip().lower()
        for name in names:
            if name.lower() == wanted or split_unit(name)[0].lower() == wanted:
                return name
        raise RecordingError(f"{source}: {option} {explicit!r} not found; channels found: {names}")
    candidates = [n for n in names if n not in taken and _matches(n, standard)]
    exact = [n for n in candidates if split_unit(n)[0].lower() == standard]
    if exact or candidates:
        return (exact or candidates)[0]
    if required:
        patterns = " or ".join(repr(p) for p in CHANNEL_PATTERNS[standard])
        raise RecordingError(f"{source}: no {standard} channel (a name containing {patterns}, or pass {option}); "
                             f"channels found: {names}")
    return None


def time_base_of(time: np.ndarray, unit: str | None, source: str) -> tuple[float, float]:
    """(sample rate [Hz], start time [s]) of a time column in ``unit``; see :func:`impactometer.recording.time_base`."""
    known = unit_factor(unit, dimension="time", field="time", source=source)
    return time_base(samples(time, "time", source, squeeze=True), source, scale=1.0 if known is None else known[1])


#: a metadata array with more elements is stored as its shape only
METADATA_ARRAY_ITEMS = 1000


def plain_metadata(value: Any) -> Any:
    """A JSON-friendly copy of a metadata value (:func:`impactometer.jsonable.plain`; NaN and infinities as their
    text, arrays of more than :data:`METADATA_ARRAY_ITEMS` elements as their shape)."""
    return plain(value, nonfinite="text", max_items=METADATA_ARRAY_ITEMS)


def metadata_from_json(text: Any, source: str, field: str) -> dict[str, Any]:
    """Parse a JSON object of metadata stored in a file; a RecordingError otherwise."""
    if isinstance(text, bytes):
        text = text.decode("utf-8", "replace")
    try:
        data = json.loads(text)
    except (TypeError, ValueError) as exc:
        raise RecordingError(f"{source}: {field} must be valid JSON ({exc})") from None
    except RecursionError:
        raise RecordingError(f"{source}: {field} nests too deeply; expected a JSON object of metadata") from None
    if not isinstance(data, dict):
        raise RecordingError(f"{source}: {field} must hold a JSON object, got {type(data).__name__}")
    return data


#: attribute names (case-insensitive) stating the time base in HDF5 attributes, TDMS properties, MAT scalars
RATE_KEYS = ("sample_rate", "sampling_rate", "samplerate", "fs", "sample_rate_hz", "sampling_frequency")
PERIOD_KEYS = ("dt", "wf_increment", "sample_interval", "sampling_interval", "increment")
START_KEYS = ("start_time", "t0", "wf_start_offset")


def _scalar(value: Any, source: str, field: str) -> float:
    arr = np.asarray(value)
    if arr.size != 1 or arr.dtype.kind not in "iuf":
        text = repr(plain_metadata(value))
        text = text if len(text) <= 60 else text[:57] + "..."
        raise RecordingError(f"{source}: {field} must be a number, got {text}")
    number = float(arr.reshape(-1)[0])
    if not math.isfinite(number):
        raise RecordingError(f"{source}: {field} must be finite, got {number!r}")
    return number


def one_value(statements: list[tuple[str, float]], source: str, what: str, unit: str, tolerance: float) -> float | None:
    """The value every statement ``(where, value)`` of one quantity gives; RecordingError when two disagree."""
    for where, value in statements[1:]:
        first_where, first = statements[0]
        if abs(value - first) > tolerance * max(abs(first), abs(value)) + (1e-12 if unit == "s" else 0.0):
            raise RecordingError(f"{source}: the {what} is stated twice, differently: {first_where} gives "
                                 f"{first:g} {unit}, {where} gives {value:g} {unit}; expected one value")
    return statements[0][1] if statements else None


Levels = Mapping[str, Any] | Sequence[tuple[str, Mapping[str, Any]]]


def _levels(levels: Levels) -> list[tuple[str, Mapping[str, Any]]]:
    return [("", levels)] if isinstance(levels, Mapping) else list(levels)


def time_attributes(levels: Levels, source: str) -> tuple[float | None, float | None, dict[str, Any]]:
    """(sample rate [Hz], start time [s], remaining attributes) from file attributes or properties.

    ``levels`` is one mapping or a sequence of (label, mapping) pairs (file, group): a rate (or period) and a start
    time stated more than once must agree, and so must a known truth; other attributes of a later level replace
    those of an earlier one.
    """
    rates: list[tuple[str, float]] = []
    starts: list[tuple[str, float]] = []
    rests: list[tuple[str, dict[str, Any]]] = []
    for label, level in _levels(levels):
        rest: dict[str, Any] = {}
        rests.append((label, rest))
        for key, value in level.items():
            low = str(key).lower()
            where = f"{label} {key}".strip()
            if low in RATE_KEYS:
                rates.append((where, check_sample_rate(_scalar(value, source, where), f"{source}: {where}")))
            elif low in PERIOD_KEYS:
                period = _scalar(value, source, where)
                low_rate, high_rate = SAMPLE_RATE_RANGE
                if not 1.0 / high_rate <= period <= 1.0 / low_rate:
                    raise RecordingError(f"{source}: {where} must be a sample period within [{1.0 / high_rate:g}, "
                                         f"{1.0 / low_rate:g}] s, got {period!r}")
                rates.append((where, float(f"{1.0 / period:.12g}")))  # 1/(1/fs) is not always fs in floating point
            elif low in START_KEYS:
                start = _scalar(value, source, where)
                if abs(start) > START_TIME_LIMIT:
                    raise RecordingError(f"{source}: {where} must be a time within ±{START_TIME_LIMIT:g} s, got "
                                         f"{start!r}")
                starts.append((where, start))
            else:
                rest[str(key)] = plain_metadata(value)
    return (one_value(rates, source, "sample rate", "Hz", 1e-6), one_value(starts, source, "start time", "s", 1e-9),
            merge_metadata(rests, source))


def merge_metadata(parts: Levels, source: str, *, tolerance: float = 1e-6) -> dict[str, Any]:
    """Metadata stated in several places: (label, mapping) pairs (file attributes, a JSON object, a manifest).

    A known truth (``mass_kg``, ...) stated in two places must agree within ``tolerance`` (relative); other keys of
    a later part replace those of an earlier one.
    """
    merged: dict[str, Any] = {}
    seen: dict[str, list[tuple[str, float]]] = {}
    for label, part in _levels(parts):
        for key, value in part.items():
            if key in TRUTH_KEYS and value is not None:
                where = f"{label} {key}".strip()
                seen.setdefault(key, []).append((where, truth_value(key, value, f"{source}: {where}: ")))
            merged[key] = value
    for key, statements in seen.items():
        one_value(statements, source, f"truth {key}", TRUTH_UNITS[key], tolerance)
    return merged


#: the channels whose unit a reader option may state instead of the file (channel -> the option's stem:
#: ``time_unit``, ``force_unit``, ``acceleration_unit``; ``--time-unit`` ... on the command line)
UNIT_OPTIONS = {"time": "time", FORCE: "force", ACCELERATION: "acceleration"}


def check_unit_options(units: Mapping[str, str | None] | None, source: str) -> dict[str, str]:
    """The units given for channels (:data:`UNIT_OPTIONS`), checked against each channel's dimension; None values
    left out. RecordingError naming the option, its value and what was expected."""
    if units is None:
        return {}
    if not isinstance(units, Mapping):
        raise RecordingError(f"units must be a mapping of channel to unit, got {type(units).__name__}")
    out: dict[str, str] = {}
    for channel, unit in units.items():
        if channel not in UNIT_OPTIONS:
            raise RecordingError(f"units: channel must be one of {sorted(UNIT_OPTIONS)}, got {channel!r}")
        if unit is None:
            continue
        option = f"{UNIT_OPTIONS[channel]}_unit"
        if not isinstance(unit, str) or not unit.strip():
            raise RecordingError(f"{option} must be a unit text such as 'g' or 'ms', got {unit!r}")
        dimension = "time" if channel == "time" else CHANNEL_DIMENSIONS[channel]
        known = unit_factor(unit, dimension=None, field=option, source=source)
        if known is None or known[0] != dimension:
            valid = list(UNITS.get(dimension, {})) + list(EXTRA_UNITS.get(dimension, {}))
            article = "an" if dimension[0] in "aeiou" else "a"
            raise RecordingError(f"{option} must be {article} {dimension} unit ({', '.join(valid)}), got {unit!r}")
        out[channel] = unit.strip()
    return out


#: a time column without a unit whose step, read in seconds, gives a rate below this is refused [Hz]
UNITLESS_RATE_FLOOR = 1e3


#: a record whose time column gives a rate below this cannot resolve a contact pulse (which lasts milliseconds) [Hz]
IMPACT_RATE_FLOOR = 1e3


def check_impact_time_base(rate: float, size: int, unit: str, source: str) -> None:
    """RecordingError for a time column, in its stated ``unit``, that gives no impact record: a rate below
    :data:`IMPACT_RATE_FLOOR` (a time column in ms under an ``[s]`` header made a 50 kHz, 70 ms record a 50 Hz,
    70 s one, whose contact pulses fall within a sample). The message names the unit that gives a rate an impact
    record can have."""
    duration = size / rate
    if rate >= IMPACT_RATE_FLOOR:
        return
    known = unit_factor(unit, dimension="time", field="time", source=source)
    factor = known[1] if known is not None else 1.0
    others = [(name, value) for name, value in UNITS["time"].items() if value < factor
              and rate * factor / value >= IMPACT_RATE_FLOOR]
    hint = ""
    if others:
        name, value = max(others, key=lambda item: item[1])
        hint = (f"; read in {name} it gives {rate * factor / value:g} Hz over {duration * value / factor:.3g} s: "
                f"read it with --time-unit {name} (time_unit={name!r})")
    raise RecordingError(f"{source}: the time column, read in its stated unit {unit!r}, gives {rate:g} Hz over "
                         f"{duration:.3g} s, no record of an impact (a contact pulse lasts milliseconds, within one "
                         f"sample here){hint}")


def assemble(raw: RawData, *, force_channel: str | None = None, acceleration_channel: str | None = None,
             flip_force: bool = False, flip_acceleration: bool = False,
             acceleration_includes_gravity: bool = False, sample_rate: float | None = None,
             units: Mapping[str, str | None] | None = None) -> Recording:
    """Build a Recording from what a reader found (see :func:`impactometer.io.read_recording`)."""
    source = raw.source
    columns = dict(raw.columns)
    raw_time = raw.time
    given_units = check_unit_options(units, source)
    if raw_time is None:
        for name in list(columns):
            bare, unit_in_name = split_unit(name)
            if bare.lower() in TIME_NAMES:
                values, unit = columns.pop(name)
                raw_time = (values, unit or unit_in_name)
                break
    if "time" in given_units:
        if raw_time is None:
            raise RecordingError(f"{source}: time_unit={given_units['time']!r} (--time-unit) applies to a time column, "
                                 "and the file has none (it states its sample rate)")
        raw_time = (raw_time[0], given_units["time"])
    names = list(columns)
    if not names:
        raise RecordingError(f"{source}: no data channels found")
    force_name = pick_channel(names, FORCE, force_channel, option="force_channel", source=source, required=True)
    acc_name = pick_channel(names, ACCELERATION, acceleration_channel, option="acceleration_channel",
                            source=source, required=acceleration_channel is not None, taken=(force_name,))
    noted_units = raw.metadata.get("channel_units")
    units_in = noted_units if isinstance(noted_units, dict) else {}
    channels: dict[str, np.ndarray] = {}
    units_out: dict[str, str] = {}
    origin: dict[str, str] = {}
    assumed: dict[str, str] = {}  # channel -> the SI unit it was read in for want of a stated one
    for name, (values, unit) in columns.items():
        bare, unit_in_name = split_unit(name)
        unit = unit if unit not in (None, "") else unit_in_name
        target = FORCE if name == force_name else ACCELERATION if name == acc_name else bare
        unit = given_units.get(target, unit)
        if unit in (None, "") and name in (force_name, acc_name) and not units_in.get(target):
            assumed[name] = "N" if name == force_name else "m/s^2"
        if target in channels:
            raise RecordingError(f"{source}: two columns give channel {target!r}; rename one or pick channels "
                                 f"with force_channel / acceleration_channel")
        if getattr(values, "dtype", None) is not None and values.dtype.kind == "b" and target in CHANNEL_DIMENSIONS:
            raise RecordingError(f"{source}: channel {name!r} holds logical (true/false) values; expected the "
                                 f"{target} as numbers")
        arr = samples(values, name, source, squeeze=True)
        known = unit_factor(unit, dimension=CHANNEL_DIMENSIONS.get(target), field=name, source=source)
        if known is not None:
            arr = arr * known[1] if known[1] != 1.0 else arr
        if target not in CHANNEL_UNITS:
            noted = SI_UNITS[known[0]] if known is not None else unit or units_in.get(target)
            if noted:
                units_out[target] = str(noted)
        channels[target] = arr
        origin[target] = name
    if flip_force:
        channels[FORCE] = -channels[FORCE]
    if flip_acceleration or acceleration_includes_gravity:
        if ACCELERATION not in channels:
            raise RecordingError(f"{source}: flip_acceleration/acceleration_includes_gravity need an acceleration "
                                 f"channel; channels found: {names}")
        if flip_acceleration:
            channels[ACCELERATION] = -channels[ACCELERATION]
        if acceleration_includes_gravity:  # specific force along the downward axis reads a − g
            channels[ACCELERATION] = channels[ACCELERATION] + STANDARD_GRAVITY

    rate, start = raw.sample_rate, raw.start_time
    if rate is not None:
        rate = check_sample_rate(rate, f"{source}: sample rate stated in the file")
    if raw_time is not None:
        time_rate, time_start = time_base_of(raw_time[0], raw_time[1], source)
        if raw_time[1] in (None, ""):
            assumed["time"] = "s"
            if time_rate < UNITLESS_RATE_FLOOR:
                raise RecordingError(
                    f"{source}: the time column states no unit; read in seconds its step gives {time_rate:g} Hz, "
                    f"no sample rate for an impact record; expected the units stated {unit_statement(source)}")
        else:
            check_impact_time_base(time_rate, np.size(raw_time[0]), str(raw_time[1]), source)
        if rate is not None and abs(time_rate - rate) > 1e-3 * rate:
            raise RecordingError(f"{source}: time column gives {time_rate:g} Hz but the file states {rate:g} Hz")
        rate, start = rate or time_rate, time_start  # a stated rate is exact, a printed time column rounded
        if np.size(raw_time[0]) != next(iter(channels.values())).size:
            raise RecordingError(f"{source}: time has {np.size(raw_time[0])} samples but the channels have "
                                 f"{next(iter(channels.values())).size}; expected equal lengths")
    if sample_rate is not None:
        given = check_sample_rate(sample_rate, f"{source}: sample_rate")
        if rate is not None and abs(given - rate) > 1e-3 * given:
            stated = "time column" if raw_time is not None else "sample rate stated in the file"
            raise RecordingError(f"{source}: sample_rate={given:g} Hz (--sample-rate) disagrees with the {stated} "
                                 f"({rate:g} Hz); expected the file's own rate: leave the option out")
        rate = given
    if rate is None:
        raise RecordingError(f"{source}: no time column and no sample rate in the file; expected a time column "
                             f"or pass sample_rate")
    metadata = {k: v for k, v in raw.metadata.items() if k != "channel_units"}
    metadata["source_channels"] = origin
    if assumed:
        metadata["units_assumed"] = assumed
    if units_out:
        metadata["channel_units"] = units_out
    flags = {"flip_force": flip_force, "flip_acceleration": flip_acceleration,
             "acceleration_includes_gravity": acceleration_includes_gravity}
    metadata["read_options"] = {k: True for k, v in flags.items() if v}
    metadata["read_options"].update({f"{UNIT_OPTIONS[k]}_unit": v for k, v in given_units.items()})
    if not metadata["read_options"]:
        del metadata["read_options"]
    return Recording(sample_rate=rate, channels=channels, start_time=0.0 if start is None else float(start),
                     metadata=metadata, source=source)


def metadata_to_json(recording: Recording) -> str:
    """Metadata of ``recording`` as JSON (numpy values made plain)."""
    return json.dumps(plain_metadata(recording.metadata), sort_keys=True)
