"""How each drop of a calibration set agrees with the fit and with the other drops, each figure in σ.

- **light-gate pull**: (ln V0 fitted − ln V0 of the light gate) / ``velocity_sigma``. M1 and p0 are known and the
  stand is shared, so a drop's record fixes its V0; a drop whose stated values or stand differ from the others'
  (a wrong mass, another stand) moves its V0 away from its gate to make up for it.
- **misfit**: (χ²/dof of the drop's samples − 1) over its scatter under a right model, sqrt(2/dof + 1/(n − 1)):
  the χ² of ``dof`` residuals, and each channel's σ measured on n pre-trigger samples (its relative variance
  2/(n − 1), the two channels averaged). What noise explains stays within a few σ.
- **influence**: a linearised leave-one-out. Deleting drop i's rows moves the fit to the other drops' own optimum;
  to first order its stand parameters move by Δ = [(F − Fᵢ)⁻¹ g]ₛ, where F is the Fisher information of the fit,
  Fᵢ drop i's share and g = Jᵢᵀ rᵢ drop i's gradient (the other drops' nuisances profiled). Under a right model Δ
  is Gaussian with covariance V = Cₒ − C, the stand's covariance from the others alone less that from every drop
  (the two estimates are nested), so T = Δᵀ V⁺ Δ follows χ² with rank(V) degrees of freedom (a Hausman test of
  the drop against the others); it is given as the Gaussian σ of the same upper tail (Wilson-Hilferty). It costs
  one Jacobian per drop where a refit per drop costs a calibration per drop, and measures what a leave-one-out
  measures: how far the others alone would take the stand, in its own σ.

A drop is named **inconsistent with the others** when the largest of its three figures (the influence divided by
:data:`INFLUENCE_MARGIN`) exceeds :func:`_limit` (a Gaussian false alarm of 1 % over the set) and :data:`STANDOUT`
times the set's median: a misfit every drop shares
(a pad outside every family) is the model's, not one drop's, and is reported as such. Each figure sees another
fault: a drop of another stand moves its V0 off its gate; a drop stated 10 % too heavy kept its V0 at the gate
(pull −0.6 σ) but could not be fitted (misfit 1600 σ against the others' 13-50 σ, influence 150 σ against 50 σ).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from scipy.stats import norm

from ..identify.model_fit.engine import Residuals, window
from .drops import _ObservedDrop
from .joint import NUISANCES, _Family

#: false-alarm probability of naming a drop of a set that a right model fits [-]
FALSE_ALARM = 0.01
#: a drop is named only when its figure is at least this many times the set's median [-]
STANDOUT = 3.0
#: the influence names a drop only beyond this times the limit: it is linearised, and late in a record the
#: likelihood is not smooth (grazing contacts as the piston returns to its top stop). On the README's six clean
#: drops of the pad stand it gave one drop (15 kg, 2.2 m/s, 350 kPa: the one whose σ(V0) the non-smooth likelihood
#: makes ten times too small) 4.9 σ, pull 0.0 σ, misfit 0.1 σ
INFLUENCE_MARGIN = 2.0
#: misfit of the whole set [σ] beyond which the calibrated stand is said not to fit its drops: a right model
#: exceeds it with a Gaussian probability of 3e-5, a model error of a few % of χ²/dof on six drops far exceeds it
MISFIT_LIMIT = 4.0


def _limit(drops: int) -> float:
    """|σ| beyond which a drop's pull or influence names it: the two-sided Gaussian quantile of a false alarm
    :data:`FALSE_ALARM` over ``drops`` drops (Bonferroni) [σ]."""
    return float(norm.isf(FALSE_ALARM / (2 * max(drops, 1))))


def _chi2_sigma(value: float, dof: int) -> float:
    """A χ² of ``dof`` degrees of freedom as the Gaussian σ of the same upper tail (Wilson-Hilferty) [σ]."""
    if dof <= 0 or not math.isfinite(value):
        return math.inf if value > 0 else 0.0
    c = 2.0 / (9.0 * dof)
    return float(((max(value, 0.0) / dof) ** (1.0 / 3.0) - (1.0 - c)) / math.sqrt(c))


def _misfit_sigma(chi2: float, dof: int, pre_samples: float) -> float:
    """χ² of ``dof`` residuals weighted by σ measured on ``pre_samples`` samples, as σ of its scatter under a
    right model (see the module notes) [σ]."""
    spread = math.sqrt(2.0 / max(dof, 1) + 1.0 / max(pre_samples - 1.0, 1.0))
    return (chi2 / max(dof, 1) - 1.0) / spread


def _set_misfit_sigma(family: _Family, drops: Sequence[_ObservedDrop]) -> float:
    """The misfit of every drop's samples together [σ]: their χ² over its scatter under a right model, each drop's
    noise estimate weighted by its share of the degrees of freedom (see the module notes)."""
    dofs = np.array([n - len(NUISANCES) for n in family.drop_residuals], dtype=float)
    dof = max(float(dofs.sum()) - len(family.free), 1.0)
    pre = np.array([_pre_samples(drop) for drop in drops])
    spread = math.sqrt(2.0 / dof + float(np.sum((dofs / dofs.sum()) ** 2 / np.maximum(pre - 1.0, 1.0))))
    return (float(sum(family.drop_chi2)) / dof - 1.0) / spread


def _pre_samples(drop: _ObservedDrop) -> float:
    """Number of samples before the drop's first contact (where each channel's σ was measured) [-]."""
    return max((drop.contact_time - drop.data.grid.start_time) * drop.data.grid.sample_rate, 2.0)


def _drop_figures(family: _Family, drops: Sequence[_ObservedDrop], *, velocity_sigma: float,
                  duration: float | None) -> list[dict[str, float]]:
    """Each drop's light-gate pull, misfit and influence [σ] (see the module notes) at the fit ``family``."""
    s, k = len(family.free), family.unknowns
    information = family.root.T @ family.root
    everything = np.linalg.pinv(information)
    out = []
    for i, drop in enumerate(drops):
        data = drop.data if duration is None else window(drop.data, drop.contact_time + duration)
        model = Residuals(data, family.layouts[i])
        x = family.local(i)
        own = np.arange(s + len(NUISANCES) * i, s + len(NUISANCES) * (i + 1))
        columns = np.r_[own[:2], np.arange(s), own[2:]]
        jac = model.jacobian(x)  # the light gate's prior row included
        gradient = np.zeros(k)
        gradient[columns] = jac.T @ model.residuals(x)
        share = np.zeros((k, k))
        share[np.ix_(columns, columns)] = jac.T @ jac
        rest = np.setdiff1d(np.arange(k), own)
        others = np.linalg.pinv((information - share)[np.ix_(rest, rest)])
        shift = (others @ gradient[rest])[:s]
        statistic, dof = _quadratic(shift, others[:s, :s] - everything[:s, :s])
        pull = float((family.x[own[0]] - math.log(drop.velocity)) / velocity_sigma)
        out.append({"velocity_pull": pull,
                    "misfit_sigma": _misfit_sigma(family.drop_chi2[i], family.drop_residuals[i] - len(NUISANCES),
                                                  _pre_samples(drop)),
                    "influence_sigma": _chi2_sigma(statistic, dof)})
    return out


def _quadratic(shift: np.ndarray, cov: np.ndarray) -> tuple[float, int]:
    """shiftᵀ cov⁺ shift and the rank of ``cov`` (its eigenvalues above 1e-9 of the largest)."""
    values, vectors = np.linalg.eigh((cov + cov.T) / 2.0)
    keep = values > 1e-9 * max(float(values.max()), 0.0) if values.size and values.max() > 0 else values > np.inf
    projected = vectors[:, keep].T @ shift
    return float(np.sum(projected ** 2 / values[keep])), int(np.count_nonzero(keep))


def _inconsistent(figures: Sequence[dict[str, float]]) -> list[int]:
    """Indices of the drops inconsistent with the others (see the module notes)."""
    scores = np.array([max(abs(f["velocity_pull"]), f["influence_sigma"] / INFLUENCE_MARGIN, f["misfit_sigma"])
                       for f in figures])
    if scores.size < 2:
        return []
    bar = max(_limit(scores.size), STANDOUT * float(np.median(scores)))
    return [int(i) for i in np.flatnonzero(scores > bar)]
