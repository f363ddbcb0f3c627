"""The joint maximum-likelihood fit of one contact-law family over every drop of a calibration set.

Shared unknowns: the stand parameters fitted (default the contact law's parameters, the seal friction and both
dead volumes). Per-drop nuisances: V0 (with the light gate's reading as a Gaussian prior of relative σ
``velocity_sigma``), the contact instant and both sensor offsets; M1 and p0 are known. Each drop is predicted and
differentiated by the model-based identification's engine (:class:`impactometer.identify.model_fit.engine.Residuals`:
the compiled integrator through the recording's sensor model, one batch of integrations per drop and Jacobian),
so the joint Jacobian is kept block by block: a drop's rows depend only on the shared unknowns and its own
nuisances, and the normal equations the solver reads are summed drop by drop (linear in the number of drops); the
engine's solver (:func:`~impactometer.identify.model_fit.engine.solve`) fits it. The fit continues
over growing windows after each drop's contact (:data:`STAGES`, :func:`~impactometer.identify.model_fit.engine.staged`)
as :mod:`impactometer.identify.model_fit.select` does for one record: the first holds the stand and finds each
drop's V0 and contact instant, the later free everything.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from ..errors import IdentificationError
from ..identify.model_fit.engine import (
    TOLERANCE,
    Quality,
    Residuals,
    Solution,
    normal_equations,
    solve,
    staged,
    window,
)
from ..identify.model_fit.forward import Layout, make_layout, stand_values, to_variable
from ..rig import Rig
from .drops import _ObservedDrop

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
#: relative reduction of χ² at which the last stage has converged (the engine's stopping rule): the engine's 1e-6
#: of a χ² of 50 000 left the optimum up to 0.3 σ of a parameter off (Δχ² ~ 0.1)
FINAL_TOLERANCE = 1e-10
#: further start values [-] of contact-law parameters whose joint χ² over the first pulses has more than one minimum:
#: a power-law pad's unloading exponent m and its plastic set φ both shorten the rebound, so a fit started at the
#: law's default m can end at another m with the set driven to zero (χ²/dof 9.9 where the start nearer the truth
#: reaches 1). The screening stages are run from each (the law's default and these, a factor of about 1.7 each side
#: of the default 3.5, spanning soft to stiff pads) and the lowest χ² is kept
ALTERNATIVE_STARTS = {"contact.unloading_exponent": (2.0, 6.0)}
#: per-drop nuisances, in the order they take in the vector of unknowns
NUISANCES = ("velocity", "contact_time", "offset.contact_force", "offset.piston_acceleration")


def _stages_for(duration: float | None) -> tuple[tuple[float | None, str], ...]:
    """The windows of :data:`STAGES` shorter than ``duration`` [s], then ``duration`` itself (None: whole
    records)."""
    return (*((end, kind) for end, kind in STAGES if duration is None or end < duration), (duration, "all"))


@dataclass(frozen=True)
class _Family(Quality):
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
        """Drop ``i``'s vector of :class:`~impactometer.identify.model_fit.engine.Residuals` (V0, contact instant, the
        shared variables, the offsets) of the joint vector ``x`` (default the optimum)."""
        return _local(self.x if x is None else x, i, len(self.free))

    def summary(self) -> dict:
        """JSON-ready figures of the fit."""
        return {"chi2": self.chi2, "dof": self.dof, "reduced_chi2": self.reduced_chi2, "bic": self.bic,
                "unknowns": self.unknowns, "evaluations": self.evaluations, "converged": self.converged,
                "drops_reduced_chi2": [self.drop_reduced_chi2(i) for i in range(len(self.drop_chi2))]}


def _local(x: np.ndarray, i: int, shared: int) -> np.ndarray:
    """Drop ``i``'s vector (V0, contact instant, the ``shared`` variables, the offsets) of a joint vector."""
    own = x[shared + len(NUISANCES) * i: shared + len(NUISANCES) * (i + 1)]
    return np.r_[own[:2], x[:shared], own[2:]]


