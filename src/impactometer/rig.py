"""The drop stand: cylinder, gas, friction, contact, stops and valve, as frozen keyword-only dataclasses.

A stand is loaded from and saved to TOML (unknown keys are errors). ``PRESETS['drop-stand']`` is the built-in
stand, representative of the stand of the reference paper (Fig. 1): a 4 kg piston and rod in an 80 mm bore,
25 mm rod, 200 mm stroke, charged to 0-400 kPa gauge, with a nearly elastic Kelvin-Voigt contact (the rod bounces
on the mass for the whole stroke; also named ``drop-stand-stiff``; the defaults of these classes).
``PRESETS['drop-stand-pad']`` has a hysteretic elastomer pad between mass and rod, 100 N of seal friction and
end-of-stroke gas cushions: a rebound or two, then sustained contact to the deepest point, as the paper describes
(Fig. 2).
"""

from __future__ import annotations

import dataclasses
import math
import numbers
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .errors import ParameterError
from .stands import CYLINDER_LIMITS, MASS_RANGE, VELOCITY_RANGE, check_stops

ATMOSPHERIC_PRESSURE = 101325.0  # [Pa]
STANDARD_GRAVITY = 9.81  # [m/s²], the value of the reference model


def _check(name: str, value: Any, *, low: float | None = None, high: float | None = None,
           low_open: bool = True, unit: str = "") -> None:
    """Raise ParameterError unless ``value`` is a finite real within the bounds."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real) or not math.isfinite(value):
        shown = float(value) if isinstance(value, numbers.Real) and not isinstance(value, bool) else value
        raise ParameterError(f"{name} must be a finite number{unit}, got {shown!r}")
    value = float(value)  # numpy scalars print as plain numbers below
    if low is not None and (value <= low if low_open else value < low):
        raise ParameterError(f"{name} must be {'>' if low_open else '>='} {low:g}{unit}, got {value!r}")
    if high is not None and value > high:
        raise ParameterError(f"{name} must be <= {high:g}{unit}, got {value!r}")


@dataclass(frozen=True, kw_only=True)
class Cylinder:
    """Pneumatic cylinder with its piston and rod.

    Attributes
    ----------
    piston_mass : Mass of piston and rod M2 [kg].
    bore : Cylinder bore diameter [m].
    rod_diameter : Rod diameter [m]; the rod passes through the upper chamber.
    stroke : Piston travel between the top and bottom stops [m].
    lower_length, upper_length : Gas column lengths with the piston at the top stop [m].
    dead_volume_lower, dead_volume_upper : Extra gas volume of ports, cushions and fittings [m³]. The pad stand's
        20 cm³ and 10 cm³ (4 mm and 2 mm of the 80 mm bore) keep a gas cushion at the end of the stroke when the
        valve has let the lower chamber empty into the upper one.
    rated_pressure_gauge : Highest admissible charge pressure above atmosphere [Pa].
    """

    piston_mass: float = 4.0
    bore: float = 0.08
    rod_diameter: float = 0.025
    stroke: float = 0.20
    lower_length: float = 0.20
    upper_length: float = 0.02
    dead_volume_lower: float = 0.0
    dead_volume_upper: float = 0.0
    rated_pressure_gauge: float = 400e3

    def __post_init__(self) -> None:
        for name, high in CYLINDER_LIMITS.items():
            _check(f"cylinder.{name}", getattr(self, name), low=0.0, high=high, low_open=not name.endswith(
                ("_length", "_lower", "_upper")))
        if self.rod_diameter >= self.bore:
            raise ParameterError(f"cylinder.rod_diameter must be < bore ({self.bore!r} m), got {self.rod_diameter!r}")
        if self.lower_length * self.area + self.dead_volume_lower <= 0.0:
            raise ParameterError("cylinder.lower_length: the lower chamber has zero gas volume; expected "
                                 "lower_length > 0 or dead_volume_lower > 0")
        if self.upper_length * self.annulus_area + self.dead_volume_upper <= 0.0:
            raise ParameterError("cylinder.upper_length: the upper chamber has zero gas volume; expected "
                                 "upper_length > 0 or dead_volume_upper > 0")
        if self.stroke > self.lower_length + self.dead_volume_lower / self.area:
            raise ParameterError(f"cylinder.stroke must not exceed the lower gas column "
                                 f"({self.lower_length!r} m), got {self.stroke!r}")

    @property
    def area(self) -> float:
        """Piston area A [m²]."""
        return math.pi * self.bore**2 / 4.0

    @property
    def rod_area(self) -> float:
        """Rod cross-section A_rod [m²]."""
        return math.pi * self.rod_diameter**2 / 4.0

    @property
    def annulus_area(self) -> float:
        """Piston area on the rod side, A - A_rod [m²]."""
        return self.area - self.rod_area


@dataclass(frozen=True, kw_only=True)
class Gas:
    """Charge gas (ideal, calorically perfect).

    Attributes
    ----------
    gamma : Adiabatic exponent [-].
    gas_constant : Specific gas constant R [J/(kg·K)].
    temperature : Charge temperature [K].
    atmospheric_pressure : Ambient pressure p_atm [Pa].
    """

    gamma: float = 1.4
    gas_constant: float = 287.05
    temperature: float = 293.15
    atmospheric_pressure: float = ATMOSPHERIC_PRESSURE

    def __post_init__(self) -> None:
        _check("gas.gamma", self.gamma, low=1.0, high=5.0 / 3.0)
        for name in ("gas_constant", "temperature", "atmospheric_pressure"):
            _check(f"gas.{name}", getattr(self, name), low=0.0)


@dataclass(frozen=True, kw_only=True)
class Friction:
    """Coulomb friction of the piston, smoothed as ``force·tanh(v2 / velocity_scale)``.

    Attributes
    ----------
    force : Coulomb friction force [N]. The pad stand's 100 N is about 15 % of the gas force on the 80 mm piston
        at 100 kPa: published thrust losses of pneumatic cylinders are 10-25 % (about 50-250 N at this bore).
    velocity_scale : Smoothing velocity [m/s]: the friction reaches 76 % of its Coulomb level at this speed.
    """

    force: float = 30.0
    velocity_scale: float = 0.01

    def __post_init__(self) -> None:
        _check("friction.force", self.force, low=0.0, low_open=False)
        _check("friction.velocity_scale", self.velocity_scale, low=0.0)


#: contact law name -> its parameters and their defaults on the built-in stand
CONTACT_LAWS: dict[str, dict[str, float]] = {
    "hysteretic": {"stiffness": 1e6, "restitution": 0.5},
    "kelvin-voigt": {"stiffness": 2e6, "damping": 150.0},
    "hunt-crossley": {"stiffness": 4e8, "damping": 0.2},
}
CONTACT_ALIASES = {"kv": "kelvin-voigt", "kelvin": "kelvin-voigt", "hunt": "hunt-crossley", "hc": "hunt-crossley",
                   "hys": "hysteretic", "walton-braun": "hysteretic"}


def contact_law_name(name: str) -> str:
    """Return the canonical contact law name for ``name`` or an alias (``kv``, ``hunt``)."""
    if not isinstance(name, str):
        raise ParameterError(f"contact.law must be a string, got {name!r}")
    key = CONTACT_ALIASES.get(name.lower(), name.lower())
    if key not in CONTACT_LAWS:
        raise ParameterError(f"contact.law must be one of {sorted(CONTACT_LAWS)} (or {sorted(CONTACT_ALIASES)}), "
                             f"got {name!r}")
    return key


@dataclass(frozen=True, kw_only=True)
class Contact:
    """Compressive-only contact between the falling mass and the rod tip (an elastomer pad or a sensor cap).

    ``hysteretic`` (Walton-Braun): loading F = k1·δ, unloading and reloading F = k2·(δ − s) with the
    set s of the current pulse [stiffness = k1 N/m, restitution e = sqrt(k1/k2), 0 < e <= 1]; the force peaks
    exactly at maximum compression and a collision keeps e² of its relative kinetic energy;
    ``kelvin-voigt`` (the default): F = k·δ + c·δ' [stiffness N/m, damping N·s/m];
    ``hunt-crossley``: F = k·δ^1.5·(1 + 1.5·α·δ') [stiffness N/m^1.5, damping = α s/m].
    The force is zero while δ <= 0 and never pulls. Parameters left out take the law's defaults
    (``CONTACT_LAWS``); a parameter of another law is an error.
    """

    law: str = "kelvin-voigt"
    # None here means "the law's default"; every law has a stiffness, so it is a float once created
    stiffness: float = None  # type: ignore[assignment]
    damping: float | None = None
    restitution: float | None = None

    def __post_init__(self) -> None:
        law = contact_law_name(self.law)
        object.__setattr__(self, "law", law)
        defaults = CONTACT_LAWS[law]
        for name in ("stiffness", "damping", "restitution"):
            value = getattr(self, name)
            if name not in defaults:
                if value is not None:
                    raise ParameterError(f"contact.{name} is not a parameter of the {law} contact law, got "
                                         f"{value!r}; expected only {sorted(defaults)} (or another contact.law)")
            elif value is None:
                object.__setattr__(self, name, defaults[name])
        _check("contact.stiffness", self.stiffness, low=0.0)
        if self.damping is not None:
            _check("contact.damping", self.damping, low=0.0, low_open=False)
        if self.restitution is not None:
            _check("contact.restitution", self.restitution, low=0.0, high=1.0,
                   unit=" (e = sqrt(k1/k2): 1 is elastic, above 1 the unloading line would be softer than the "
                        "loading line)")

    @property
    def unloading_stiffness(self) -> float:
        """Unloading stiffness k2 = k1/e² of the hysteretic law [N/m]."""
        if self.law != "hysteretic":
            raise ParameterError(f"contact.unloading_stiffness exists for the hysteretic law only, not {self.law}")
        return self.stiffness / float(self.restitution) ** 2  # type: ignore[arg-type]  # set for this law

    @classmethod
    def preset(cls, law: str) -> Contact:
        """The default contact of the built-in stand for ``law``."""
        name = contact_law_name(law)
        return cls(law=name, **CONTACT_LAWS[name])


@dataclass(frozen=True, kw_only=True)
class Stops:
    """Top and bottom stops of the piston (push only, spring-damper).

    Attributes
    ----------
    stiffness : [N/m].  damping : [N·s/m].
    """

    stiffness: float = 5e7
    damping: float = 2e3

    def __post_init__(self) -> None:
        _check("stops.stiffness", self.stiffness, low=0.0)
        _check("stops.damping", self.damping, low=0.0, low_open=False)


#: flow laws of valve Z and the parameters each one uses besides ``area`` and ``max_area``
VALVE_LAW_PARAMETERS: dict[str, tuple[str, ...]] = {"orifice": ("discharge_coefficient",),
                                                     "iso6358": ("sonic_conductance", "critical_ratio")}


@dataclass(frozen=True, kw_only=True)
class Valve:
    """Valve Z between the lower and the upper chamber (closed by default).

    ``orifice``: compressible flow through an orifice of the opening area with discharge coefficient C_d.
    ``iso6358``: the flow law of pneumatic catalogues (ISO 6358-1), q = C·p_up·ρ0·sqrt(T0/T_up)·φ(p_down/p_up, b),
    for the fully open valve; a partly open valve has the conductance C·area/max_area.

    Attributes
    ----------
    area : Constant opening area [m²] (0 = closed cylinder).
    max_area : Fully open area A_max [m²].
    law : ``"orifice"`` or ``"iso6358"``.
    discharge_coefficient : C_d [-] (orifice law).
    sonic_conductance : C of the fully open valve [m³/(s·Pa)]; 1 dm³/(s·bar) = 1e-8 m³/(s·Pa) (ISO 6358 law).
    critical_ratio : Critical pressure ratio b [-], within (0, 1) (ISO 6358 law).
    """

    area: float = 0.0
    max_area: float = 5e-5
    discharge_coefficient: float = 0.7
    law: str = "orifice"
    sonic_conductance: float | None = None
    critical_ratio: float | None = None

    def __post_init__(self) -> None:
        _check("valve.max_area", self.max_area, low=0.0, unit=" [m²]")
        _check("valve.area", self.area, low=0.0, low_open=False, high=self.max_area, unit=" [m²]")
        _check("valve.discharge_coefficient", self.discharge_coefficient, low=0.0, high=1.0)
        if self.law not in VALVE_LAW_PARAMETERS:
            raise ParameterError(f"valve.law must be one of {sorted(VALVE_LAW_PARAMETERS)}, got {self.law!r}")
        if self.law == "orifice":
            for name in ("sonic_conductance", "critical_ratio"):
                if getattr(self, name) is not None:
                    raise ParameterError(f"valve.{name} is a parameter of the iso6358 law, not of the orifice law; "
                                         f"got {getattr(self, name)!r} (set valve.law = 'iso6358' or leave it out)")
            return
        for name in ("sonic_conductance", "critical_ratio"):
            if getattr(self, name) is None:
                raise ParameterError(f"valve.{name} is required by the iso6358 law, got None")
        _check("valve.sonic_conductance", self.sonic_conductance, low=0.0, unit=" [m³/(s·Pa)]")
        _check("valve.critical_ratio", self.critical_ratio, low=0.0, high=1.0, unit=" (expected within (0, 1))")
        if self.critical_ratio >= 1.0:  # type: ignore[operator]  # set for this law
            raise ParameterError(f"valve.critical_ratio must be within (0, 1), got {self.critical_ratio!r}")


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
        _check("rig.gravity", self.gravity, low=0.0, low_open=False)
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
    unknown = sorted(set(data) - known_top)
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
    path = Path(path)
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


def save_toml(rig: Rig, path: str | Path, *, overwrite: bool = False) -> Path:
    """Write ``rig`` to ``path`` as TOML."""
    import tomli_w

    from .outputs import check_file, write_failed

    path = check_file(path, "rig file", overwrite=overwrite, flag="overwrite=True")
    try:
        path.write_text(tomli_w.dumps(to_dict(rig)), encoding="utf-8")
    except OSError as exc:
        raise write_failed(path, exc) from None
    return path


#: the stand with a nearly elastic Kelvin-Voigt contact: the rod bounces on the mass for the whole stroke
STIFF_STAND = Rig(name="drop-stand-stiff")
#: the stand with a hysteretic elastomer pad: a rebound or two (stage A), then sustained contact (stage B)
PAD_STAND = Rig(name="drop-stand-pad", contact=Contact(law="hysteretic"), friction=Friction(force=100.0),
                cylinder=Cylinder(dead_volume_lower=2e-5, dead_volume_upper=1e-5),
                valve=Valve(law="iso6358", sonic_conductance=2e-7, critical_ratio=0.3, max_area=2e-4))
#: named stands; ``drop-stand`` is the default (today the stiff stand: the robust identification does not yet
#: use stage B, which the pad stand reaches after one or two rebounds)
PRESETS: dict[str, Rig] = {
    "drop-stand": dataclasses.replace(STIFF_STAND, name="drop-stand"),
    "drop-stand-stiff": STIFF_STAND,
    "drop-stand-pad": PAD_STAND,
}


#: the stand of the absorber's commands and studies (``absorb``, ``study absorption``, ``study valve-design``)
ABSORPTION_RIG = "drop-stand-pad"


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
        _check("mass", self.mass, low=MASS_RANGE[0], low_open=False, high=MASS_RANGE[1], unit=" [kg]")
        _check("velocity", self.velocity, low=0.0, high=VELOCITY_RANGE[1], unit=" [m/s]")
        _check("pressure_gauge", self.pressure_gauge, low=0.0, low_open=False, unit=" [Pa]")

    @classmethod
    def from_height(cls, *, mass: float, height: float, pressure_gauge: float = 200e3,
                    gravity: float = STANDARD_GRAVITY) -> Scenario:
        """Scenario of a free drop from ``height`` [m]: V0 = sqrt(2·g·h)."""
        _check("height", height, low=0.0, unit=" [m]")
        return cls(mass=mass, velocity=math.sqrt(2.0 * gravity * height), pressure_gauge=pressure_gauge)

    def check_against(self, rig: Rig) -> None:
        """Raise unless the charge pressure is within the rating of ``rig``."""
        if self.pressure_gauge > rig.cylinder.rated_pressure_gauge:
            raise ParameterError(f"pressure_gauge must be <= the rated {rig.cylinder.rated_pressure_gauge:g} Pa "
                                 f"of {rig.name!r}, got {self.pressure_gauge!r}")
