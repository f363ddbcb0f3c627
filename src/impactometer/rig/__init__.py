"""The drop stand: its parts (:mod:`.parts`), what a drop test and a stand can be (:mod:`.limits`) and the stand
itself with its presets, TOML files and scenarios (:mod:`.stand`); this package only re-exports."""

from __future__ import annotations

from .limits import CYLINDER_LIMITS, FREE_FALL_HEIGHTS, MASS_RANGE, VELOCITY_RANGE, check_stops
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
from .stand import (
    ABSORPTION_RIG,
    PAD_STAND,
    PRESETS,
    PROVENANCE_KEY,
    STAND_KEY,
    STIFF_STAND,
    Rig,
    Scenario,
    check_recorded_on,
    fingerprint,
    from_dict,
    get_rig,
    load_toml,
    parameter_names,
    save_toml,
    to_dict,
)

__all__ = ["ABSORPTION_RIG", "CONTACT_ALIASES", "CONTACT_LAWS", "CYLINDER_LIMITS", "FREE_FALL_HEIGHTS",
           "ISO6358_DEFAULTS", "MASS_RANGE", "PAD_STAND", "PRESETS", "PROVENANCE_KEY", "STAND_KEY", "STIFF_STAND",
           "VALVE_LAW_PARAMETERS", "VELOCITY_RANGE", "Contact", "Cylinder", "Friction", "Gas", "Rig", "Scenario",
           "Stops", "Valve", "check_recorded_on", "check_stops", "contact_law_name", "fingerprint", "from_dict",
           "get_rig", "load_toml", "parameter_names", "save_toml", "to_dict"]
