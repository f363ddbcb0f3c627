"""The joint maximum-likelihood fit of one contact-law family over every drop of a calibration set.

Shared unknowns: the stand parameters fitted (default the contact law's parameters, the seal friction and both
dead volumes). Per-drop nuisances: V0 (with the light gate's reading as a Gaussian prior of relative σ
``velocity_sigma``), the contact instant and both sensor offsets; M1 and p0 are known. Each drop is predicted and
differentiated by the model-based identification's engine (:class:`impactometer.identify.model_fit.fit._Model`:
the compiled integrator through the recording's sensor model, one batch of integrations per drop and Jacobian),
so the joint Jacobian is assembled block by block: a drop's rows depend only on the shared unknowns and its own
nuisances. The fit continues over growing windows after each drop's contact (:data:`STAGES`) as
:mod:`impactometer.identify.model_fit.select` does for one record: the first holds the stand and finds each drop's
V0 and contact instant, the later free everything.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from ..errors import IdentificationError
from ..identify.model_fit.fit import TOLERANCE, Quality, _Model, window
from ..identify.model_fit.forward import Layout, make_layout, stand_values, to_variable
from ..rig import Rig
from .drops import ObservedDrop

#: windows after each drop's start contact instant [s] fitted in turn, up to the length fitted (see
#: :func:`stages_for`), and which shared stand parameters are free in them: none ("core": each drop's V0, contact
#: instant and offsets only), the contact law's ("contact"), or all. The first pulses say little of the dead
#: volumes and the friction: freed there (from a stand without dead volumes, the pad stand's drops), they drifted
#: to values the later windows did not bring back (chi2/dof 2.3 instead of 1.01)
STAGES = ((0.004, "core"), (0.008, "contact"), (0.015, "contact"), (0.03, "all"), (0.06, "all"), (0.1, "all"))
#: the stage after which the families are screened by BIC (index into STAGES)
SCREEN_STAGE = 3
#: most residual evaluations of one stage
STAGE_EVALUATIONS = 100
#: relative change of χ² and of the variables at which the last stage has converged (MINPACK's ftol and xtol): the
#: engine's 1e-6 of a χ² of 50 000 left the optimum up to 0.3 σ of a parameter off (Δχ² ~ 0.1)
FINAL_TOLERANCE = 1e-10
#: per-drop nuisances, in the order they take in the vector of unknowns
NUISANCES = ("velocity", "contact_time", "offset.contact_force", "offset.piston_acceleration")


def stages_for(duration: float | None) -> tuple[tuple[float | None, str], ...]:
    """The windows of :data:`STAGES` shorter than ``duration`` [s], then ``duration`` itself (None: whole
    records)."""
    return (*((end, kind) for end, kind in STAGES if duration is None or end < duration), (duration, "all"))


@dataclass(frozen=True)
class Family(Quality):
    """The joint fit of one contact-law family.

    ``x`` holds the fit variables (the shared ones, then per drop :data:`NUISANCES`: ln V0, the contact instant in
    sample periods from the drop's start, the offsets in units of the channel's σ); ``root`` is the triangle R of
    the QR decomposition of the weighted Jacobian at the optimum (RᵀR is the Fisher information, so
    :func:`~impactometer.identify.model_fit.information.covariance` of R is the covariance of ``x``); ``chi2`` is
    that of every residual (the samples and the velocity priors) and ``drop_chi2`` each drop's samples' share.
    """

    law: str
    free: tuple[str, ...]
    layouts: tuple[Layout, ...]
    x: np.ndarray
    root: np.ndarray
    chi2: float
    residuals: int
    drop_chi2: tuple[float, ...]
    drop_residuals: tuple[int, ...]
    evaluations: int
    converged: bool

    @property
    def unknowns(self) -> int:
        """Number of fitted unknowns (shared and per drop)."""
        return int(self.x.size)

    def drop_reduced_chi2(self, i: int) -> float:
        """χ²/dof of drop ``i``'s samples, its dof its samples less its four nuisances [-]."""
        return self.drop_chi2[i] / max(self.drop_residuals[i] - len(NUISANCES), 1)

    def local(self, i: int, x: np.ndarray | None = None) -> np.ndarray:
        """Drop ``i``'s vector of :class:`~impactometer.identify.model_fit.fit._Model` (V0, contact instant, the
        shared variables, the offsets) of the joint vector ``x`` (default the optimum)."""
        return local(self.x if x is None else x, i, len(self.free))

    def summary(self) -> dict:
        """JSON-ready figures of the fit."""
        return {"chi2": self.chi2, "dof": self.dof, "reduced_chi2": self.reduced_chi2, "bic": self.bic,
                "unknowns": self.unknowns, "evaluations": self.evaluations, "converged": self.converged,
                "drops_reduced_chi2": [self.drop_reduced_chi2(i) for i in range(len(self.drop_chi2))]}


