"""The drop stand (its parts are in :mod:`impactometer.rig.parts`), its presets, TOML files and scenarios.

A stand is loaded from and saved to TOML (unknown keys are errors; a ``[provenance]`` table, which a calibrated
stand carries, is read past: it says where the numbers came from and changes no physics).
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
import hashlib
import json
import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import tomli_w

from ..constants import STANDARD_GRAVITY
from ..errors import ParameterError
from ..outputs import as_path, check_file, write_failed
from ..validation import check_real, is_real
from .limits import MASS_RANGE, VELOCITY_RANGE, check_stops
from .parts import (  # noqa: F401 - the parts are part of the stand's API
    CONTACT_ALIASES,
    CONTACT_LAWS,
    VALVE_LAW_PARAMETERS,
    Contact,
    Cylinder,
    Friction,
    Gas,
    Stops,
    Valve,
    contact_law_name,
)

if TYPE_CHECKING:  # annotations only: recording.py is a layer above the stand
    from ..recording import Recording


@dataclass(frozen=True, kw_only=True)
class Rig:
    """The whole drop stand."""

    name: str = "drop-stand"
    cylinder: Cylinder = field(default_factory=Cylinder)
    gas: Gas = field(default_factory=Gas)
    friction: Friction = field(default_factory=Friction)
    contact: Contact = field(default_factory=Contact)
    stops: Stops = field(default_factory=Stops)
    valve: Valve = field(default_factory=Valve)
    gravity: float = STANDARD_GRAVITY

    def __post_init__(self) -> None:
        for name, kind in _SECTIONS.items():
            if not isinstance(getattr(self, name), kind):
                raise ParameterError(f"rig.{name} must be a {kind.__name__}, got {getattr(self, name)!r}")
        check_real("rig.gravity", self.gravity, low=0.0)
        if not isinstance(self.name, str):
            raise ParameterError(f"rig.name must be a string, got {self.name!r}")
        check_stops(self)

    def with_contact(self, law: str) -> Rig:
        """This stand with the default contact of ``law``."""
        return dataclasses.replace(self, contact=Contact.preset(law))

    def replace(self, **changes: Any) -> Rig:
        """A copy with dotted-name changes, e.g. ``rig.replace(**{"contact.stiffness": 3e6})``.

        Changing ``contact.law`` keeps only the contact parameters given with it; the others take the new law's
        defaults (the parameters of one law mean nothing to another). Changing ``valve.law`` likewise drops the
        ISO 6358 parameters of the old law.
        """
        data = to_dict(self)
        valid = parameter_names() + ["name", "contact.law", "valve.law"]
        if "contact.law" in changes and contact_law_name(changes["contact.law"]) != self.contact.law:
            data["contact"] = {"law": self.contact.law}
        if "valve.law" in changes and changes["valve.law"] != self.valve.law:
            for name in VALVE_LAW_PARAMETERS.get(self.valve.law, ()):
                if name != "discharge_coefficient":
                    data["valve"].pop(name, None)
        for key, value in changes.items():
            if key not in valid:
                raise ParameterError(f"unknown rig parameter {key!r}; expected one of {valid}")
            section, _, attr = key.rpartition(".")
            (data[section] if section else data)[attr] = value
        return from_dict(data)

    def to_toml(self, path: str | Path, *, overwrite: bool = False) -> Path:
        """Save as TOML; refuses to overwrite an existing file unless ``overwrite``."""
        return save_toml(self, path, overwrite=overwrite)


#: the table of a stand file that says where its numbers came from (read past by :func:`from_dict`)
PROVENANCE_KEY = "provenance"


def _plain(value: Any) -> Any:
    """``value`` as TOML holds it: numpy numbers as Python ones, tuples as lists, None left out of tables."""
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items() if v is not None}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value if v is not None]
    if hasattr(value, "item") and not isinstance(value, (str, bytes)):
        return value.item()
    return value


_SECTIONS: dict[str, type] = {"cylinder": Cylinder, "gas": Gas, "friction": Friction, "contact": Contact,
                              "stops": Stops, "valve": Valve}


def to_dict(rig: Rig) -> dict[str, Any]:
    """Nested plain dictionary of ``rig`` (TOML shape; the contact holds only its law's parameters)."""
    data = dataclasses.asdict(rig)
    for section in ("contact", "valve"):
        data[section] = {k: v for k, v in data[section].items() if v is not None}
    return data


def from_dict(data: dict[str, Any], *, source: str = "rig") -> Rig:
    """Build a :class:`Rig` from a nested dictionary; unknown keys are errors.

    A ``[contact]`` section takes its law's defaults for the parameters it leaves out.
    """
    if not isinstance(data, dict):
        raise ParameterError(f"{source}: expected a table of rig sections, got {type(data).__name__}")
    known_top = set(_SECTIONS) | {"name", "gravity"}
    unknown = sorted(set(data) - known_top - {PROVENANCE_KEY})
    if not isinstance(data.get(PROVENANCE_KEY, {}), dict):
        raise ParameterError(f"{source}: [{PROVENANCE_KEY}] must be a table, got {data[PROVENANCE_KEY]!r}")
    if unknown:
        raise ParameterError(f"{source}: unknown key(s) {unknown}; expected {sorted(known_top)}")
    kwargs: dict[str, Any] = {k: data[k] for k in ("name", "gravity") if k in data}
    for name, kind in _SECTIONS.items():
        section = data.get(name, {})
        if not isinstance(section, dict):
            raise ParameterError(f"{source}: [{name}] must be a table, got {section!r}")
        fields = {f.name for f in dataclasses.fields(kind)}
        bad = sorted(set(section) - fields)
        if bad:
            raise ParameterError(f"{source}: unknown key(s) {[f'{name}.{b}' for b in bad]}; "
                                 f"expected {sorted(f'{name}.{f}' for f in fields)}")
        try:
            kwargs[name] = kind(**section)
        except TypeError as exc:  # pragma: no cover - keys were checked above
            raise ParameterError(f"{source}: [{name}] {exc}") from None
    return Rig(**kwargs)


def parameter_names() -> list[str]:
    """Dotted names of every numeric stand parameter (usable in :meth:`Rig.replace` and batch overrides)."""
    names = ["gravity"]
    for name, kind in _SECTIONS.items():
        names += [f"{name}.{f.name}" for f in dataclasses.fields(kind) if f.name != "law"]
    return names


def load_toml(path: str | Path) -> Rig:
    """Load a stand from a TOML file."""
    path = as_path(path, "rig file")
    if not path.is_file():
        raise ParameterError(f"rig file {str(path)!r} does not exist")
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise ParameterError(f"rig file {str(path)!r} is not valid TOML: {exc}") from None
    except RecursionError:
        raise ParameterError(f"rig file {str(path)!r} nests arrays or tables too deeply; expected a stand "
                             "description (sections of numbers)") from None
    return from_dict(data, source=str(path))


def save_toml(rig: Rig, path: str | Path, *, overwrite: bool = False,
              provenance: dict[str, Any] | None = None) -> Path:
    """Write ``rig`` to ``path`` as TOML, with a ``[provenance]`` table when ``provenance`` is given (plain numbers,
    strings, lists and tables; None values are left out)."""
    if not isinstance(rig, Rig):
        raise ParameterError(f"rig must be a Rig, got {type(rig).__name__}")
    path = check_file(path, "rig file", overwrite=overwrite, flag="overwrite=True")
    data = to_dict(rig)
    if provenance is not None:
        data[PROVENANCE_KEY] = _plain(provenance)
    try:
        path.write_text(tomli_w.dumps(data), encoding="utf-8")
    except OSError as exc:
        raise write_failed(path, exc) from None
    return path


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


@dataclass(frozen=True, kw_only=True)
class Scenario:
    """One drop test: impacting mass M1 [kg], impact velocity V0 [m/s], charge pressure p0 [Pa gauge]."""

    mass: float
    velocity: float
    pressure_gauge: float = 200e3

    def __post_init__(self) -> None:
        check_real("mass", self.mass, low=MASS_RANGE[0], high=MASS_RANGE[1], unit=" [kg]")
        check_real("velocity", self.velocity, low=0.0, low_open=True, high=VELOCITY_RANGE[1], unit=" [m/s]")
        check_real("pressure_gauge", self.pressure_gauge, low=0.0, unit=" [Pa]")

    @classmethod
    def from_height(cls, *, mass: float, height: float, pressure_gauge: float = 200e3,
                    gravity: float = STANDARD_GRAVITY) -> Scenario:
        """Scenario of a free drop from ``height`` [m]: V0 = sqrt(2·g·h)."""
        check_real("height", height, low=0.0, low_open=True, unit=" [m]")
        return cls(mass=mass, velocity=math.sqrt(2.0 * gravity * height), pressure_gauge=pressure_gauge)

    def check_against(self, rig: Rig) -> None:
        """Raise unless the charge pressure is within the rating of ``rig``."""
        if self.pressure_gauge > rig.cylinder.rated_pressure_gauge:
            raise ParameterError(f"pressure_gauge must be <= the rated {rig.cylinder.rated_pressure_gauge:g} Pa "
                                 f"of {rig.name!r}, got {self.pressure_gauge!r}")


#: metadata key holding the fingerprint of the stand a recording was made on
STAND_KEY = "rig_fingerprint"


def fingerprint(rig: Rig | dict[str, Any]) -> str:
    """A short hash of every parameter of a stand (a :class:`~impactometer.rig.Rig` or its ``to_dict`` form).

    Two stands with the same parameters have the same fingerprint whatever their names (a name is a label) and
    however their numbers are written (``2e6`` or ``2000000``); any other parameter gives another fingerprint.
    """
    stand = rig if isinstance(rig, Rig) else from_dict(rig, source="stand")

    def canonical(value: Any) -> Any:  # every number as a float: 2e6 and 2000000 hash alike
        if isinstance(value, dict):
            return {k: canonical(v) for k, v in value.items()}
        return float(value) if is_real(value) else value

    data = canonical({k: v for k, v in to_dict(stand).items() if k != "name"})
    return hashlib.sha256(json.dumps(data, sort_keys=True).encode()).hexdigest()[:16]


def check_recorded_on(recording: Recording, stand: dict[str, Any], *, hint: str,
                      error: type[Exception] = ParameterError) -> None:
    """``error`` when ``recording`` states a stand (:data:`STAND_KEY`) with other parameters than ``stand``."""
    stated = recording.metadata.get(STAND_KEY)
    if stated is None:
        return
    expected = fingerprint(stand)
    if str(stated) != expected:
        name = recording.metadata.get("rig")
        raise error(f"{recording.source}: recorded on a stand{f' labelled {name!r}' if name else ''} with other "
                    f"parameters (fingerprint {str(stated)[:16]}) than the stand {stand.get('name')!r} (fingerprint "
                    f"{expected}); {hint}")
