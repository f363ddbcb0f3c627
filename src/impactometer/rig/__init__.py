"""The drop stand: its parts, what it can physically be, the named stands, its TOML file and the drop tests on it.

One room per concept; this package only re-exports (``from impactometer.rig import Rig, Scenario, get_rig``):

- :mod:`.parts`: the stand's parts (cylinder, gas, seal friction, contact element, stops, valve), each a frozen
  dataclass validated when it is created, the contact laws and the valve laws;
- :mod:`.limits`: what a drop test and a stand can physically be (impact velocities, masses, cylinder sizes);
- :mod:`.stand`: :class:`Rig`, the whole stand, with its dictionary form and TOML load and save;
- :mod:`.toml`: the stand file (read and written with a ``[provenance]`` table that changes no physics);
- :mod:`.presets`: the named stands (:data:`PRESETS`, ``drop-stand`` the default) and :func:`get_rig`;
- :mod:`.scenario`: one drop test, :class:`Scenario` (mass, impact velocity, charge pressure);
- :mod:`.identity`: how a stand is known (the :func:`fingerprint` of its parameters that a recording states).

Imports point one way: limits <- parts <- stand (<- toml) <- presets, scenario, identity <- this facade.
"""

from __future__ import annotations

from .identity import STAND_KEY, Recorded, check_recorded_on, fingerprint
from .limits import CYLINDER_LIMITS, FREE_FALL_HEIGHTS, MASS_RANGE, VELOCITY_RANGE
from .parts import (
    CONTACT_ALIASES,
    CONTACT_LAWS,
    ISO6358_DEFAULTS,
    VALVE_LAW_PARAMETERS,
    Contact,
    Cylinder,
    Friction,
    Gas,
    Stops,
    Valve,
    contact_law_name,
)
from .presets import ABSORPTION_RIG, PAD_STAND, PRESETS, STIFF_STAND, get_rig
from .scenario import Scenario
from .stand import (
    Rig,
    check_stops,
    from_dict,
    load_toml,
    load_uncertainty,
    parameter_names,
    save_toml,
    to_dict,
    toml_text,
)
from .toml import PROVENANCE_KEY
from .uncertainty import UNCERTAINTY_KEY, StandUncertainty

__all__ = ["ABSORPTION_RIG", "CONTACT_ALIASES", "CONTACT_LAWS", "CYLINDER_LIMITS", "FREE_FALL_HEIGHTS",
           "ISO6358_DEFAULTS", "MASS_RANGE", "PAD_STAND", "PRESETS", "PROVENANCE_KEY", "STAND_KEY", "STIFF_STAND",
           "VALVE_LAW_PARAMETERS", "VELOCITY_RANGE", "Contact", "Cylinder", "Friction", "Gas", "Recorded", "Rig",
           "Scenario", "Stops", "Valve", "check_recorded_on", "check_stops", "contact_law_name", "fingerprint",
           "from_dict", "get_rig", "load_toml", "load_uncertainty", "StandUncertainty", "UNCERTAINTY_KEY",
           "parameter_names", "save_toml", "to_dict", "toml_text"]
