"""Exception hierarchy of impactometer.

Every error raised on purpose by the package derives from :class:`ImpactometerError` and from the builtin that
matches its meaning, so callers can catch either ``ImpactometerError`` or, e.g., ``ValueError``.
"""

from __future__ import annotations

import re
from typing import Any


def shown(value: Any) -> str:
    """``repr(value)`` for an error message, a numpy scalar shown as the plain number it holds (3.0, not
    np.float64(3.0)), and cut to 80 characters."""
    item = getattr(value, "item", None)
    if callable(item) and getattr(value, "shape", None) == ():
        value = item()
    text = repr(value)
    return text if len(text) <= 80 else text[:77] + "..."


#: the house form of a message about one parameter: "FIELD must EXPECTATION, got VALUE" (FIELD may carry an index,
#: ``pressure_gauge[2]``, or a section, ``contact.law``)
_ABOUT_FIELD = re.compile(r"^(?P<field>[A-Za-z_][\w.]*)(?:\[\d+\])? (?P<expected>must .+?)(?:, got .*)?$", re.S)


class ImpactometerError(Exception):
    """Base class of every error impactometer raises on purpose.

    Attributes
    ----------
    field : str or None
        The parameter the error is about, as the Python API names it (``mass``, ``pressure_gauge``, ``cfc``);
        None where the error is not about one parameter.
    expected : str or None
        What that parameter must be, without its name or value (``must be >= 0.1 [kg]``); None where unknown.

    Both are given as keywords, or else read from a message of the house form ``"FIELD must EXPECTATION, got
    VALUE"``; the command line uses them to name its option and the user's text instead of the Python name.
    """

    def __init__(self, *args: Any, field: str | None = None, expected: str | None = None) -> None:
        super().__init__(*args)
        about = _ABOUT_FIELD.match(args[0]) if len(args) == 1 and isinstance(args[0], str) else None
        self.field = field if field is not None else about["field"] if about else None
        self.expected = expected if expected is not None else about["expected"] if about else None


class ParameterError(ImpactometerError, ValueError):
    """A parameter (stand, scenario, option) is missing, of the wrong type or out of range."""


class ParameterTypeError(ParameterError, TypeError):
    """A parameter is of the wrong type (a number where names are expected, a text where a function is)."""


class UnitError(ParameterError):
    """A quantity with a unit suffix could not be parsed or has the wrong dimension."""


class SimulationError(ImpactometerError, RuntimeError):
    """The integrator failed; no partial result is returned."""


class RecordingError(ImpactometerError, ValueError):
    """A recording or a file holding one is malformed or does not fit what was asked."""


class IdentificationError(ImpactometerError, ValueError):
    """The signal does not allow an identification (no impact, too short, saturated, ...)."""


class ResponseMapError(ImpactometerError, ValueError):
    """A response map is corrupt, of another schema, or does not fit the measurement."""


class ControlError(ImpactometerError, RuntimeError):
    """An absorption strategy could not be computed or applied."""


class DeviceError(ImpactometerError, RuntimeError):
    """The requested compute device cannot be used (no GPU, or the optional GPU support is not installed)."""


class OutputError(ImpactometerError, OSError):
    """A result could not be written (disk full, permission denied, ...); nothing half-written is left."""
