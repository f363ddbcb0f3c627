"""The whole drop stand, :class:`Rig`: its parts bundled, its dictionary form, its TOML file.

A stand is loaded from and saved to TOML (unknown keys are errors; a ``[provenance]`` table, which a calibrated
stand carries, is read past: it says where the numbers came from and changes no physics). The file format itself
(reading, writing, the provenance table) is :mod:`.toml`.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..constants import STANDARD_GRAVITY
from ..errors import ParameterError
from ..outputs import as_path
from ..validation import check_real
from .parts import VALVE_LAW_PARAMETERS, Contact, Cylinder, Friction, Gas, Stops, Valve, contact_law_name
from .toml import PROVENANCE_KEY, loading, read_table, table_text, write_table
from .uncertainty import UNCERTAINTY_KEY, StandUncertainty


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


_SECTIONS: dict[str, type] = {"cylinder": Cylinder, "gas": Gas, "friction": Friction, "contact": Contact,
                              "stops": Stops, "valve": Valve}


def check_stops(rig: Rig) -> None:
    """ParameterError for a stand whose top stop cannot hold the piston within its upper gas column.

    Charged to the rated pressure, the gas pushes the piston into the top stop with up to the rated pressure on the
    full piston area (plus its weight, ten times over for the blow of a bounce); a stop yielding more than the upper
    gas column under that load would compress the gas to a negative volume: a simulation would show a negative
    stroke and negative absolute pressures.
    """
    c = rig.cylinder
    load = c.rated_pressure_gauge * c.area + 10.0 * c.piston_mass * max(rig.gravity, 1.0)
    yielding = load / rig.stops.stiffness
    column = c.upper_length + c.dead_volume_upper / c.annulus_area
    if yielding >= column:
        raise ParameterError(f"stops.stiffness {rig.stops.stiffness:g} N/m lets the top stop yield {yielding:.3g} m "
                             f"under the rated {c.rated_pressure_gauge:g} Pa on the {c.bore:g} m bore, more than the "
                             f"upper gas column ({column:.3g} m); expected a stand whose stops hold the piston within "
                             "its gas columns (stiffer stops, a smaller bore or a lower rated pressure)")


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
    unknown = sorted(set(data) - known_top - {PROVENANCE_KEY, UNCERTAINTY_KEY})
    for key in (PROVENANCE_KEY, UNCERTAINTY_KEY):
        if not isinstance(data.get(key, {}), dict):
            raise ParameterError(f"{source}: [{key}] must be a table, got {data[key]!r}")
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
    table = read_table(path)
    try:
        return from_dict(table, source=str(path))
    except ParameterError as exc:
        raise loading(path, exc) from None


def load_uncertainty(path: str | Path) -> StandUncertainty | None:
    """The σ and correlation of the calibrated parameters of the stand file at ``path`` (its ``[uncertainty]``
    table), or None where it states none (a stand not calibrated)."""
    path = as_path(path, "rig file")
    table = read_table(path)
    if UNCERTAINTY_KEY not in table:
        return None
    return StandUncertainty.from_table(table[UNCERTAINTY_KEY], source=str(path))


def toml_text(rig: Rig) -> str:
    """``rig`` as the text of its TOML file (what :func:`save_toml` writes; :func:`load_toml` reads it back)."""
    if not isinstance(rig, Rig):
        raise ParameterError(f"rig must be a Rig, got {type(rig).__name__}")
    return table_text(to_dict(rig))


def save_toml(rig: Rig, path: str | Path, *, overwrite: bool = False,
              provenance: dict[str, Any] | None = None, uncertainty: StandUncertainty | None = None) -> Path:
    """Write ``rig`` to ``path`` as TOML, with a ``[provenance]`` table when ``provenance`` is given (plain numbers,
    strings, lists and tables; None values are left out) and an ``[uncertainty]`` table when ``uncertainty`` is
    (:func:`load_uncertainty` reads it back)."""
    if not isinstance(rig, Rig):
        raise ParameterError(f"rig must be a Rig, got {type(rig).__name__}")
    if uncertainty is not None and not isinstance(uncertainty, StandUncertainty):
        raise ParameterError(f"uncertainty must be a StandUncertainty or None, got {type(uncertainty).__name__}")
    return write_table(to_dict(rig), path, overwrite=overwrite, provenance=provenance,
                       uncertainty=None if uncertainty is None else uncertainty.to_table())
