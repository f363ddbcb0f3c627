"""How a stand parameter is shown in tables and figures: its unit and the factor from SI."""

from __future__ import annotations

#: stand parameter -> (unit shown, factor from SI) in tables and figures; the contact law's where they differ
DISPLAY_UNITS: dict[str, tuple[str, float]] = {
    "contact.stiffness": ("N/m", 1.0), "contact.damping": ("N·s/m", 1.0), "contact.restitution": ("-", 1.0),
    "friction.force": ("N", 1.0), "friction.velocity_scale": ("m/s", 1.0), "cylinder.piston_mass": ("kg", 1.0),
    "cylinder.dead_volume_lower": ("cm³", 1e6), "cylinder.dead_volume_upper": ("cm³", 1e6),
    "stops.stiffness": ("N/m", 1.0), "contact.exponent": ("-", 1.0), "contact.unloading_exponent": ("-", 1.0),
    "contact.set_fraction": ("-", 1.0)}
#: contact law -> its parameters' units where they are not those of :data:`DISPLAY_UNITS`
LAW_UNITS: dict[str, dict[str, tuple[str, float]]] = {
    "hunt-crossley": {"contact.stiffness": ("N/m^1.5", 1.0), "contact.damping": ("s/m", 1.0)}}


def display_unit(name: str, law: str) -> tuple[str, float]:
    """(unit shown, factor from SI) of the stand parameter ``name`` of a stand with the contact ``law``."""
    return LAW_UNITS.get(law, {}).get(name) or DISPLAY_UNITS.get(name, ("SI", 1.0))
