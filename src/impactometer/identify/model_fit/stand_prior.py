"""The calibrated stand's own uncertainty carried into σ(M1) and σ(V0) of a whole-record fit.

A calibrated stand file states the σ and correlation of the stand parameters its calibration fitted
(:class:`~impactometer.rig.StandUncertainty`). Those the record's fit frees (by default the contact law's parameters
and the seal friction) are determined by the record itself; those it holds at the calibrated values (for example the
dead volumes) would make M1 and V0 look surer than they are. Their covariance is propagated linearly through the
fit's own Jacobian at its optimum: with J the weighted Jacobian of the fit's unknowns and J_s that of the held
parameters (their fit variables), the answer moves by S = −(JᵀJ)⁻¹JᵀJ_s per unit of the held variables, and the
covariance of the answer gains S Σ_s Sᵀ (Σ_s the stated covariance in the fit variables). To first order this is the
σ of a fit that frees them with the stated Gaussian prior, where the record adds nothing to what the calibration
knows of them; it costs one Jacobian instead of a fit with more unknowns, and leaves the answer itself unchanged.
"""

from __future__ import annotations

import numpy as np

from ...rig import Rig, StandUncertainty
from .engine import LawFit, Observed, weighted_jacobian, window
from .forward import STAND_PARAMETERS, contact_parameters, stand_values


def carried(uncertainty: StandUncertainty | None, rig: Rig, fit: LawFit) -> tuple[str, ...]:
    """The parameters of ``uncertainty`` that ``fit`` holds and whose stated value it uses: stand parameters the
    fit can free, not freed, with a σ > 0; a contact parameter only where the fit's law is the stand's own."""
    if uncertainty is None:
        return ()
    return tuple(name for name, std in zip(uncertainty.names, uncertainty.std, strict=True)
                 if std > 0.0 and name in STAND_PARAMETERS and name not in fit.layout.names
                 and (not name.startswith("contact.")
                      or (fit.law == rig.contact.law and name in contact_parameters(fit.law))))


def stand_variance(data: Observed, fit: LawFit, rig: Rig, uncertainty: StandUncertainty | None
                   ) -> tuple[float, float, tuple[str, ...]]:
    """The variance of ln M1 and ln V0 [-] that the stated uncertainty of the stand parameters ``fit`` holds adds
    to the fit's (S Σ_s Sᵀ, see the module), and the parameters it comes from; (0, 0, ()) where none is carried."""
    names = carried(uncertainty, rig, fit)
    if not names:
        return 0.0, 0.0, ()
    assert uncertainty is not None  # names are carried from a stated uncertainty only
    layout = fit.layout
    for name in names:
        layout = layout.with_free(name)
    held = stand_values(rig, fit.law, names)
    point = {**fit.values, **held}
    part = data if fit.span is None else window(data, fit.values["contact_time"] + fit.span[0])
    jacobian = weighted_jacobian(part, layout, point)
    columns = [layout.names.index(name) for name in names]
    own = [j for j in range(jacobian.shape[1]) if j not in columns]
    if not np.all(np.isfinite(fit.cov)):
        return 0.0, 0.0, names
    sensitivity = -fit.cov @ (jacobian[:, own].T @ jacobian[:, columns])
    x = layout.variables(point)
    slope = np.array([abs(layout.derivative(name, float(x[j]))) for name, j in zip(names, columns, strict=True)])
    stated = uncertainty.covariance(names) / np.outer(slope, slope)
    added = sensitivity[:2] @ stated @ sensitivity[:2].T
    return float(added[0, 0]), float(added[1, 1]), names
