"""The result of a calibration: the calibrated stand, each parameter with its standard error and correlations, how
well each contact-law family fits, each drop's fit, and the stand file with its provenance."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..rig import Rig, StandUncertainty, save_toml
from ..validation import finite_or_none


@dataclass(frozen=True, kw_only=True)
class Drop:
    """A drop as a stand reproduces it: ``source`` (the file), M1 [kg], V0 [m/s], p0 [Pa gauge], the χ²/dof of the
    fit [-]; ``time`` [s] on the recording's clock and ``measured`` and ``simulated`` contact force [N] and piston
    acceleration [m/s²] (2, n), the simulated ones with the fitted offsets."""

    source: str
    mass: float
    velocity: float
    pressure_gauge: float
    reduced_chi2: float
    time: np.ndarray
    measured: np.ndarray
    simulated: np.ndarray

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready mapping (without the arrays)."""
        return {"file": self.source, "mass_kg": self.mass, "velocity_m_s": self.velocity,
                "pressure_gauge_Pa": self.pressure_gauge, "reduced_chi2": self.reduced_chi2}


@dataclass(frozen=True, kw_only=True)
class DropFit(Drop):
    """One drop of the calibration set fitted: V0 is the fitted one (``velocity_std`` [m/s] its standard error,
    ``velocity_gate`` the light gate's), the contact instant [s] and the offsets [N], [m/s²] are fitted too."""

    velocity_gate: float
    velocity_std: float
    contact_time: float
    offsets: tuple[float, float]
    #: RMS(measured − simulated force) / (max − min of the measured) over the length fitted [-]
    force_nrmse: float
    #: (ln V0 fitted − ln V0 of the light gate) / the gate's relative σ [σ]
    velocity_pull: float
    #: the drop's χ²/dof beyond what the noise explains [σ]
    misfit_sigma: float
    #: linearised leave-one-out: how far the drop pulls the stand from what the other drops say [σ]
    influence_sigma: float
    #: whether the drop is named inconsistent with the others, and the limit in σ that names one
    inconsistent: bool
    limit: float

    def verdict(self) -> str:
        """The drop's figures in words (light-gate pull, influence and misfit in σ)."""
        text = (f"light gate {self.velocity_pull:+.1f} sigma (V0 {self.velocity:.4g} m/s against the gate's "
                f"{self.velocity_gate:.4g}), influence on the stand {self.influence_sigma:.1f} sigma, misfit "
                f"{self.misfit_sigma:.1f} sigma")
        return text + (f" (limit {self.limit:.2f} sigma)" if self.inconsistent else "")

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready mapping (without the arrays)."""
        return {**super().to_dict(), "velocity_gate_m_s": self.velocity_gate,
                "velocity_std_m_s": finite_or_none(self.velocity_std), "contact_time_s": self.contact_time,
                "offset_contact_force_N": self.offsets[0], "offset_piston_acceleration_m_s2": self.offsets[1],
                "force_nrmse": self.force_nrmse, "velocity_pull_sigma": finite_or_none(self.velocity_pull),
                "misfit_sigma": finite_or_none(self.misfit_sigma),
                "influence_sigma": finite_or_none(self.influence_sigma),
                "inconsistent": self.inconsistent, "limit_sigma": self.limit}


@dataclass(frozen=True, kw_only=True)
class Calibration:
    """A stand calibrated from drops of known mass, velocity and pressure.

    Attributes
    ----------
    rig : Rig
        The calibrated stand (the base stand with the chosen contact law and the fitted values).
    base : str
        Name of the stand the calibration started from.
    law : str
        The contact-law family chosen (smallest BIC).
    parameters, std : dict
        Fitted value and standard error of each stand parameter [SI]; the standard errors come from the Fisher
        information, inflated by ``inflation``.
    correlation : ndarray
        Correlation matrix of the fitted parameters, in the order of ``parameters``.
    reduced_chi2, chi2, dof, bic : float
        Fit quality of the chosen family over every drop [-].
    inflation : float
        sqrt(max(1, χ²/dof)) [-].
    families : dict
        Law -> its fit figures (χ², dof, BIC, each drop's χ²/dof), or why it was dropped or failed.
    criterion : str
        How the family was chosen.
    drops : tuple of DropFit
    indistinct : tuple of dict
        Pairs of parameters the drops do not tell apart (|correlation| above the limit), undetermined ones, and the
        extra drop suggested to separate them.
    warnings : tuple of str
    velocity_sigma : float
        Relative σ of the light-gate velocities assumed [-].
    duration : float or None
        Length of each record fitted after its contact [s] (None: the whole record).
    created : str
        When the calibration was made (ISO 8601, UTC).
    max_reduced_chi2 : float
        χ²/dof above which the stand is said not to describe the drops [-].
    misfit_sigma, misfit_limit : float
        The χ² of every drop's samples beyond what the noise explains, and the limit above which the stand is said
        not to describe the drops [σ] (:func:`impactometer.calibrate.influence.set_misfit_sigma`).
    excluded : tuple of dict
        Drops left out by ``drop_outliers`` (file and why).
    """

    rig: Rig
    base: str
    law: str
    parameters: dict[str, float]
    std: dict[str, float]
    correlation: np.ndarray
    reduced_chi2: float
    chi2: float
    dof: int
    bic: float
    inflation: float
    families: dict[str, dict]
    criterion: str
    drops: tuple[DropFit, ...]
    indistinct: tuple[dict, ...]
    warnings: tuple[str, ...]
    velocity_sigma: float
    duration: float | None
    created: str
    max_reduced_chi2: float
    misfit_sigma: float
    misfit_limit: float
    excluded: tuple[dict, ...] = ()

    @property
    def fits(self) -> bool:
        """Whether the chosen family describes the drops: χ²/dof within ``max_reduced_chi2`` and no more than
        ``misfit_limit`` σ beyond what the noise explains."""
        return self.reduced_chi2 <= self.max_reduced_chi2 and self.misfit_sigma <= self.misfit_limit

    @property
    def inconsistent(self) -> tuple[str, ...]:
        """The drops named inconsistent with the others (their files)."""
        return tuple(d.source for d in self.drops if d.inconsistent)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready mapping of everything but the arrays of the drops."""
        names = list(self.parameters)
        return {"stand": self.rig.name, "base": self.base, "contact_law": self.law, "criterion": self.criterion,
                "fits": self.fits, "misfit_sigma": self.misfit_sigma, "misfit_limit_sigma": self.misfit_limit,
                "inconsistent": list(self.inconsistent), "excluded": list(self.excluded),
                "reduced_chi2": self.reduced_chi2, "chi2": self.chi2, "dof": self.dof,
                "bic": self.bic, "inflation": self.inflation,
                "parameters": {name: {"value": self.parameters[name], "std": finite_or_none(self.std[name])}
                               for name in names},
                "correlation": {"names": names,
                                "matrix": [[finite_or_none(c) for c in row] for row in self.correlation.tolist()]},
                "families": self.families, "indistinct": list(self.indistinct),
                "drops": [drop.to_dict() for drop in self.drops], "warnings": list(self.warnings),
                "velocity_sigma": self.velocity_sigma, "duration_s": self.duration, "created": self.created}

    def provenance(self) -> dict[str, Any]:
        """The ``[provenance]`` table of the stand file: files, fit quality, law chosen, date."""
        from .. import __version__

        return {"created": self.created, "tool": f"impactometer {__version__}", "method": "calibrate",
                "base": self.base, "contact_law": self.law, "criterion": self.criterion,
                "reduced_chi2": self.reduced_chi2, "fits": self.fits, "misfit_sigma": self.misfit_sigma,
                "misfit_limit_sigma": self.misfit_limit, "inconsistent": list(self.inconsistent),
                "excluded": list(self.excluded), "velocity_sigma": self.velocity_sigma,
                "duration_s": self.duration,
                "families": {law: {k: v for k, v in fam.items() if k in ("reduced_chi2", "bic", "dropped", "error")}
                             for law, fam in self.families.items()},
                "parameters": {name: {"value": self.parameters[name], "std": finite_or_none(self.std[name])}
                               for name in self.parameters},
                "drops": [{"file": d.source, "mass_kg": d.mass, "velocity_gate_m_s": d.velocity_gate,
                           "pressure_gauge_Pa": d.pressure_gauge, "velocity_m_s": d.velocity,
                           "reduced_chi2": d.reduced_chi2, "force_nrmse": d.force_nrmse,
                           "velocity_pull_sigma": d.velocity_pull, "influence_sigma": d.influence_sigma,
                           "misfit_sigma": d.misfit_sigma, "inconsistent": d.inconsistent} for d in self.drops],
                "warnings": list(self.warnings)}

    def uncertainty(self) -> StandUncertainty:
        """The σ [SI] and correlation of the fitted parameters whose σ is finite (the ``[uncertainty]`` table of the
        stand file; :func:`~impactometer.identify.model_fit.identify` carries it into σ(M1), σ(V0))."""
        kept = [i for i, name in enumerate(self.parameters) if math.isfinite(self.std[name])]
        names = [list(self.parameters)[i] for i in kept]
        correlation = np.nan_to_num(np.asarray(self.correlation, dtype=float)[np.ix_(kept, kept)])
        np.fill_diagonal(correlation, 1.0)
        return StandUncertainty(names=tuple(names), std=tuple(self.std[name] for name in names),
                                correlation=np.clip(correlation, -1.0, 1.0))

    def to_toml(self, path: str | Path, *, overwrite: bool = False) -> Path:
        """Write the calibrated stand with its provenance and the uncertainty of its fitted parameters (loadable by
        :func:`~impactometer.rig.get_rig` and :func:`~impactometer.rig.load_uncertainty`), under a temporary name
        moved into place: a failed or interrupted write leaves any previous file as it was."""
        return save_toml(self.rig, path, overwrite=overwrite, provenance=self.provenance(),
                         uncertainty=self.uncertainty())

    def plot(self, folder: str | Path) -> list[Path]:
        """One figure per drop (measured and simulated channels with residuals) and a parameter summary, written
        to ``folder``; returns their paths (see :func:`impactometer.plotting.calibration.plot_calibration`)."""
        from ..plotting.calibration import plot_calibration

        return plot_calibration(self, folder)
