"""Which stand parameters the drops cannot tell apart, and which extra drop would separate them.

Two fitted parameters are not told apart when the magnitude of their correlation exceeds
:data:`CORRELATION_LIMIT`; one is undetermined when the Fisher information leaves it an infinite variance (a
singular value of the column-scaled Jacobian below
:data:`~impactometer.identify.model_fit.information.RANK_TOLERANCE` of the largest). The rule for the extra drop:
three candidates are tried, each alone added to the set (its Fisher information added to the fit's, with its own
four nuisances and light-gate prior):

- another mass: 1.5 times the heaviest drop's M1 (a third of the lightest's where that leaves the stand's range),
- another height: V0 1.3 times the fastest drop's (1.7 times the drop height), within the free-fall range,
- another pressure: p0 at 90 % of the cylinder's rating, or at 15 % where the set's median is above half of it,

each at the set's median of the other two quantities; the candidate that brings the largest correlation of the
flagged pairs lowest is named.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..errors import IdentificationError
from ..identify.model_fit.engine import weighted_jacobian, window
from ..identify.model_fit.forward import make_layout
from ..identify.model_fit.information import covariance
from ..rig import MASS_RANGE, VELOCITY_RANGE, Rig
from .drops import _ObservedDrop
from .joint import NUISANCES, _Family

#: |correlation| above which two fitted parameters are reported as not told apart by the drops [-]
CORRELATION_LIMIT = 0.95
#: M1 of the "another mass" candidate: this times the heaviest drop's (or the lightest's divided by 3) [-]
MASS_STEP = 1.5
#: V0 of the "another height" candidate: this times the fastest drop's [-]
VELOCITY_STEP = 1.3
#: p0 of the "another pressure" candidate: these fractions of the cylinder's rating [-]
PRESSURE_FRACTIONS = (0.9, 0.15)


def _correlation(cov: np.ndarray) -> np.ndarray:
    """Correlation matrix of a covariance; NaN where a variance is infinite or zero."""
    with np.errstate(invalid="ignore", divide="ignore"):
        std = np.sqrt(np.diag(cov))
        out = cov / np.outer(std, std)
    out[~np.isfinite(out)] = np.nan
    np.fill_diagonal(out, 1.0)
    return out


def _flagged(names: Sequence[str], cov: np.ndarray) -> tuple[list[tuple[str, str, float]], list[str]]:
    """The pairs of parameters whose |correlation| exceeds :data:`CORRELATION_LIMIT` (with it) and the parameters
    the drops leave undetermined (infinite variance)."""
    corr = _correlation(cov)
    pairs = [(names[a], names[b], float(corr[a, b])) for a in range(len(names)) for b in range(a + 1, len(names))
             if np.isfinite(corr[a, b]) and abs(corr[a, b]) > CORRELATION_LIMIT]
    lost = [name for j, name in enumerate(names) if not np.isfinite(cov[j, j])]
    return pairs, lost


def _candidates(drops: Sequence[_ObservedDrop], rig: Rig) -> dict[str, tuple[float, float, float]]:
    """The extra drops tried (see the module notes): kind -> (M1 [kg], V0 [m/s], p0 [Pa gauge])."""
    masses = np.array([drop.mass for drop in drops])
    velocities = np.array([drop.velocity for drop in drops])
    pressures = np.array([drop.pressure_gauge for drop in drops])
    mass, velocity, pressure_gauge = (float(np.median(a)) for a in (masses, velocities, pressures))
    heavier = MASS_STEP * masses.max()
    other_mass = heavier if heavier <= MASS_RANGE[1] else masses.min() / 3.0
    faster = min(VELOCITY_STEP * velocities.max(), VELOCITY_RANGE[1])
    rated = rig.cylinder.rated_pressure_gauge
    other_pressure = PRESSURE_FRACTIONS[0 if pressure_gauge <= rated / 2 else 1] * rated
    return {"mass": (other_mass, velocity, pressure_gauge), "height": (mass, faster, pressure_gauge),
            "pressure": (mass, velocity, other_pressure)}


def _with_drop(family: _Family, drops: Sequence[_ObservedDrop], rig: Rig, scenario: tuple[float, float, float],
               velocity_sigma: float, end: float | None) -> np.ndarray:
    """The covariance of the shared variables with one more drop of ``scenario`` (recorded like the first drop:
    its sample rate, noise and length)."""
    mass, velocity, pressure_gauge = scenario
    first = drops[0]
    t0 = family.layouts[0].values(family.local(0))["contact_time"]
    data = first.data if end is None else window(first.data, first.contact_time + end)
    layout = make_layout(rig, family.law, family.free, pressure_gauge=pressure_gauge, contact_time=t0,
                         sample_rate=data.grid.sample_rate, mass=mass)
    shared = family.layouts[0].values(family.local(0))
    values = {**{name: shared[name] for name in family.free}, "velocity": velocity, "contact_time": t0}
    jac = weighted_jacobian(data, layout, values)  # columns: V0, contact instant, shared, two offsets
    k, s = family.unknowns, len(family.free)
    extra = np.zeros((jac.shape[0] + 1, k + len(NUISANCES)))
    extra[:-1, :s] = jac[:, 2:2 + s]
    extra[:-1, k:k + 2] = jac[:, :2]
    extra[:-1, k + 2:] = jac[:, 2 + s:]
    extra[-1, k] = 1.0 / velocity_sigma
    root = np.hstack([family.root, np.zeros((family.root.shape[0], len(NUISANCES)))])
    cov, _ = covariance(np.vstack([root, extra]))
    return cov[:s, :s]


def _suggest(family: _Family, drops: Sequence[_ObservedDrop], rig: Rig, pairs: Sequence[tuple[str, str, float]], *,
             velocity_sigma: float, end: float | None) -> dict | None:
    """The extra drop that best separates ``pairs`` (see the module notes), or None when no pair is flagged or no
    candidate can be predicted: kind, M1, V0, p0 and the largest |correlation| of the pairs before and after."""
    if not pairs:
        return None
    index = {name: j for j, name in enumerate(family.free)}
    before = max(abs(c) for _, _, c in pairs)
    best: dict | None = None
    for kind, scenario in _candidates(drops, rig).items():
        try:
            corr = _correlation(_with_drop(family, drops, rig, scenario, velocity_sigma, end))
        except IdentificationError:
            continue
        after = max(abs(float(corr[index[a], index[b]])) for a, b, _ in pairs)
        if not np.isfinite(after):  # the candidate leaves a parameter undetermined: no help
            continue
        if best is None or after < float(best["largest_correlation_after"]):
            best = {"kind": kind, "mass_kg": scenario[0], "velocity_m_s": scenario[1],
                    "pressure_gauge_Pa": scenario[2], "largest_correlation_before": before,
                    "largest_correlation_after": after}
    return best
