"""Parsing of quantities with unit suffixes (``"200kPa"``, ``"30kg"``, ``"0.3m"``, ``"50kHz"``, ``"2%"``).

Used only at the edges (CLI, files): everything inside the package is SI. Symbols are read as written where case
tells two units apart (``mHz`` is milli-, ``MHz`` mega-hertz; ``mPa`` and ``MPa``); elsewhere case does not matter
(``khz``, ``KPA``, ``KN``), and a spelling that could be either of two units (``mhz``) is refused.

On the command line a bare number (SI) outside the range a drop test makes plausible for its quantity
(:data:`BARE_RANGES`) is refused with the unit most likely meant: ``--pressure 200`` is 200 Pa, which nobody charges
a cylinder to, and almost always means 200 kPa. A unit suffix, SI included (``200Pa``), is always taken as meant.
"""

from __future__ import annotations

import math
import re

from .constants import STANDARD_GRAVITY
from .errors import UnitError
from .rig.limits import FREE_FALL_HEIGHTS, VELOCITY_RANGE
from .validation import check_real, is_real

#: dimension -> unit symbol (as written) -> factor to SI
UNITS: dict[str, dict[str, float]] = {
    "mass": {"kg": 1.0, "g": 1e-3, "t": 1e3, "lb": 0.45359237},
    "length": {"m": 1.0, "cm": 1e-2, "mm": 1e-3, "km": 1e3},
    "velocity": {"m/s": 1.0, "km/h": 1 / 3.6, "mm/s": 1e-3},
    "pressure": {"Pa": 1.0, "mPa": 1e-3, "kPa": 1e3, "MPa": 1e6, "bar": 1e5, "mbar": 1e2, "psi": 6894.757293168},
    "time": {"s": 1.0, "ms": 1e-3, "us": 1e-6, "µs": 1e-6},
    "frequency": {"Hz": 1.0, "mHz": 1e-3, "kHz": 1e3, "MHz": 1e6, "GHz": 1e9},
    "force": {"N": 1.0, "kN": 1e3},
    "acceleration": {"m/s2": 1.0, "m/s^2": 1.0, "m/s²": 1.0, "g": STANDARD_GRAVITY},
    "fraction": {"%": 1e-2},
    "stiffness": {"N/m": 1.0, "kN/m": 1e3, "kN/mm": 1e6},
    "area": {"m2": 1.0, "mm2": 1e-6, "mm^2": 1e-6, "cm2": 1e-4},
}

#: dimension -> (low, high, units meant): a bare number (SI) of that dimension is plausible for a drop test within
#: [low, high] (0 always is: it is 0 in any unit, and negative values are left to the checks of the quantity);
#: outside, the units in the tuple that bring it within are named as the likely intent
BARE_RANGES: dict[str, tuple[float, float, tuple[str, ...]]] = {
    "mass": (0.0, 1e3, ("g",)),  # a mass above a tonne written in grams
    "length": (0.0, FREE_FALL_HEIGHTS[1], ("cm", "mm")),  # a drop height above the stand's 12 m
    "velocity": (0.0, VELOCITY_RANGE[1], ("mm/s", "km/h")),  # faster than a free fall from 12 m
    "pressure": (1e3, math.inf, ("kPa",)),  # a charge pressure below 1 kPa gauge
    "time": (0.0, 10.0, ("ms",)),  # a record or window longer than 10 s
    "frequency": (1e3, math.inf, ("kHz",)),  # a sample rate below 1 kHz
    "fraction": (0.0, 0.5, ("%",)),  # noise above half of a channel's RMS
}

_NUMBER = re.compile(r"^\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?|[-+]?inf|nan)\s*(.*?)\s*$", re.IGNORECASE)


def find_unit(symbol: str, dimension: str | None = None, *, field: str = "unit",
              extra: dict[str, dict[str, float]] | None = None) -> tuple[str, float] | None:
    """(dimension, factor to SI) of a unit ``symbol``, or None when it is unknown.

    The symbol is taken as written first; otherwise its case is ignored, unless that makes it match two units of
    different size (``mhz``: milli or mega?), which raises UnitError. Without ``dimension`` every dimension is
    searched, ``g`` meaning standard gravity. ``extra`` adds units (same layout as :data:`UNITS`).
    """
    key = symbol.strip().replace("\u03bc", "\u00b5")  # Greek mu (as upper/lower-casing makes it) -> micro sign
    tables = dict(UNITS)
    for name, units in (extra or {}).items():
        tables[name] = {**tables.get(name, {}), **units}
    if dimension is not None:
        tables = {dimension: tables.get(dimension, {})}
    else:
        tables["mass"] = {k: v for k, v in tables["mass"].items() if k != "g"}
    exact = [(name, units[key]) for name, units in tables.items() if key in units]
    if exact:
        return exact[0]
    folded = {(name, unit, factor) for name, units in tables.items() for unit, factor in units.items()
              if _fold(unit) == _fold(key)}
    if len({(name, factor) for name, _, factor in folded}) > 1:
        spelled = " or ".join(sorted(unit for _, unit, _ in folded))
        raise UnitError(f"{field}: unit {symbol!r} is ambiguous; write {spelled} (case tells milli- from "
                        "mega-)")
    return next(((name, factor) for name, _, factor in folded), None)


