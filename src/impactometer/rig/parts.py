"""The parts of the drop stand: cylinder, gas, seal friction, contact element, stops and valve.

Each part is a frozen keyword-only dataclass validated when it is created; :class:`~impactometer.rig.Rig` bundles
them. The defaults are the parts of the built-in stand (``drop-stand``): a TOML file or a :meth:`Rig.replace` that
leaves a parameter out keeps the built-in stand's value.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

from ..constants import ATMOSPHERIC_PRESSURE
from ..errors import ParameterError
from ..validation import check_real
from .limits import CYLINDER_LIMITS

#: a part's parameter check: a finite number, the lower bound excluded unless ``low_open=False``
_check = functools.partial(check_real, low_open=True)


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
    dead_volume_lower: float = 2e-5
    dead_volume_upper: float = 1e-5
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
    force : Coulomb friction force [N]. The built-in stand's 200 N is 20 % of the gas force on the 80 mm piston at
        200 kPa: published thrust losses of pneumatic cylinders are 10-25 % (about 50-250 N at this bore).
    velocity_scale : Smoothing velocity [m/s]: the friction reaches 76 % of its Coulomb level at this speed.
    """

    force: float = 200.0
    velocity_scale: float = 0.01

    def __post_init__(self) -> None:
        _check("friction.force", self.force, low=0.0, low_open=False)
        _check("friction.velocity_scale", self.velocity_scale, low=0.0)


#: contact law name -> its parameters and their defaults on the built-in stand
CONTACT_LAWS: dict[str, dict[str, float]] = {
    "hysteretic": {"stiffness": 7e5, "restitution": 0.4},
    "kelvin-voigt": {"stiffness": 2e6, "damping": 150.0},
    "hunt-crossley": {"stiffness": 4e8, "damping": 0.2},
    "power": {"stiffness": 8e5, "exponent": 1.5, "unloading_exponent": 3.5, "set_fraction": 0.4},
}
CONTACT_ALIASES = {"kv": "kelvin-voigt", "kelvin": "kelvin-voigt", "hunt": "hunt-crossley", "hc": "hunt-crossley",
                   "hys": "hysteretic", "walton-braun": "hysteretic", "masing": "power", "power-set": "power"}
