"""impactometer: on-line impact load identification and adaptive impact absorption.

SI units everywhere (kg, m, s, N, Pa absolute unless named ``gauge``); the axis points down; t = 0 is first contact.
"""

from .compiled_cache import remove_stale

remove_stale()  # numba's cached machine code made from other sources than these: removed before any is loaded

from .errors import (  # noqa: E402
    ControlError,
    DeviceError,
    IdentificationError,
    ImpactometerError,
    ParameterError,
    RecordingError,
    ResponseMapError,
    SimulationError,
    UnitError,
)
from .rig import PRESETS, Contact, Cylinder, Friction, Gas, Rig, Scenario, Stops, Valve, get_rig, load_toml  # noqa: E402

__version__ = "0.1.0"

__all__ = ["ControlError", "DeviceError", "IdentificationError", "ImpactometerError", "ParameterError",
           "RecordingError", "ResponseMapError", "SimulationError", "UnitError", "BatchResult", "SimulationResult",
           "simulate", "simulate_batch", "simulate_blocks", "PRESETS", "Contact", "Cylinder", "Friction", "Gas", "Rig",
           "Scenario", "Stops", "Valve", "get_rig", "load_toml", "__version__"]

_MODEL = ("BatchResult", "SimulationResult", "simulate", "simulate_batch", "simulate_blocks")


def __getattr__(name: str):
    # the model imports numba and scipy (about a second): only when asked for, so that the command line starts fast
    if name in _MODEL:
        from . import model

        return getattr(model, name)
    raise AttributeError(f"module 'impactometer' has no attribute {name!r}")

