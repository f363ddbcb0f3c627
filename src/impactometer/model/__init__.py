"""The drop-stand model (paper eqs. 1-2): force laws, initial equilibrium, reference and fast integrators."""

from .dynamics import CHANNELS
from .result import BatchResult, SimulationResult
from .simulate import DEFAULT_RTOL, simulate, simulate_batch, simulate_blocks

__all__ = ["CHANNELS", "BatchResult", "SimulationResult", "DEFAULT_RTOL", "simulate", "simulate_batch",
           "simulate_blocks"]