def local(x: np.ndarray, i: int, shared: int) -> np.ndarray:
    """Drop ``i``'s vector (V0, contact instant, the ``shared`` variables, the offsets) of a joint vector."""
    own = x[shared + len(NUISANCES) * i: shared + len(NUISANCES) * (i + 1)]
    return np.r_[own[:2], x[:shared], own[2:]]


class _Joint:
    """Residuals and Jacobian of one family on every drop, each drop up to the end of its window.

    Each drop is handed to the solver compressed: at each point x, with Q R = [J r] the QR decomposition of the
    drop's Jacobian J and weighted residuals r (n samples × m unknowns of the drop, and r), its rows are
    c = [Qᵀr, |r − QQᵀr|] and their Jacobian [R_J; 0] (R_J the triangle of J). The sum of squares |c|² = |r|²,
    the gradient R_Jᵀ Qᵀr = Jᵀr and the Gauss-Newton information R_Jᵀ R_J = JᵀJ are those of the uncompressed
    rows at every point, and so are the column norms MINPACK scales by: Levenberg-Marquardt takes the same steps
    (the Jacobian is differenced at every trial point instead of at every accepted one). A drop then gives the
    solver m + 1 rows instead of n: MINPACK's dense QR of the joint Jacobian, (samples of all drops) × (4 per drop
    + shared), grew as the cube of the number of drops (6 drops: 5 s of a 17 s calibration; 12 drops: 36 s of
    69 s), the compressed one costs next to nothing.
    """

    def __init__(self, drops: Sequence[ObservedDrop], layouts: Sequence[Layout], shared: int, velocity_sigma: float,
                 end: float | None):
        self.models = [_Model(drop.data if end is None else window(drop.data, drop.contact_time + end), layout)
                       for drop, layout in zip(drops, layouts, strict=True)]
        self.shared, self.sigma = shared, velocity_sigma
        self.gate = np.log([drop.velocity for drop in drops])
        self.sizes = [model.data.size for model in self.models]
        self.columns = [np.r_[shared + 4 * i, shared + 4 * i + 1, np.arange(shared), shared + 4 * i + 2,
                              shared + 4 * i + 3] for i in range(len(drops))]
        self.rows = [len(columns) + 1 for columns in self.columns]
        self._last: tuple[bytes, list[np.ndarray]] | None = None

    def velocities(self, x: np.ndarray) -> np.ndarray:
        return x[self.shared::len(NUISANCES)][:len(self.models)]

    def _triangles(self, x: np.ndarray, exact: bool = False) -> list[np.ndarray]:
        """Each drop's triangle R of [J r] at ``x`` (the last point's kept: the solver asks for the Jacobian where
        it has just evaluated the residuals; ``exact``: by QR, see :func:`_triangle`); where the model cannot be
        integrated (a trial point far off, which the solver steps back from) the residuals' norm alone."""
        key = x.tobytes() + bytes([exact])
        if self._last is None or self._last[0] != key:
            triangles = []
            for i, model in enumerate(self.models):
                xi = local(x, i, self.shared)
                r = model.residuals(xi)
                try:
                    triangles.append(_triangle(np.column_stack([_jacobian(model, xi), r]), exact=exact))
                except IdentificationError:
                    out = np.zeros((self.rows[i], self.rows[i]))
                    out[-1, -1] = np.linalg.norm(r)
                    triangles.append(out)
            self._last = (key, triangles)
        return self._last[1]

    def residuals(self, x: np.ndarray) -> np.ndarray:
        """Every drop's compressed residuals (see the class notes), then the velocity priors (ln V0 − ln V_gate)/σ."""
        parts = [np.r_[t[:-1, -1], abs(t[-1, -1])] for t in self._triangles(x)]
        return np.concatenate([*parts, (self.velocities(x) - self.gate) / self.sigma])

    def jacobian(self, x: np.ndarray, exact: bool = False) -> np.ndarray:
        """The Jacobian of :meth:`residuals`, assembled from each drop's block (its rows touch the shared columns
        and its own); ``exact``: each drop's triangle by QR (the information at the optimum)."""
        jac = np.zeros((sum(self.rows) + len(self.models), x.size))
        row = 0
        for i, t in enumerate(self._triangles(x, exact)):
            jac[row:row + self.rows[i] - 1, self.columns[i]] = t[:-1, :-1]
            row += self.rows[i]
        jac[row + np.arange(len(self.models)), self.shared + len(NUISANCES) * np.arange(len(self.models))] = \
            1.0 / self.sigma
        return jac