class _Joint:
    """Residuals and Jacobian of one family on every drop, each drop up to the end of its window, the shared
    variables outside ``active`` held at their values in ``x0``."""

    def __init__(self, drops: Sequence[_ObservedDrop], layouts: Sequence[Layout], shared: int, end: float | None,
                 x0: np.ndarray, active: np.ndarray):
        self.models = [Residuals(drop.data if end is None else window(drop.data, drop.contact_time + end), layout)
                       for drop, layout in zip(drops, layouts, strict=True)]
        self.shared, self.x0, self.active = shared, x0, active
        self.sizes = [model.data.size for model in self.models]
        self.columns = [np.r_[shared + 4 * i, shared + 4 * i + 1, np.arange(shared), shared + 4 * i + 2,
                              shared + 4 * i + 3] for i in range(len(drops))]

    @property
    def size(self) -> int:
        """Number of residuals: every drop's samples and its velocity prior."""
        return int(sum(model.size for model in self.models))

    def full(self, xa: np.ndarray) -> np.ndarray:
        """The joint vector of the active variables ``xa``."""
        out = self.x0.copy()
        out[self.active] = xa
        return out

    def parts(self, x: np.ndarray) -> list[np.ndarray] | None:
        """Each drop's weighted residuals at the joint vector ``x`` (None where a drop's model cannot be
        integrated)."""
        parts = [model.residuals(_local(x, i, self.shared)) for i, model in enumerate(self.models)]
        return None if any(part is None for part in parts) else parts  # type: ignore[return-value]

    def residuals(self, xa: np.ndarray) -> np.ndarray | None:
        """Every drop's weighted residuals, each with its velocity prior's row."""
        parts = self.parts(self.full(xa))
        return None if parts is None else np.concatenate(parts)

    def jacobian(self, xa: np.ndarray) -> list[np.ndarray]:
        """The joint Jacobian as each drop's block (its rows touch the shared columns and its own only:
        ``columns``)."""
        x = self.full(xa)
        return [model.jacobian(_local(x, i, self.shared)) for i, model in enumerate(self.models)]

    def normal(self, blocks: list[np.ndarray], r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The normal equations JᵀJ, Jᵀr of the active variables, summed drop by drop from each block's
        (:func:`~impactometer.identify.model_fit.engine.normal_equations`): linear in the number of drops, where
        those of the assembled Jacobian grow with its square."""
        size = self.x0.size
        normal, gradient = np.zeros((size, size)), np.zeros(size)
        row = 0
        for columns, block in zip(self.columns, blocks, strict=True):
            a, b = normal_equations(block, r[row:row + block.shape[0]])
            normal[np.ix_(columns, columns)] += a
            gradient[columns] += b
            row += block.shape[0]
        return normal[np.ix_(self.active, self.active)], gradient[self.active]

    def root(self, blocks: list[np.ndarray]) -> np.ndarray:
        """The triangle R of the QR decomposition of the Jacobian of the active variables (RᵀR = JᵀJ), from each
        drop's block reduced to its own triangle first (linear in the number of drops)."""
        size = self.x0.size
        rows = []
        for columns, block in zip(self.columns, blocks, strict=True):
            wide = np.zeros((min(block.shape), size))
            wide[:, columns] = np.linalg.qr(block, mode="r")
            rows.append(wide[:, self.active])
        return np.asarray(np.linalg.qr(np.vstack(rows), mode="r"))

    def drop_chi2(self, x: np.ndarray) -> tuple[float, ...]:
        """Each drop's χ² of its samples at the joint vector ``x``."""
        parts = self.parts(x)
        assert parts is not None  # at an answer of the fit
        return tuple(model.sample_chi2(part) for part, model in zip(parts, self.models, strict=True))

    @property
    def constant(self) -> float:
        """χ² of the drops' heads about their means (see :class:`~impactometer.identify.model_fit.engine.Residuals`)."""
        return float(sum(model.constant for model in self.models))


def _start_vector(drops: Sequence[_ObservedDrop], layouts: Sequence[Layout], free: tuple[str, ...],
                 start: dict[str, float]) -> np.ndarray:
    """The joint vector at the stand values ``start`` [SI], each drop at its light-gate V0, its start contact
    instant and the offsets of its pre-trigger."""
    specs = dict(zip(layouts[0].names, layouts[0].specs, strict=True))
    shared = [to_variable(start[name], *specs[name][1:]) for name in free]
    own = [[math.log(drop.velocity), 0.0, *(drop.data.offsets / drop.data.noise)] for drop in drops]
    return np.r_[shared, np.ravel(own)].astype(float)


def _starts(rig: Rig, law: str, free: tuple[str, ...]) -> list[dict[str, float]]:
    """The start values [SI] of the freed stand parameters the family of ``law`` is screened from: the stand's own
    (:func:`~impactometer.identify.model_fit.forward.stand_values`) and each of :data:`ALTERNATIVE_STARTS` that is
    freed and differs from it."""
    own = stand_values(rig, law, free)
    starts = [own]
    for name, values in ALTERNATIVE_STARTS.items():
        if name in free:
            starts += [{**own, name: value} for value in values if not math.isclose(value, own[name])]
    return starts


def _make_layouts(rig: Rig, law: str, free: tuple[str, ...], drops: Sequence[_ObservedDrop], *,
                 velocity_sigma: float) -> tuple[Layout, ...]:
    """Each drop's layout: V0 (with the light gate's reading as its prior of relative σ ``velocity_sigma``) and the
    contact instant unknown, M1 and p0 known, the ``free`` stand parameters."""
    return tuple(make_layout(rig, law, free, pressure_gauge=drop.pressure_gauge, contact_time=drop.contact_time,
                             sample_rate=drop.data.grid.sample_rate, mass=drop.mass).with_prior(
                                 "velocity", drop.velocity, velocity_sigma * drop.velocity) for drop in drops)


def _fit_stage(drops: Sequence[_ObservedDrop], layouts: Sequence[Layout], free: tuple[str, ...], x0: np.ndarray, *,
              velocity_sigma: float, end: float | None, kind: str, evaluations: int = STAGE_EVALUATIONS,
              tolerance: float = TOLERANCE, information: bool = False) -> tuple[Solution, _Joint]:
    """One stage: the joint least-squares fit on the window ``end`` [s] after each drop's start contact instant
    (None: whole records), the shared variables held where ``kind`` is ``"core"`` and all but the contact law's
    where it is ``"contact"``; returns the engine's solution with the full vector as ``x`` and the joint problem."""
    active = np.ones(x0.size, dtype=bool)
    if kind != "all":
        active[:len(free)] = [kind == "contact" and name.startswith("contact.") for name in free]
    joint = _Joint(drops, layouts, len(free), end, x0, active)
    try:
        answer = solve(joint, x0[active], evaluations=evaluations, tolerance=tolerance, information=information)
    except IdentificationError as exc:
        raise IdentificationError(f"the joint {layouts[0].law} fit failed: {exc}") from None
    return Solution(x=joint.full(answer.x), residuals=answer.residuals, chi2=answer.chi2, jacobian=answer.jacobian,
                    evaluations=answer.evaluations, converged=answer.converged), joint


def _fit_family(drops: Sequence[_ObservedDrop], rig: Rig, law: str, free: tuple[str, ...], *, velocity_sigma: float,
               stages: Sequence[tuple[float | None, str]], x0: np.ndarray | None = None, final: bool = True,
               progress: Callable[[], None] | None = None,
               start: dict[str, float] | None = None) -> tuple[_Family, np.ndarray]:
    """Fit the family of ``law`` jointly over ``drops`` through ``stages`` (from ``x0``, else from the stand values
    ``start`` [SI], default the stand's own, see :func:`start_vector`) by
    :func:`~impactometer.identify.model_fit.engine.staged`; returns the last stage's :class:`Family` and its vector.
    ``progress`` is called after each stage."""
    layouts = _make_layouts(rig, law, free, drops, velocity_sigma=velocity_sigma)
    if x0 is None:
        x0 = _start_vector(drops, layouts, free, stand_values(rig, law, free) if start is None else start)
    x = x0
    last = len(stages) - 1

    def fit_one(stage, state):
        k, (end, kind) = stage
        answer, joint = _fit_stage(drops, layouts, free, state[0].x if state else x, velocity_sigma=velocity_sigma,
                                  end=end, kind=kind, information=k == last,
                                  tolerance=FINAL_TOLERANCE if final and k == last else TOLERANCE)
        if progress is not None:
            progress()
        return answer, joint, (state[2] if state else 0) + answer.evaluations

    answer, joint, evaluations = staged(tuple(enumerate(stages)), fit_one, None)
    x = answer.x
    if joint.active.all():
        root = joint.root(answer.jacobian)
    else:  # the Fisher information of every unknown, the held ones too
        every = _Joint(drops, layouts, len(free), stages[-1][0], x, np.ones(x.size, dtype=bool))
        root = every.root(every.jacobian(x))
    drop_chi2 = joint.drop_chi2(x)
    family = _Family(law=law, free=free, layouts=layouts, x=x, root=root, chi2=answer.chi2 + joint.constant,
                    residuals=joint.size, drop_chi2=drop_chi2, drop_residuals=tuple(joint.sizes),
                    evaluations=evaluations, converged=answer.converged)
    return family, x
