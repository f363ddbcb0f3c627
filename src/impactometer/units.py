"""Parsing of quantities with unit suffixes (``"200kPa"``, ``"30kg"``, ``"0.3m"``, ``"50kHz"``, ``"2%"``).

Used only at the edges (CLI, files): everything inside the package is SI. Symbols are read as written where case
tells two units apart (``mHz`` is milli-, ``MHz`` mega-hertz; ``mPa`` and ``MPa``); elsewhere case does not matter
(``khz``, ``KPA``, ``KN``), and a spelling that could be either of two units (``mhz``) is refused.
"""

from __future__ import annotations

import math
import re

from .constants import STANDARD_GRAVITY
from .errors import UnitError
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
        return value
    known = find_unit(unit, dimension, field=field)
    if known is None:
        raise UnitError(f"{field}: unknown {dimension} unit {unit!r} in {text!r}; expected one of "
                        f"{', '.join(UNITS.get(dimension, {}))}")
    result = value * known[1]
    if not math.isfinite(result):
        raise UnitError(f"{field} must be a finite number, got {text!r} ({value:g} {unit} overflows)")
    return result


def _example(dimension: str) -> str:
    return {"mass": "30kg", "length": "0.2m", "velocity": "2m/s", "pressure": "200kPa", "time": "50ms",
            "frequency": "50kHz", "fraction": "2%"}.get(dimension, "1.0")
