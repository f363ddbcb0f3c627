"""Exception hierarchy of impactometer.

Every error raised on purpose by the package derives from :class:`ImpactometerError` and from the builtin that
matches its meaning, so callers can catch either ``ImpactometerError`` or, e.g., ``ValueError``.
"""

from __future__ import annotations

from typing import Any


def shown(value: Any) -> str:
    """``repr(value)`` for an error message, a numpy scalar shown as the plain number it holds (3.0, not
    np.float64(3.0)), and cut to 80 characters."""
    item = getattr(value, "item", None)
    if callable(item) and getattr(value, "shape", None) == ():
        value = item()
    text = repr(value)
    return text if len(text) <= 80 else text[:77] + "..."


class ImpactometerError(Exception):
    """Base class of every error impactometer raises on purpose."""


class ParameterError(ImpactometerError, ValueError):
    """A parameter (stand, scenario, option) is missing, of the wrong type or out of range."""


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
