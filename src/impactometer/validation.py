"""The one parameter check of the package: is a value a real number (or an integer) within bounds?

Every public function validates its numeric arguments through :func:`check_real` or :func:`check_integer` (arrays
of numbers through :func:`real_array`, its flags through :func:`check_flag`), so a ``bool`` (which Python counts as
an ``int``), a string, a NaN or an out-of-range value is refused the same way everywhere, with a message naming the
field, the value and what was expected.
"""

from __future__ import annotations

import functools
import math
import numbers
from collections.abc import Callable
from typing import Any, ParamSpec, TypeVar

import numpy as np

from .errors import ImpactometerError, ParameterError, ParameterTypeError, shown

P = ParamSpec("P")
R = TypeVar("R")


def is_real(value: Any) -> bool:
    """True for a real number (Python or numpy scalar), False for a bool, a string, an array or None."""
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


def is_integer(value: Any) -> bool:
    """True for an integer (Python or numpy scalar), False for a bool, a float or anything else."""
    return isinstance(value, numbers.Integral) and not isinstance(value, bool)


def _bounds(low: float | None, high: float | None, low_open: bool, high_open: bool, spec: str) -> str:
    """The range part of an expectation, with its leading space: `` within [0, 1]``, `` > 0``, `` <= 5`` or ``""``."""
    if low is not None and high is not None:
        return f" within {'(' if low_open else '['}{low:{spec}}, {high:{spec}}{')' if high_open else ']'}"
    if low is not None:
        return f" {'>' if low_open else '>='} {low:{spec}}"
    return "" if high is None else f" {'<' if high_open else '<='} {high:{spec}}"


def _refused(error: type[Exception], name: str, expected: str, got: str) -> Exception:
    """``error`` "NAME EXPECTED, got GOT", an :class:`~impactometer.errors.ImpactometerError` carrying ``name`` as
    its field and what was expected."""
    message = f"{name} {expected}, got {got}"
    if issubclass(error, ImpactometerError):
        return error(message, field=name, expected=expected)
    return error(message)


def check_real(name: str, value: Any, *, low: float | None = None, high: float | None = None,
               low_open: bool = False, high_open: bool = False, unit: str = "", finite: bool = True,
               state_range: bool = False, error: type[Exception] = ParameterError) -> float:
    """``value`` as a float, or ``error`` naming ``name``, the value and the bound it misses.

    Parameters
    ----------
    name : Field name shown in the message.
    value : The value to check.
    low, high : Bounds (None: unbounded); ``low_open``/``high_open`` exclude the bound itself.
    unit : Unit shown in the message after the bound, with its leading space, e.g. ``" [kg]"``.
    finite : Refuse infinities (NaN is always refused).
    state_range : Every message states the whole expectation (``must be a finite number > 0 [s]``, ``must be a
        number within [0, 1]``: a closed range needs no "finite") instead of the one part the value misses.
    error : Exception class raised (a subclass of :class:`~impactometer.errors.ImpactometerError`).
    """
    number = is_real(value) and not math.isnan(value) and (not finite or math.isfinite(value))
    v = float(value) if number else math.nan  # numpy scalars print as plain numbers below
    below = low is not None and (v <= low if low_open else v < low)
    above = high is not None and (v >= high if high_open else v > high)
    if state_range and not (number and not below and not above):
        finite_word = "finite " if finite and (low is None or high is None) else ""
        raise _refused(error, name, f"must be a {finite_word}number{_bounds(low, high, low_open, high_open, 'g')}"
                                    f"{unit}", shown(value))
    if not number:
        raise _refused(error, name, f"must be a {'finite ' if finite else ''}number{unit}", shown(value))
    if below:
        raise _refused(error, name, f"must be {'>' if low_open else '>='} {low:g}{unit}", repr(v))
    if above:
        raise _refused(error, name, f"must be {'<' if high_open else '<='} {high:g}{unit}", repr(v))
    return v


def check_integer(name: str, value: Any, *, low: int | None = None, high: int | None = None, unit: str = "",
                  state_range: bool = False, error: type[Exception] = ParameterError) -> int:
    """``value`` as an int, or ``error`` naming ``name``, the value and the expected range (in every message with
    ``state_range``, as :func:`check_real`)."""
    outside = is_integer(value) and ((low is not None and value < low) or (high is not None and value > high))
    if not is_integer(value) or (state_range and outside):
        raise _refused(error, name, f"must be an integer{_bounds(low, high, False, False, '')}{unit}", shown(value))
    if low is not None and value < low:
        raise _refused(error, name, f"must be an integer >= {low}{unit}", repr(int(value)))
    if high is not None and value > high:
        raise _refused(error, name, f"must be an integer <= {high}{unit}", repr(int(value)))
    return int(value)


def check_flag(name: str, value: Any, *, error: type[Exception] = ParameterError) -> bool:
    """``value`` as a bool (Python or numpy), or ``error`` saying ``name`` must be True or False: no 0, 1 or
    "yes" taken for one."""
    if not isinstance(value, (bool, np.bool_)):
        raise _refused(error, name, "must be True or False", shown(value))
    return bool(value)


def holds_flag(values: Any) -> bool:
    """True where ``values`` is a bool or holds one (a bool array, a list or tuple with a bool in it): numpy would
    read True as 1 and False as 0."""
    if isinstance(values, (bool, np.bool_)):
        return True
    if isinstance(values, (list, tuple)):
        return any(holds_flag(v) for v in values)
    if isinstance(values, np.ndarray):
        return values.dtype == bool or (values.dtype == object and any(holds_flag(v) for v in values.ravel()))
    return False


def real_array(name: str, values: Any, *, unit: str = "", error: type[Exception] = ParameterError) -> np.ndarray:
    """``values`` (a number or an array of them) as a float array, or ``error`` naming ``name`` where it is or
    holds a bool, a text or anything else that is not a real number; finiteness and bounds are the caller's."""
    expected = f"must be a number or an array of numbers{unit}"
    if holds_flag(values):
        raise _refused(error, name, expected, shown(values))
    try:
        return np.asarray(values, dtype=float)
    except (TypeError, ValueError):
        raise _refused(error, name, expected, shown(values)) from None


def is_finite(value: Any) -> bool:
    """True for a finite real number (Python or numpy scalar), False for NaN, an infinity, a bool or anything
    else."""
    return is_real(value) and math.isfinite(value)


def finite_or_none(value: Any) -> float | None:
    """``value`` as a float where it is a finite real number, else None: the JSON form of a number that may be
    unknown (NaN, an infinity, None)."""
    return float(value) if is_finite(value) else None


def renamed(**names: str) -> Callable[[Callable[P, R]], Callable[P, R]]:
    """Decorator: a call that passes a keyword by its former name (``names``: former -> present) raises
    :class:`~impactometer.errors.ParameterTypeError` naming the present one, instead of Python's bare "unexpected
    keyword argument"."""
    def wrap(func: Callable[P, R]) -> Callable[P, R]:
        @functools.wraps(func)
        def call(*args: P.args, **kwargs: P.kwargs) -> R:
            for old, new in names.items():
                if old in kwargs:
                    raise ParameterTypeError(f"{old} is now named {new}: pass {new}={shown(kwargs[old])}", field=old,
                                             expected=f"named {new}")
            return func(*args, **kwargs)
        return call
    return wrap
