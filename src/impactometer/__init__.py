"""impactometer: on-line impact load identification and adaptive impact absorption.

SI units everywhere (kg, m, s, N, Pa absolute unless named ``gauge``); the axis points down; t = 0 is first contact.
"""

from .errors import (ControlError, IdentificationError, ImpactometerError, ParameterError, RecordingError,
                     ResponseMapError, SimulationError, UnitError)
from .model import BatchResult, SimulationResult, simulate, simulate_batch
from .rig import PRESETS, Contact, Cylinder, Friction, Gas, Rig, Scenario, Stops, Valve, get_rig, load_toml

__version__ = "0.1.0"

__all__ = ["ControlError", "IdentificationError", "ImpactometerError", "ParameterError", "RecordingError",
           "ResponseMapError", "SimulationError", "UnitError", "BatchResult", "SimulationResult", "simulate",
           "simulate_batch", "PRESETS", "Contact", "Cylinder", "Friction", "Gas", "Rig", "Scenario", "Stops",
           "Valve", "get_rig", "load_toml", "__version__"]
