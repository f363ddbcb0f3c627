"""Maximum-likelihood fit of a whole record with one contact law: weighted least squares of both channels, every
sample, over M1, V0, the contact instant, the stand parameters marked uncertain and the two sensor offsets."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from scipy.optimize import least_squares

from ...errors import IdentificationError
from .forward import Grid, Layout, predict
from .information import covariance

#: finite-difference step of the Jacobian in the fit variables (ln of a positive value, value/scale of a linear
#: one) and in sample periods for the contact instant. Smaller steps let the integrator's error (its step sequence
#: changes with the parameters, and the contact opens and closes between steps) into the differences: at 1e-6 the
#: Fisher information of M1 came out 8-25 times too large on two pad records (σ(M1) 0.18 % instead of 0.53 %);
#: from 1e-4 to 1e-3 it agrees within 4 %
STEP = 3e-4
CONTACT_TIME_STEP = 1e-2
#: most residual evaluations of one fit (a pad record converges in 11-18)
MAX_EVALUATIONS = 40
#: weighted residual of every sample at a point where the model cannot be integrated
PENALTY = 1e4
#: relative change of χ² and of the variables at which a fit has converged (MINPACK's ftol and xtol): 1e-6 of χ²
#: is ~0.01 on a record of 7000 residuals, nothing beside its scatter of ±120
TOLERANCE = 1e-6


@dataclass(frozen=True)
class Observed:
    """What the fit reads of a recording: both channels (2, n) [N], [m/s²], their noise σ (2,) from the
    pre-trigger, the grid and sensor model of the samples, and the start values of the offsets (2,)."""

    channels: np.ndarray
    noise: np.ndarray
    grid: Grid
    offsets: np.ndarray

    @property
    def size(self) -> int:
        """Number of residuals (both channels)."""
        return int(self.channels.size)


class Quality:
    """The χ² figures of a weighted least-squares fit with ``chi2``, ``residuals`` (their number) and
    ``unknowns``."""

    chi2: float
    residuals: int

    @property
    def unknowns(self) -> int:  # pragma: no cover - every fit defines it
        raise NotImplementedError

    @property
    def dof(self) -> int:
        """Degrees of freedom of χ²."""
        return self.residuals - self.unknowns

    @property
    def reduced_chi2(self) -> float:
        """χ² per degree of freedom [-] (1 when the model explains the data down to their noise)."""
        return self.chi2 / max(self.dof, 1)

    @property
    def bic(self) -> float:
        """Bayesian information criterion χ² + k·ln(N) (−2·log-likelihood up to a constant shared by every law)."""
        return self.chi2 + self.unknowns * math.log(self.residuals)


@dataclass(frozen=True)
class LawFit(Quality):
    """The fit of one contact law.

    ``x`` holds the layout's variables then the offsets in units of each channel's σ; ``cov`` is the inverse
    Fisher information of all of them (unscaled by χ²); ``values`` the physical values [SI] of the layout's
    unknowns and ``offsets`` the sensor offsets [N], [m/s²].
    """

    layout: Layout
    x: np.ndarray
    values: dict
    offsets: np.ndarray
    cov: np.ndarray
    rank: int
    chi2: float
    residuals: int
    evaluations: int
    converged: bool
    #: the span of the record after first contact the fit read [s] and why it ends there (the whole window
    #: given, or the :func:`~.forward.horizon` of the whole record)
    span: tuple[float, str] | None = None

    @property
    def law(self) -> str:
        """The contact law."""
        return self.layout.law

    @property
    def unknowns(self) -> int:
        """Number of fitted unknowns (the layout's and the two offsets)."""
        return self.x.size

    def std(self, name: str) -> float:
        """Standard error [SI] of a fitted unknown from the Fisher information (not scaled by χ²)."""
        j = self.layout.names.index(name)
        return abs(self.layout.derivative(name, float(self.x[j]))) * math.sqrt(self.cov[j, j])

    def summary(self) -> dict:
        """JSON-ready figures of the fit: χ², degrees of freedom, BIC and each unknown with its standard error."""
        return {"chi2": self.chi2, "dof": self.dof, "reduced_chi2": self.reduced_chi2, "bic": self.bic,
                "evaluations": self.evaluations, "converged": self.converged, "rank": self.rank,
                "unknowns": self.unknowns,
                **({} if self.span is None else {"fit_span_s": self.span[0], "fit_span": self.span[1]}),
                "values": {name: self.values[name] for name in self.layout.names},
                "std": {name: self.std(name) for name in self.layout.names},
                "offsets": {"contact_force_N": float(self.offsets[0]),
                            "piston_acceleration_m_s2": float(self.offsets[1])}}


class _Model:
    """Residuals and Jacobian of one layout on one record, sharing the prediction at the last point."""

    def __init__(self, data: Observed, layout: Layout):
        self.data, self.layout = data, layout
        self.scaled = data.channels / data.noise[:, None]
        self.q = len(layout.names)
        self.steps = np.array([CONTACT_TIME_STEP if name == "contact_time" else STEP for name in layout.names])
        self._key: bytes | None = None
        self._pred: np.ndarray | None = None

    def prediction(self, x: np.ndarray) -> np.ndarray:
        """Predicted channels over σ (2, n) at variables ``x`` (offsets excluded)."""
        key = x[:self.q].tobytes()
        if key != self._key:
            params, times = self.layout.packed(x[None, :self.q])
            self._pred = predict(self.data.grid, params, times)[0] / self.data.noise[:, None]
            self._key = key
        assert self._pred is not None  # set above for this key
        return self._pred

    def residuals(self, x: np.ndarray) -> np.ndarray:
        """(data − offset − model)/σ, both channels, every sample; ``PENALTY`` everywhere where the model cannot be
        integrated (a trial point far off: the fit steps back)."""
        try:
            return (self.scaled - x[self.q:, None] - self.prediction(x)).ravel()
        except IdentificationError:
            return np.full(self.data.size, PENALTY)

    def jacobian(self, x: np.ndarray) -> np.ndarray:
        """∂residuals/∂x: forward differences of the layout's variables (one batch of integrations), exact for
        the offsets."""
        base = self.prediction(x)
        steps = self.steps
        rows = x[None, :self.q] + np.diag(steps)
        params, times = self.layout.packed(rows)
        shifted = predict(self.data.grid, params, times) / self.data.noise[None, :, None]
        jac = np.empty((self.data.size, self.q + 2))
        jac[:, :self.q] = -((shifted - base[None]).reshape(self.q, -1) / steps[:, None]).T
        n = self.data.channels.shape[1]
        jac[:, self.q:] = 0.0
        jac[:n, self.q] = -1.0
        jac[n:, self.q + 1] = -1.0
        return jac


def window(data: Observed, end: float) -> Observed:
    """``data`` up to the instant ``end`` [s] on the recording's clock (all of it when ``end`` is past its end)."""
    n = min(data.channels.shape[1], int(math.floor((end - data.grid.start_time) * data.grid.sample_rate)) + 1)
    return replace(data, channels=data.channels[:, :n], grid=replace(data.grid, size=n))


def fit_law(data: Observed, layout: Layout, start: dict[str, float], *, evaluations: int = MAX_EVALUATIONS,
            information: bool = True) -> LawFit:
    """Weighted least-squares fit of ``layout`` to ``data`` from ``start`` (physical values of its unknowns; the
    offsets start from ``data.offsets``), in at most ``evaluations`` residual evaluations; with ``information``
    the covariance from the Jacobian at the optimum (else NaN: a window whose answer only starts the next).

    Raises
    ------
    IdentificationError
        When the model cannot be integrated along the way or the fit does not converge.
    """
    model = _Model(data, layout)
    x0 = np.r_[layout.variables(start), data.offsets / data.noise]
    # Levenberg-Marquardt (MINPACK): the variables are unbounded by their transforms, and its QR of the Jacobian
    # costs a fraction of the SVDs the bounded trust-region method takes at every iteration
    result = least_squares(model.residuals, x0, jac=model.jacobian, method="lm", max_nfev=evaluations,
                           x_scale=1.0, ftol=TOLERANCE, xtol=TOLERANCE)
    if result.status < 0 or np.all(result.fun == PENALTY):
        raise IdentificationError(f"the {layout.law} fit failed: {result.message}")
    x = result.x
    if information:  # scipy's answer holds the Jacobian at the optimum (it evaluates it there after MINPACK)
        cov, rank = covariance(result.jac)
    else:
        cov, rank = np.full((x.size, x.size), np.nan), 0
    q = len(layout.names)
    return LawFit(layout=layout, x=x, values=layout.values(x[:q]), offsets=x[q:] * data.noise, cov=cov, rank=rank,
                  chi2=float(np.dot(result.fun, result.fun)), residuals=data.size, evaluations=int(result.nfev),
                  converged=result.status > 0)


#: Marquardt damping a step of :func:`refine` tries in turn until χ² falls (relative to the diagonal of JᵀJ)
DAMPING = (1e-3, 1e-1, 10.0)


def refine(data: Observed, layout: Layout, start: dict[str, float], offsets: np.ndarray, *,
           steps: int = 1) -> LawFit:
    """``steps`` Levenberg-Marquardt steps of ``layout`` on ``data`` from ``start`` (physical values) and
    ``offsets`` [N], [m/s²]: the update of a fit whose window grew a little (each step one Jacobian and one or a
    few residual evaluations, against the several of :func:`fit_law` and its Jacobian at the optimum). The
    covariance comes from the Jacobian the last step started from; ``converged`` is True (an update does not
    claim convergence, nor does it warn of its absence).

    Raises
    ------
    IdentificationError
        When the model cannot be integrated at the start.
    """
    model = _Model(data, layout)
    x = np.r_[layout.variables(start), offsets / data.noise]
    r = model.residuals(x)
    if np.all(r == PENALTY):
        raise IdentificationError(f"the {layout.law} model cannot be integrated at the update's start")
    chi2, evaluations, jac = float(r @ r), 1, None
    for _ in range(steps):
        jac = model.jacobian(x)
        scale = np.linalg.norm(jac, axis=0)
        scale[scale == 0.0] = 1.0
        scaled = jac / scale
        normal, gradient = scaled.T @ scaled, scaled.T @ r
        for damping in DAMPING:
            lifted = normal + damping * np.diag(np.diag(normal))
            trial = x - np.linalg.lstsq(lifted, gradient, rcond=None)[0] / scale
            r_trial = model.residuals(trial)
            evaluations += 1
            if float(r_trial @ r_trial) < chi2:
                x, r, chi2 = trial, r_trial, float(r_trial @ r_trial)
                break
        else:
            break
    cov, rank = covariance(model.jacobian(x) if jac is None else jac)
    q = len(layout.names)
    return LawFit(layout=layout, x=x, values=layout.values(x[:q]), offsets=x[q:] * data.noise, cov=cov, rank=rank,
                  chi2=chi2, residuals=data.size, evaluations=evaluations, converged=True)


def weighted_jacobian(data: Observed, layout: Layout, values: dict[str, float]) -> np.ndarray:
    """The weighted Jacobian of ``layout`` on ``data`` at physical ``values`` (offsets zero: they enter linearly,
    so the Jacobian does not depend on them)."""
    model = _Model(data, layout)
    return model.jacobian(np.r_[layout.variables(values), 0.0, 0.0])
