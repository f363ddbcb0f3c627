"""Adaptive impact absorption (paper section 6, Fig. 10): valve Z, absorption strategies and the closed loop
identify → control.

``absorb(scenario, strategy="all")`` runs the loop on one impact; ``study.absorption_table()`` over the paper's
125-case grid.
"""

from .loop import AbsorptionResult, absorb
from .plant import simulate_controlled
from .settings import ControlSettings
from .strategies import STRATEGIES, get_strategy
from .valve import Absorber, ValveDrive, valve_mass_flow

__all__ = ["AbsorptionResult", "Absorber", "ControlSettings", "STRATEGIES", "ValveDrive", "absorb", "get_strategy",
           "simulate_controlled", "valve_mass_flow"]