def _triangle(a: np.ndarray, exact: bool = False) -> np.ndarray:
    """An upper triangle R with RᵀR = aᵀa for the tall ``a`` (square, its columns' count; rows and columns of the
    columns that are zero left zero: a parameter of another law than the drop's): by Cholesky of the Gram matrix
    of the other columns scaled to unit norm (a fraction of a millisecond for 6000 × 10, where LAPACK's QR took
    2 ms on one thread and 0.2 s on the threads of a loaded machine), by QR where that is not positive definite or
    ``exact`` is asked (the Gram matrix squares the columns' condition: σ of the example's restitution, its
    smallest relative one, came out 2 % off by Cholesky)."""
    live = np.flatnonzero(np.any(a != 0.0, axis=0))
    part = a[:, live]
    norms = np.linalg.norm(part, axis=0)
    scaled = part / norms
    try:
        if exact:
            raise np.linalg.LinAlgError
        triangle = np.linalg.cholesky(scaled.T @ scaled).T * norms
    except np.linalg.LinAlgError:
        triangle = np.asarray(np.linalg.qr(part, mode="r"))
    out = np.zeros((a.shape[1], a.shape[1]))
    out[np.ix_(np.arange(live.size), live)] = triangle
    return out


def _jacobian(model: _Model, x: np.ndarray) -> np.ndarray:
    """``model``'s Jacobian at ``x`` by forward differences, or by backward ones where a forward step leaves the
    range the model is integrated in (a fit of a family that does not describe the drops runs to its edges)."""
    try:
        return model.jacobian(x)
    except IdentificationError:
        model.steps = -model.steps
        try:
            return model.jacobian(x)
        finally:
            model.steps = -model.steps


def start_vector(drops: Sequence[ObservedDrop], layouts: Sequence[Layout], free: tuple[str, ...],
                 start: dict[str, float]) -> np.ndarray:
    """The joint vector at the stand values ``start`` [SI], each drop at its light-gate V0, its start contact
    instant and the offsets of its pre-trigger."""
    specs = dict(zip(layouts[0].names, layouts[0].specs, strict=True))
    shared = [to_variable(start[name], *specs[name][1:]) for name in free]
    own = [[math.log(drop.velocity), 0.0, *(drop.data.offsets / drop.data.noise)] for drop in drops]
    return np.r_[shared, np.ravel(own)].astype(float)


