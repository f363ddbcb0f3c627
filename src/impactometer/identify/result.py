"""The result of an identification, whatever the method: mass, velocity, energy, their standard errors, when the
answer was known, the early answer, warnings and the method's own details.

Every method returns an :class:`Identification`: the peak-to-peak method (``peak-to-peak/robust``,
``peak-to-peak/paper``, batch or streaming), the response map (``response-map/fast``, ``response-map/brute``), the
model-based fit of the whole record (``model/ml``, or ``model/fallback`` when it gives the robust answer), and the
closed loop's oracle (``oracle``), which knows the true impact.

Unknown numbers are NaN (a standard error the method does not give, a time never reached); :meth:`to_dict` gives
them as None, ready for JSON.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from ..jsonable import plain
from ..validation import finite_or_none

#: names of the peak-to-peak variants
VARIANTS = ("robust", "paper")
#: method-specific details reported by :meth:`Identification.to_dict`: detail name -> JSON key, in order
REPORTED_DETAILS = {"t00": "t00_s", "t01": "t01_s", "t11": "t11_s", "onsets": "onsets_s", "stage": "stage",
                    "equations": "equations", "caution": "caution", "residual": "residual", "features": "features",
                    "feature_set": "feature_set", "pressure_gauge": "pressure_gauge_Pa",
                    "extrapolated": "extrapolated", "path": "path", "reason": "reason", "contact_law": "contact_law",
                    "criterion": "criterion", "model_selection": "model_selection", "reduced_chi2": "reduced_chi2",
                    "parameters": "parameters", "crb": "crb", "robust": "robust", "start": "start",
                    "adequacy": "adequacy", "stands": "stands"}
#: JSON key of the part of the method's name after its family: the peak-to-peak variant, the map's search
VARIANT_KEYS = {"peak-to-peak": "variant", "response-map": "search", "model": "variant"}


@dataclass(frozen=True, kw_only=True)
class Identification:
    """An identified impact: mass M1 [kg] and velocity V0 [m/s] at first contact, with their standard errors.

    Attributes
    ----------
    mass : float
        Impacting mass M1 [kg] (NaN: no answer, see ``error``).
    velocity : float
        Impact velocity V0 at first contact [m/s] (NaN: no answer).
    available_at : float
        Time at which the data used had all arrived [s], same clock as the recording (``inf``: never).
    method : str
        ``family/variant``: ``peak-to-peak/robust``, ``peak-to-peak/paper``, ``response-map/fast``,
        ``response-map/brute``, ``model/ml``, ``model/fallback``; or ``oracle`` (the true impact, in the closed loop).
    mass_std, velocity_std : float
        Standard errors [kg], [m/s]; NaN when the method gives none (``peak-to-peak/paper``, the response map).
    early : Identification or None
        The early answer (peak-to-peak robust: from the data up to the second pulse), or None.
    early_reason : str or None
        Why there is no early answer (peak-to-peak: the refusal of the early fit, the data that never allowed one,
        or a variant that gives none); None where there is one, for the early answer itself, and for the methods
        that give none by design (response map, oracle).
    warnings : tuple of str
        Sentences on what makes the answer implausible (:mod:`.plausibility`); empty when nothing does.
    details : mapping
        The method's own diagnostics. Peak-to-peak: a :class:`.details.PeakToPeakDetails` -- ``t00``, ``t01``,
        ``t11`` (first contact and the force peaks of the first two pulses [s]), ``onsets`` (contact onsets [s],
        robust), ``stage`` (``early`` or ``final``), ``equations`` (what the answer used,
        :class:`.details.EquationsUsed`), ``chi2``, ``dof``, noise levels, ``caution``. Response map: a
        :class:`.details.ResponseMapDetails` -- ``residual`` (eq. (7) [-]), ``features``, ``feature_set``,
        ``pressure_gauge`` [Pa gauge], ``extrapolated``. The typed details are also read-only mappings by these
        names (:class:`.details.Details`). Model: a :class:`.details.ModelDetails` -- ``path`` (``ml`` or
        ``fallback``, which carries the robust answer's typed details as well) and ``reason``, ``contact_law``,
        ``criterion`` and ``model_selection`` (each law's fit), ``reduced_chi2``, ``parameters`` (the stand
        parameters fitted), ``crb`` (Cramér-Rao σ of M1 and V0), ``robust`` (its answer or why it failed),
        ``start`` (where the fit started: the robust answer or a grid).
    error : str or None
        Why there is no answer (or why it never became available), where a caller keeps a failed identification
        (the closed loop); None for an answer.
    """

    mass: float
    velocity: float
    available_at: float
    method: str
    mass_std: float = math.nan
    velocity_std: float = math.nan
    early: Identification | None = None
    early_reason: str | None = None
    warnings: tuple[str, ...] = ()
    details: Mapping[str, Any] = field(default_factory=dict)
    error: str | None = None

    @property
    def family(self) -> str:
        """The method's family: ``peak-to-peak``, ``response-map`` or ``oracle``."""
        return self.method.partition("/")[0]

    @property
    def variant(self) -> str:
        """The method's name after its family: the peak-to-peak variant (``robust``, ``paper``) or the map's
        search (``fast``, ``brute``); empty for the oracle."""
        return self.method.partition("/")[2]

    @property
    def energy(self) -> float:
        """Impact energy M1·V0²/2 [J]."""
        return 0.5 * self.mass * self.velocity ** 2

    @property
    def energy_std(self) -> float:
        """Standard error of the energy [J], first order, mass and velocity errors taken as independent (NaN
        when a standard error is unknown)."""
        return math.hypot(0.5 * self.velocity ** 2 * self.mass_std, self.mass * self.velocity * self.velocity_std)

    @property
    def t00(self) -> float:
        """First contact [s] (peak-to-peak; NaN for other methods)."""
        return self.details.get("t00", math.nan)

    @property
    def t01(self) -> float:
        """Force peak of the first pulse [s] (peak-to-peak; NaN for other methods)."""
        return self.details.get("t01", math.nan)

    @property
    def t11(self) -> float:
        """Force peak of the second pulse [s] (peak-to-peak; NaN for other methods)."""
        return self.details.get("t11", math.nan)

    @property
    def onsets(self) -> tuple[float, ...]:
        """Contact onsets found [s]: t00 and the onset of every later pulse (peak-to-peak robust; else empty)."""
        return tuple(self.details.get("onsets", ()))

    @property
    def residual(self) -> float:
        """Eq. (7) at the answer [-] (response map; NaN for other methods)."""
        return self.details.get("residual", math.nan)

    @property
    def extrapolated(self) -> bool:
        """Whether the answer lies outside the response map (False for other methods)."""
        return bool(self.details.get("extrapolated", False))

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready mapping: ``mass_kg``, ``velocity_m_s``, ``energy_J``, their standard errors, ``available_at_s``,
        ``method`` (the family), ``variant`` (peak-to-peak) or ``search`` (response map), ``early``,
        ``early_reason``, ``warnings``,
        ``error``, and the reported details (:data:`REPORTED_DETAILS`); unknown numbers as None."""
        out: dict[str, Any] = {
            "mass_kg": finite_or_none(self.mass), "velocity_m_s": finite_or_none(self.velocity),
            "energy_J": finite_or_none(self.energy), "mass_std_kg": finite_or_none(self.mass_std),
            "velocity_std_m_s": finite_or_none(self.velocity_std), "energy_std_J": finite_or_none(self.energy_std),
            "available_at_s": finite_or_none(self.available_at), "method": self.family}
        if self.family in VARIANT_KEYS:
            out[VARIANT_KEYS[self.family]] = self.variant
        out["early"] = None if self.early is None else self.early.to_dict()
        out["early_reason"] = self.early_reason
        out["warnings"] = list(self.warnings)
        out["error"] = self.error
        for name, key in REPORTED_DETAILS.items():
            value = self.details.get(name)
            if value is not None and not (isinstance(value, (str, Mapping)) and not value):
                out[key] = plain(value)
        return out

    def plot(self, recording=None, ax=None, *, used=None):
        """Figure of the answer (:func:`impactometer.plotting.identification.plot_identification`; matplotlib
        imported lazily): with a recording, its force and acceleration with the instants used marked, and with
        ``used`` (:func:`impactometer.identify.peak_to_peak.used_samples`) the samples a robust answer's equations
        read; without a recording, mass and velocity (early and final answer) against the time they were known."""
        from ..plotting.identification import plot_identification

        return plot_identification(self, recording, ax=ax, used=used)