#: the parameters of the contact laws, in the order of :class:`Contact`'s fields
_CONTACT_PARAMETERS = ("stiffness", "damping", "restitution", "exponent", "unloading_exponent", "set_fraction")


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
    exactly at maximum compression and a collision keeps e² of its relative kinetic energy (the default);
    ``kelvin-voigt``: F = k·δ + c·δ' [stiffness N/m, damping N·s/m];
    ``hunt-crossley``: F = k·δ^1.5·(1 + 1.5·α·δ') [stiffness N/m^1.5, damping = α s/m];
    ``power`` (Masing-type with a plastic set; aliases ``masing``, ``power-set``): loading F = k·δr·(δ/δr)^n
    [stiffness = k N/m, the secant stiffness at δr = 1 cm; exponent = n, 0.5-5]; from the turning point (δmax,
    F_max) the pad unloads, and reloads back to it, along F = F_max·((δ − s)/(δmax − s))^m [unloading_exponent = m,
    0.5-20] with the plastic set s = φ·δmax [set_fraction = φ, within [0, 1)], which stays for the rest of the
    record; loaded beyond δmax it follows the loading curve again. A load cycle to δmax returns e² = (n + 1)·(1 −
    φ)/(m + 1) of the work done on the pad (:attr:`restitution_squared`; at most 1: a pad gives back no more than it
    took). The defaults, n = 1.5, m = 3.5, φ = 0.4 (e = 0.58) and k = 8e5 N/m (about the built-in pad's 13 mm and 9
    kN under 60 J), describe an elastomer pad that stiffens as it is compressed and unloads along a steeper curve.
    The force is zero while δ <= 0 and never pulls. Parameters left out take the law's defaults
    (``CONTACT_LAWS``); a parameter of another law is an error.
    """

    law: str = "hysteretic"
    # None here means "the law's default"; every law has a stiffness, so it is a float once created
    stiffness: float = None  # type: ignore[assignment]
    damping: float | None = None
    restitution: float | None = None
    exponent: float | None = None
    unloading_exponent: float | None = None
    set_fraction: float | None = None

    def __post_init__(self) -> None:
        law = contact_law_name(self.law)
        object.__setattr__(self, "law", law)
        defaults = CONTACT_LAWS[law]
        for name in _CONTACT_PARAMETERS:
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
        if law == "power":
            _check("contact.exponent", self.exponent, low=0.5, high=5.0, low_open=False, state_range=True)
            _check("contact.unloading_exponent", self.unloading_exponent, low=0.5, high=20.0, low_open=False,
                   state_range=True)
            _check("contact.set_fraction", self.set_fraction, low=0.0, high=1.0, low_open=False, high_open=True,
                   state_range=True)
            if self.restitution_squared > 1.0 + 1e-12:
                raise ParameterError(
                    f"contact.unloading_exponent must be >= (exponent + 1)·(1 - set_fraction) - 1 = "
                    f"{(self.exponent + 1.0) * (1.0 - self.set_fraction) - 1.0:.6g} for a pad that gives back no "  # type: ignore[operator]
                    f"more energy than it takes, got {self.unloading_exponent!r}")

    @property
    def restitution_squared(self) -> float:
        """Share of the work done on a power-law pad up to its turning point that unloading gives back,
        e² = (n + 1)·(1 − φ)/(m + 1) [-]."""
        if self.law != "power":
            raise ParameterError(f"contact.restitution_squared exists for the power law only, not {self.law}")
        return ((self.exponent + 1.0) * (1.0 - self.set_fraction)  # type: ignore[operator]  # set for this law
                / (self.unloading_exponent + 1.0))  # type: ignore[operator]

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


#: ISO 6358 parameters of the built-in valve, taken where a valve of that law leaves them out
ISO6358_DEFAULTS = {"sonic_conductance": 2e-7, "critical_ratio": 0.3}
#: flow laws of valve Z and the parameters each one uses besides ``area`` and ``max_area``
VALVE_LAW_PARAMETERS: dict[str, tuple[str, ...]] = {"orifice": ("discharge_coefficient",),
                                                     "iso6358": ("sonic_conductance", "critical_ratio")}


@dataclass(frozen=True, kw_only=True)
class Valve:
    """Valve Z between the lower and the upper chamber (closed by default; ISO 6358, about 100 mm² effective).

    ``orifice``: compressible flow through an orifice of the opening area with discharge coefficient C_d.
    ``iso6358``: the flow law of pneumatic catalogues (ISO 6358-1), q = C·p_up·ρ0·sqrt(T0/T_up)·φ(p_down/p_up, b),
    for the fully open valve; a partly open valve has the conductance C·area/max_area.

    Attributes
    ----------
    area : Constant opening area [m²] (0 = closed cylinder).
    max_area : Fully open area A_max [m²].
    law : ``"orifice"`` or ``"iso6358"``.
    discharge_coefficient : C_d [-] (orifice law).
    sonic_conductance : C of the fully open valve [m³/(s·Pa)]; 1 dm³/(s·bar) = 1e-8 m³/(s·Pa) (ISO 6358 law;
        left out: 2e-7, a 20 dm³/(s·bar) valve).
    critical_ratio : Critical pressure ratio b [-], within (0, 1) (ISO 6358 law; left out: 0.3).
    """

    area: float = 0.0
    max_area: float = 2e-4
    discharge_coefficient: float = 0.7
    law: str = "iso6358"
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
        for name, default in ISO6358_DEFAULTS.items():
            if getattr(self, name) is None:
                object.__setattr__(self, name, default)
        _check("valve.sonic_conductance", self.sonic_conductance, low=0.0, unit=" [m³/(s·Pa)]")
        _check("valve.critical_ratio", self.critical_ratio, low=0.0, high=1.0, unit=" (expected within (0, 1))")
        if self.critical_ratio >= 1.0:  # type: ignore[operator]  # set for this law
            raise ParameterError(f"valve.critical_ratio must be within (0, 1), got {self.critical_ratio!r}")