def make_layouts(rig: Rig, law: str, free: tuple[str, ...], drops: Sequence[ObservedDrop]) -> tuple[Layout, ...]:
    """Each drop's layout: V0 and the contact instant unknown, M1 and p0 known, the ``free`` stand parameters."""
    return tuple(make_layout(rig, law, free, pressure=drop.pressure, contact_time=drop.contact_time,
                             sample_rate=drop.data.grid.sample_rate, mass=drop.mass) for drop in drops)


def fit_stage(drops: Sequence[ObservedDrop], layouts: Sequence[Layout], free: tuple[str, ...], x0: np.ndarray, *,
              velocity_sigma: float, end: float | None, kind: str, evaluations: int = STAGE_EVALUATIONS,
              tolerance: float = TOLERANCE):
    """One stage: the joint least-squares fit on the window ``end`` [s] after each drop's start contact instant
    (None: whole records), the shared variables held where ``kind`` is ``"core"`` and all but the contact law's
    where it is ``"contact"``; returns the scipy answer with the full vector as ``x`` and the joint problem."""
    joint = _Joint(drops, layouts, len(free), velocity_sigma, end)
    active = np.ones(x0.size, dtype=bool)
    if kind != "all":
        active[:len(free)] = [kind == "contact" and name.startswith("contact.") for name in free]

    def full(xa: np.ndarray) -> np.ndarray:
        out = x0.copy()
        out[active] = xa
        return out

    answer = least_squares(lambda xa: joint.residuals(full(xa)), x0[active],
                           jac=lambda xa: joint.jacobian(full(xa))[:, active], method="lm", max_nfev=evaluations,
                           x_scale=1.0, ftol=tolerance, xtol=tolerance)
    if answer.status < 0 or not np.all(np.isfinite(answer.fun)):
        raise IdentificationError(f"the joint {layouts[0].law} fit failed: {answer.message}")
    answer.x = full(answer.x)
    return answer, joint


def fit_family(drops: Sequence[ObservedDrop], rig: Rig, law: str, free: tuple[str, ...], *, velocity_sigma: float,
               stages: Sequence[tuple[float | None, str]], x0: np.ndarray | None = None, final: bool = True,
               progress: Callable[[], None] | None = None) -> tuple[Family, np.ndarray]:
    """Fit the family of ``law`` jointly over ``drops`` through ``stages`` (from ``x0``, default the stand's own
    values, see :func:`start_vector`); returns the last stage's :class:`Family` and its vector. ``progress`` is
    called after each stage."""
    layouts = make_layouts(rig, law, free, drops)
    x = start_vector(drops, layouts, free, stand_values(rig, law, free)) if x0 is None else x0
    evaluations = 0
    answer = joint = None
    for k, (end, kind) in enumerate(stages):
        answer, joint = fit_stage(drops, layouts, free, x, velocity_sigma=velocity_sigma, end=end, kind=kind,
                                  tolerance=FINAL_TOLERANCE if final and k == len(stages) - 1 else TOLERANCE)
        x, evaluations = answer.x, evaluations + int(answer.nfev)
        if progress is not None:
            progress()
    assert answer is not None and joint is not None  # stages is never empty
    root = np.asarray(np.linalg.qr(joint.jacobian(x, exact=True), mode="r"))  # the uncompressed information at x
    fun = joint.residuals(x)
    bounds = np.cumsum([0, *joint.rows])
    drop_chi2 = tuple(float(fun[a:b] @ fun[a:b]) for a, b in zip(bounds[:-1], bounds[1:], strict=True))
    family = Family(law=law, free=free, layouts=layouts, x=x, root=root, chi2=float(fun @ fun),
                    residuals=int(sum(joint.sizes)) + len(drops), drop_chi2=drop_chi2,
                    drop_residuals=tuple(joint.sizes), evaluations=evaluations, converged=answer.status > 0)
    return family, x
