"""The one parameter check of the package: is a value a real number (or an integer) within bounds?

Every public function validates its numeric arguments through :func:`check_real` or :func:`check_integer`, so a
``bool`` (which Python counts as an ``int``), a string, a NaN or an out-of-range value is refused the same way
everywhere, with a message naming the field, the value and what was expected.
"""

from __future__ import annotations

import math
import numbers
from typing import Any

from .errors import ParameterError, shown


def is_real(value: Any) -> bool:
    """True for a real number (Python or numpy scalar), False for a bool, a string, an array or None."""
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


def is_integer(value: Any) -> bool:
    """True for an integer (Python or numpy scalar), False for a bool, a float or anything else."""
    return isinstance(value, numbers.Integral) and not isinstance(value, bool)


def check_real(name: str, value: Any, *, low: float | None = None, high: float | None = None,
               low_open: bool = False, high_open: bool = False, unit: str = "", finite: bool = True,
               error: type[Exception] = ParameterError) -> float:
    """``value`` as a float, or ``error`` naming ``name``, the value and the bound it misses.

    Parameters
    ----------
    name : Field name shown in the message.
    value : The value to check.
    low, high : Bounds (None: unbounded); ``low_open``/``high_open`` exclude the bound itself.
    unit : Unit shown in the message after the bound, with its leading space, e.g. ``" [kg]"``.
    finite : Refuse infinities (NaN is always refused).
    error : Exception class raised (a subclass of :class:`~impactometer.errors.ImpactometerError`).
    """
    if not is_real(value) or math.isnan(value) or (finite and not math.isfinite(value)):
        raise error(f"{name} must be a {'finite ' if finite else ''}number{unit}, got {shown(value)}")
    v = float(value)  # numpy scalars print as plain numbers below
    if low is not None and (v <= low if low_open else v < low):
        raise error(f"{name} must be {'>' if low_open else '>='} {low:g}{unit}, got {v!r}")
    if high is not None and (v >= high if high_open else v > high):
        raise error(f"{name} must be {'<' if high_open else '<='} {high:g}{unit}, got {v!r}")
    return v


def check_integer(name: str, value: Any, *, low: int | None = None, high: int | None = None, unit: str = "",
                  error: type[Exception] = ParameterError) -> int:
    """``value`` as an int, or ``error`` naming ``name``, the value and the expected range."""
    if not is_integer(value):
        bounds = (f" within [{low}, {high}]" if low is not None and high is not None else
                  f" >= {low}" if low is not None else f" <= {high}" if high is not None else "")
        raise error(f"{name} must be an integer{bounds}{unit}, got {shown(value)}")
    if low is not None and value < low:
        raise error(f"{name} must be an integer >= {low}{unit}, got {int(value)!r}")
    if high is not None and value > high:
        raise error(f"{name} must be an integer <= {high}{unit}, got {int(value)!r}")
    return int(value)


def is_finite(value: Any) -> bool:
    """True for a finite real number (Python or numpy scalar), False for NaN, an infinity, a bool or anything
    else."""
    return is_real(value) and math.isfinite(value)


def finite_or_none(value: Any) -> float | None:
    """``value`` as a float where it is a finite real number, else None: the JSON form of a number that may be
    unknown (NaN, an infinity, None)."""
    return float(value) if is_finite(value) else None
