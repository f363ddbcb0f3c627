"""The calibrated stand's own uncertainty carried into σ(M1) and σ(V0) of a whole-record fit.

A calibrated stand file states the σ and correlation of the stand parameters its calibration fitted
(:class:`~impactometer.rig.StandUncertainty`). Those the record's fit frees (by default the contact law's parameters
and the seal friction) are determined by the record itself; those it holds at the calibrated values (for example the
dead volumes) would make M1 and V0 look surer than they are. Their covariance is propagated linearly through the
fit's own Jacobian at its optimum: with J the weighted Jacobian of the fit's unknowns and J_s that of the held
parameters (their fit variables), the answer moves by S = −(JᵀJ)⁻¹JᵀJ_s per unit of the held variables, and the
covariance of the answer gains S Σ_s Sᵀ (Σ_s the stated covariance in the fit variables). J_s is a central
difference over ± each parameter's stated σ (at least the fit's own step): the secant over the range the calibration
leaves open, where the fit's own small step (:data:`.engine.STEP`) reads the integrator's tolerance rather than the
slope of a parameter as weak in a record as a dead volume (its S came out 2-50 times off a refit's; the secant's
agrees with a refit on the stand moved by ±σ). To first order this is the
σ of a fit that frees them with the stated Gaussian prior, where the record adds nothing to what the calibration
knows of them; it costs one Jacobian instead of a fit with more unknowns, and leaves the answer itself unchanged.
"""

from __future__ import annotations

import math

import numpy as np

from ...rig import Rig, StandUncertainty
from .engine import STEP, LawFit, Observed, Residuals, weighted_jacobian, window
from .forward import STAND_PARAMETERS, contact_parameters, stand_values


def _carried(uncertainty: StandUncertainty | None, rig: Rig, fit: LawFit) -> tuple[str, ...]:
    """The parameters of ``uncertainty`` that ``fit`` holds and whose stated value it uses: stand parameters the
    fit can free, not freed, with a σ > 0; a contact parameter only where the fit's law is the stand's own."""
    if uncertainty is None:
        return ()
    return tuple(name for name, std in zip(uncertainty.names, uncertainty.std, strict=True)
                 if std > 0.0 and name in STAND_PARAMETERS and name not in fit.layout.names
                 and (not name.startswith("contact.")
                      or (fit.law == rig.contact.law and name in contact_parameters(fit.law))))


def _stand_variance(data: Observed, fit: LawFit, rig: Rig, uncertainty: StandUncertainty | None
                   ) -> tuple[float, float, tuple[str, ...], tuple[str, ...]]:
    """The variance of ln M1 and ln V0 [-] that the stated uncertainty of the stand parameters ``fit`` holds adds
    to the fit's (S Σ_s Sᵀ, see the module), the parameters it comes from, and those whose slope the model could not
    be integrated for (not carried); (0, 0, (), ()) where none is carried."""
    names = _carried(uncertainty, rig, fit)
    if not names:
        return 0.0, 0.0, (), ()
    assert uncertainty is not None  # names are carried from a stated uncertainty only
    layout = fit.layout
    for name in names:
        layout = layout.with_free(name)
    point = {**fit.values, **stand_values(rig, fit.law, names)}
    part = window(data, fit.end)
    x = np.r_[layout.variables(point), fit.x[-2:]]
    problem = Residuals(part, layout)
    # each stated σ in its fit variable (d value / d variable at the calibrated value)
    scale = {name: abs(layout.derivative(name, float(x[layout.names.index(name)]))) for name in names}
    slopes = {}
    for name in names:
        std = math.sqrt(uncertainty.covariance((name,))[0, 0]) / scale[name]
        slope = _secant(problem, x, layout.names.index(name), max(std, STEP))
        if slope is not None:
            slopes[name] = slope
    lost = tuple(name for name in names if name not in slopes)
    kept = tuple(slopes)
    if not kept or not np.all(np.isfinite(fit.cov)):
        return 0.0, 0.0, kept, lost
    factor = np.array([scale[name] for name in kept])
    stated = uncertainty.covariance(kept) / np.outer(factor, factor)
    held = np.column_stack([slopes[name] for name in kept])
    own = weighted_jacobian(part, fit.layout, fit.values)
    sensitivity = -fit.cov @ (own.T @ held)
    added = sensitivity[:2] @ stated @ sensitivity[:2].T
    return float(added[0, 0]), float(added[1, 1]), kept, lost


def _secant(problem: Residuals, x: np.ndarray, j: int, step: float) -> np.ndarray | None:
    """The central difference of the residuals of ``problem`` in variable ``j`` over ± ``step`` (one-sided where one
    end leaves the range the model is integrated in, as a calibrated volume of 0 does), quartered until the model can
    be integrated (a stated σ that reaches beyond the range the model is integrated in, as
    an inflated σ of a stand that does not describe its drops can), down to the fit's own step; None where even that
    cannot be integrated."""
    while True:
        moved = np.zeros_like(x)
        moved[j] = step
        up, down = problem.residuals(x + moved), problem.residuals(x - moved)
        if up is not None and down is not None:
            return (up - down) / (2.0 * step)
        middle = problem.residuals(x)
        if middle is not None and (up is not None or down is not None):  # at the edge of the range (a volume of 0)
            return (up - middle) / step if up is not None else (middle - down) / step
        if step <= STEP:
            return None
        step = max(step / 4.0, STEP)
