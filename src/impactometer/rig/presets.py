"""The named stands, :data:`PRESETS`, and :func:`get_rig`: a stand by preset name, by TOML file or the default.

``PRESETS['drop-stand']`` is the built-in stand, representative of the stand of the reference paper (Fig. 1): a 4 kg
piston and rod in an 80 mm bore, 25 mm rod, 200 mm stroke, charged to 0-400 kPa gauge, with a hysteretic
elastomer pad between mass and rod (Walton-Braun, loading stiffness 7e5 N/m, restitution 0.4), 200 N of seal
friction, end-of-stroke gas cushions and
an ISO 6358 valve between the chambers: a rebound or two (stage A), then sustained contact to the deepest point
(stage B), as the paper describes (Fig. 2). It is also named ``drop-stand-pad``; its parts are the defaults of the
part classes.
``PRESETS['drop-stand-stiff']`` is the earlier built-in stand: a nearly elastic
Kelvin-Voigt contact on which the rod bounces on the mass for most of the stroke, 30 N of friction, no cushions.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

from ..errors import ParameterError
from .parts import Contact, Cylinder, Friction, Valve
from .stand import Rig, load_toml

#: the stand with a nearly elastic Kelvin-Voigt contact: the rod bounces on the mass for most of the stroke
STIFF_STAND = Rig(name="drop-stand-stiff", contact=Contact(law="kelvin-voigt"), friction=Friction(force=30.0),
                  cylinder=Cylinder(dead_volume_lower=0.0, dead_volume_upper=0.0),
                  valve=Valve(law="orifice", max_area=5e-5))
#: the stand with a hysteretic elastomer pad: a rebound or two (stage A), then sustained contact (stage B); the
#: defaults of the part classes
PAD_STAND = Rig(name="drop-stand-pad")
#: named stands; ``drop-stand`` is the default (the pad stand)
PRESETS: dict[str, Rig] = {
    "drop-stand": dataclasses.replace(PAD_STAND, name="drop-stand"),
    "drop-stand-pad": PAD_STAND,
    "drop-stand-stiff": STIFF_STAND,
}


#: the stand of the absorber's commands and studies (``absorb``, ``study absorption``, ``study valve-design``)
ABSORPTION_RIG = "drop-stand"


def get_rig(name_or_path: str | Path | Rig | None = None, *, contact: str | None = None) -> Rig:
    """A preset by name, a TOML file by path, or the default stand; optionally with another contact law."""
    if isinstance(name_or_path, Rig):
        rig = name_or_path
    elif name_or_path is None:
        rig = PRESETS["drop-stand"]
    elif not isinstance(name_or_path, (str, Path)):
        raise ParameterError(f"rig must be a Rig, a preset name or a .toml file, got {type(name_or_path).__name__}")
    elif str(name_or_path) in PRESETS:
        rig = PRESETS[str(name_or_path)]
    elif Path(name_or_path).suffix.lower() == ".toml":
        rig = load_toml(name_or_path)
    else:
        raise ParameterError(f"rig must be one of {sorted(PRESETS)} or a .toml file, got {str(name_or_path)!r}")
    return rig.with_contact(contact) if contact is not None else rig