def _fold(symbol: str) -> str:
    return symbol.lower().replace("\u03bc", "\u00b5")  # upper-casing µ gives Greek capital mu, lower-casing that mu


def parse_quantity(text: str | float | int, dimension: str, *, field: str = "value", plausible: bool = False) -> float:
    """Parse ``text`` as a quantity of ``dimension`` and return it in SI units.

    Parameters
    ----------
    text : str or float
        A number, optionally followed by a unit symbol (``"200kPa"``, ``"0.3 m"``). A bare number is taken as SI.
    dimension : str
        Expected dimension: ``mass``, ``length``, ``velocity``, ``pressure``, ``time``, ``frequency``, ``force``,
        ``acceleration``, ``fraction``, ``stiffness`` or ``area``.
    field : str
        Name used in error messages.
    plausible : bool
        Refuse a bare number outside the plausible range of ``dimension`` (:data:`BARE_RANGES`), naming the unit
        most likely meant and the explicit spelling that keeps the number as it is (the command line).

    Returns
    -------
    float
        The value in SI units (fractions as plain numbers, ``2%`` -> 0.02).
    """
    if not isinstance(dimension, str) or (dimension not in UNITS and dimension != "number"):
        raise UnitError(f"dimension must be one of {sorted(UNITS)} or 'number', got {dimension!r}")
    if is_real(text):
        return check_real(field, text, error=UnitError)
    if not isinstance(text, str):
        raise UnitError(f"{field} must be a number with an optional {dimension} unit, got {text!r}")
    match = _NUMBER.match(text)
    if match is None:
        raise UnitError(f"{field} must be a number with an optional {dimension} unit (e.g. "
                        f"{_example(dimension)}), got {text!r}")
    value = float(match.group(1))
    unit = match.group(2)
    if not math.isfinite(value):
        raise UnitError(f"{field} must be a finite number with an optional {dimension} unit, got {text!r}")
    if not unit:
        if plausible:
            check_bare(match.group(1), value, dimension, field)
        return value
    known = find_unit(unit, dimension, field=field)
    if known is None:
        raise UnitError(f"{field}: unknown {dimension} unit {unit!r} in {text!r}; expected one of "
                        f"{', '.join(UNITS.get(dimension, {}))}")
    result = value * known[1]
    if not math.isfinite(result):
        raise UnitError(f"{field} must be a finite number, got {text!r} ({value:g} {unit} overflows)")
    return result


def check_bare(number: str, value: float, dimension: str, field: str) -> None:
    """UnitError when the bare ``number`` (``value`` in SI) lies outside the plausible range of ``dimension``
    (:data:`BARE_RANGES`): one line naming ``field``, the text, the units likely meant and how to keep the value."""
    if dimension not in BARE_RANGES or not value > 0:
        return
    low, high, _ = BARE_RANGES[dimension]
    if low <= value <= high:
        return
    units = UNITS[dimension]
    likely = [f"{number}{unit}" for unit in likely_units(value, dimension)]
    if dimension == "fraction":
        reading, kept = f"a fraction ({number} = {value:.0%})", f"{value * 100:g}%"
    else:
        si = next(unit for unit, factor in units.items() if factor == 1.0)
        reading, kept = f"SI ({si})", f"{number}{si}"
    guess = f"did you mean {' or '.join(likely)}?" if likely else f"an implausible {dimension}; give its unit"
    raise UnitError(f"{field} {number}: a bare number is {reading}; {guess} (write {kept} to mean it)")


def likely_units(value: float, dimension: str) -> list[str]:
    """The units of :data:`BARE_RANGES` most likely meant for ``value`` [SI] of ``dimension``, a number outside
    the plausible range read as SI: those that bring it within (none for a plausible value)."""
    if dimension not in BARE_RANGES or not value > 0:
        return []
    low, high, meant = BARE_RANGES[dimension]
    if low <= value <= high:
        return []
    return [unit for unit in meant if low <= value * UNITS[dimension][unit] <= high]


def _example(dimension: str) -> str:
    return {"mass": "30kg", "length": "0.2m", "velocity": "2m/s", "pressure": "200kPa", "time": "50ms",
            "frequency": "50kHz", "fraction": "2%"}.get(dimension, "1.0")
