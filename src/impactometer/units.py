"""Parsing of quantities with unit suffixes (``"200kPa"``, ``"30kg"``, ``"0.3m"``, ``"50kHz"``, ``"2%"``).

Used only at the edges (CLI, files): everything inside the package is SI.
"""

from __future__ import annotations

import math
import re

from .errors import UnitError

#: unit symbol -> (dimension, factor to SI)
UNITS: dict[str, tuple[str, float]] = {
    "kg": ("mass", 1.0), "g_mass": ("mass", 1e-3), "t": ("mass", 1e3), "lb": ("mass", 0.45359237),
    "m": ("length", 1.0), "cm": ("length", 1e-2), "mm": ("length", 1e-3), "km": ("length", 1e3),
    "m/s": ("velocity", 1.0), "km/h": ("velocity", 1 / 3.6), "mm/s": ("velocity", 1e-3),
    "pa": ("pressure", 1.0), "kpa": ("pressure", 1e3), "mpa": ("pressure", 1e6), "bar": ("pressure", 1e5),
    "mbar": ("pressure", 1e2), "psi": ("pressure", 6894.757293168),
    "s": ("time", 1.0), "ms": ("time", 1e-3), "us": ("time", 1e-6), "µs": ("time", 1e-6),
    "hz": ("frequency", 1.0), "khz": ("frequency", 1e3), "mhz": ("frequency", 1e6),
    "n": ("force", 1.0), "kn": ("force", 1e3),
    "m/s2": ("acceleration", 1.0), "m/s^2": ("acceleration", 1.0), "m/s²": ("acceleration", 1.0),
    "g": ("acceleration", 9.80665),
    "%": ("fraction", 1e-2),
    "n/m": ("stiffness", 1.0), "kn/m": ("stiffness", 1e3), "kn/mm": ("stiffness", 1e6),
    "m2": ("area", 1.0), "mm2": ("area", 1e-6), "mm^2": ("area", 1e-6), "cm2": ("area", 1e-4),
}

_NUMBER = re.compile(r"^\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?|[-+]?inf|nan)\s*(.*?)\s*$", re.IGNORECASE)


def parse_quantity(text: str | float | int, dimension: str, *, field: str = "value") -> float:
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

    Returns
    -------
    float
        The value in SI units (fractions as plain numbers, ``2%`` -> 0.02).
    """
    if isinstance(text, bool):
        raise UnitError(f"{field} must be a number with an optional {dimension} unit, got {text!r}")
    if isinstance(text, (int, float)):
        if not math.isfinite(text):
            raise UnitError(f"{field} must be a finite number, got {text!r}")
        return float(text)
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
        return value
    key = unit.lower().replace("\u03bc", "\u00b5")  # Greek mu (as upper/lower-casing makes it) -> micro sign
    if dimension == "mass" and key == "g":
        key = "g_mass"
    if key not in UNITS or UNITS[key][0] != dimension:
        valid = sorted(u for u, (d, _) in UNITS.items() if d == dimension)
        raise UnitError(f"{field}: unknown {dimension} unit {unit!r} in {text!r}; expected one of "
                        f"{', '.join(u.replace('g_mass', 'g') for u in valid)}")
    return value * UNITS[key][1]


def _example(dimension: str) -> str:
    return {"mass": "30kg", "length": "0.2m", "velocity": "2m/s", "pressure": "200kPa", "time": "50ms",
            "frequency": "50kHz", "fraction": "2%"}.get(dimension, "1.0")
