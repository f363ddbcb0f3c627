"""Fisher information of a whole-record fit: the covariance of the fit's variables from its weighted Jacobian,
and the Cramér-Rao bound of M1 and V0 for a record."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

#: singular values of the column-scaled weighted Jacobian below this fraction of the largest are taken as zero:
#: the directions they span are not determined by the record (infinite variance)
RANK_TOLERANCE = 1e-10


def covariance(jacobian: np.ndarray) -> tuple[np.ndarray, int]:
    """Inverse Fisher information (JᵀJ)⁻¹ of a weighted Jacobian J (residuals/σ by variables) and its rank.

    Computed stably: the columns are scaled to unit norm, the scaled matrix is decomposed (QR, then the SVD of
    its triangle) and inverted
    through its singular values, and the scaling is undone, so that variables of very different sizes lose no
    digits. Variables in a direction the record does not determine (a singular value below ``RANK_TOLERANCE`` of
    the largest) get an infinite variance.
    """
    # each column's norm: einsum sums the squares in the order norm(axis=0) does (the same bits), in a quarter of
    # its time (norm squares the whole matrix into a temporary first)
    scale = np.sqrt(np.einsum("ij,ij->j", jacobian, jacobian))
    scale[scale == 0.0] = 1.0
    # the triangle of a Householder QR has the singular values and right singular vectors of the tall matrix, at a
    # fraction of the cost of its thin SVD (which builds the tall left factor)
    _, s, vt = np.linalg.svd(np.linalg.qr(jacobian / scale, mode="r"))
    kept = s > RANK_TOLERANCE * s[0]
    cov = (vt[kept].T / s[kept] ** 2) @ vt[kept] / (scale[:, None] * scale)  # np.outer's products, made directly
    if not kept.all():  # variables with a share in an undetermined direction are undetermined
        lost = np.any(np.abs(vt[~kept]) > 1e-6, axis=0)
        cov[lost, :] = np.inf
        cov[:, lost] = np.inf
    return cov, int(kept.sum())


@dataclass(frozen=True, kw_only=True)
class CramerRao:
    """Cramér-Rao bound of M1 and V0 for one record under one model.

    Attributes
    ----------
    mass_std : float
        Smallest standard error of an unbiased estimate of M1 [kg].
    velocity_std : float
        Smallest standard error of an unbiased estimate of V0 [m/s].
    mass, velocity : float
        The impact at which the bound is evaluated [kg], [m/s].
    contact_law : str
        The contact law of the model.
    at : str
        ``"truth"`` (values given, e.g. a simulated record's) or ``"estimate"`` (the fit's answer).
    unknowns : tuple of str
        Everything estimated alongside M1 and V0 (the contact instant, stand parameters, offsets).
    """

    mass_std: float
    velocity_std: float
    mass: float
    velocity: float
    contact_law: str
    at: str
    unknowns: tuple[str, ...]

    @property
    def mass_relative(self) -> float:
        """σ(M1)/M1 [-]."""
        return self.mass_std / self.mass

    @property
    def velocity_relative(self) -> float:
        """σ(V0)/V0 [-]."""
        return self.velocity_std / self.velocity

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready mapping."""
        return {"mass_std_kg": self.mass_std, "velocity_std_m_s": self.velocity_std,
                "mass_relative": self.mass_relative, "velocity_relative": self.velocity_relative,
                "contact_law": self.contact_law, "at": self.at, "unknowns": list(self.unknowns)}


def _bound_of(cov: np.ndarray, mass: float, velocity: float, *, law: str, at: str,
              unknowns: tuple[str, ...]) -> CramerRao:
    """The :class:`CramerRao` of a covariance of the fit variables whose first two are ln M1 and ln V0."""
    return CramerRao(mass_std=float(mass * np.sqrt(cov[0, 0])), velocity_std=float(velocity * np.sqrt(cov[1, 1])),
                     mass=float(mass), velocity=float(velocity), contact_law=law, at=at, unknowns=unknowns)
