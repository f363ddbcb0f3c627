"""The result of a peak-to-peak identification: mass, velocity, energy, standard errors and when they were known."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

#: names of the identification variants
VARIANTS = ("robust", "paper")


@dataclass(frozen=True, kw_only=True)
class Identification:
    """Identified impact: mass M1 [kg], velocity V0 [m/s] at first contact, and their standard errors.

    Attributes
    ----------
    mass : Impacting mass M1 [kg].
    velocity : Impact velocity V0 at first contact [m/s].
    mass_std, velocity_std : Standard errors [kg], [m/s] (NaN when the variant gives none, e.g. ``paper``).
    available_at : Time at which the data used had all arrived [s] (same clock as the recording).
    t00, t01, t11 : First contact and the force peaks of the first two pulses [s] (the paper's instants).
    method : ``"peak-to-peak"``.
    variant : ``"robust"`` or ``"paper"``.
    early : The early answer (from the data up to the second pulse), or None.
    onsets : Contact onsets found [s] (robust variant): t00 and the onset of every later pulse.
    details : Diagnostics: ``stage`` (``early`` or ``final``), ``equations`` (what the answer used: counts of
        onsets, force extrema, of them in stage B, separations and the stage-B samples, the contact-phase fit's
        samples where one was used, and the fitted nuisances), chi-square and degrees of freedom, noise levels.
    warnings : Sentences on what makes the answer implausible (see :mod:`.plausibility`); empty when nothing does.
    """

    mass: float
    velocity: float
    mass_std: float = math.nan
    velocity_std: float = math.nan
    available_at: float
    t00: float
    t01: float
    t11: float
    method: str = "peak-to-peak"
    variant: str = "robust"
    early: Identification | None = None
    onsets: tuple[float, ...] = ()
    details: dict[str, Any] = field(default_factory=dict)
    warnings: tuple[str, ...] = ()

    @property
    def energy(self) -> float:
        """Impact energy M1·V0²/2 [J]."""
        return 0.5 * self.mass * self.velocity ** 2

    @property
    def energy_std(self) -> float:
        """Standard error of the energy [J], first order, mass and velocity errors taken as independent."""
        return math.hypot(0.5 * self.velocity ** 2 * self.mass_std, self.mass * self.velocity * self.velocity_std)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready mapping with the CLI keys (``mass_kg``, ``velocity_m_s``, ... , ``early``); NaN -> None."""
        def num(x: float) -> float | None:
            return None if x is None or not math.isfinite(x) else float(x)

        return {"mass_kg": num(self.mass), "velocity_m_s": num(self.velocity), "energy_J": num(self.energy),
                "mass_std_kg": num(self.mass_std), "velocity_std_m_s": num(self.velocity_std),
                "energy_std_J": num(self.energy_std), "available_at_s": num(self.available_at),
                "t00_s": num(self.t00), "t01_s": num(self.t01), "t11_s": num(self.t11),
                "method": self.method, "variant": self.variant,
                "early": None if self.early is None else self.early.to_dict(),
                "onsets_s": [float(t) for t in self.onsets], "warnings": list(self.warnings),
                **({"stage": self.details["stage"]} if self.details.get("stage") else {}),
                **({"equations": _plain(self.details["equations"])} if self.details.get("equations") else {}),
                **({"caution": self.details["caution"]} if self.details.get("caution") else {})}

    def plot(self, recording, ax=None):
        """Force and acceleration with the instants used marked (matplotlib imported lazily)."""
        from ..plotting.identification import plot_identification
        return plot_identification(recording, self, ax=ax)


def _plain(value: Any) -> Any:
    """JSON-ready copy of nested details: numpy numbers as Python numbers, non-finite numbers as None."""
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, (bool, str)) or value is None:
        return value
    try:
        number = float(value)
    except (TypeError, ValueError):
        return str(value)
    if not math.isfinite(number):
        return None
    return int(number) if isinstance(value, int) or (hasattr(value, "dtype") and value.dtype.kind in "iu") \
        else number
