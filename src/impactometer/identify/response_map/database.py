"""The response map (paper section 5): features over a mass × velocity grid, optionally with a pressure axis, and
its refinement by interpolation (tensor-product cubic spline, not-a-knot) to any N×N.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.interpolate import CubicSpline

from ...errors import ParameterError, ResponseMapError
from ...recording import check_sample_rate
from ...rig import Rig, from_dict
from ...validation import is_integer, real_array
from .features import get_feature_set

SCHEMA_VERSION = 1
#: largest map (number of stored feature values) refine or build will create: 800 MB in float64
MAX_VALUES = 100_000_000


def _axis(values, name: str, unit: str) -> np.ndarray:
    arr = real_array(name, values, unit=f" {unit}", error=ResponseMapError).ravel()
    expected = f"{name} must be a non-empty, finite, strictly increasing axis {unit}"
    if arr.size < 1:
        raise ResponseMapError(f"{expected}, got no values")
    bad = np.flatnonzero(~np.isfinite(arr))
    if bad.size:
        raise ResponseMapError(f"{expected}, got {float(arr[bad[0]])!r} at index {int(bad[0])} of {arr.size}")
    steps = np.flatnonzero(np.diff(arr) <= 0)
    if steps.size:
        i = int(steps[0])
        raise ResponseMapError(f"{expected}, got {float(arr[i + 1]):g} after {float(arr[i]):g} at index {i + 1} of "
                               f"{arr.size}")
    return arr


@dataclass(frozen=True, kw_only=True)
class ResponseMap:
    """Features of the force response over impacting mass × impact velocity (× charge pressure).

    Attributes
    ----------
    masses : (n_m,) Mass axis M1 [kg], increasing.
    velocities : (n_v,) Velocity axis V0 [m/s], increasing.
    pressures_gauge : (n_p,) Charge-pressure axis [Pa gauge]; one entry for a map at a single pressure.
    values : (m, n_p, n_m, n_v) Feature values (units of the feature set), all > 0.
    feature_set : Name in :data:`~impactometer.identify.response_map.features.FEATURE_SETS`.
    feature_params : Parameters of the feature set (SI).
    sample_rate : Sample rate of the signals the features came from [Hz].
    rig : The stand (``rig.to_dict`` form).
    provenance : How the map was made (source, base grid, refinement, package version, date).
    """

    masses: np.ndarray
    velocities: np.ndarray
    pressures_gauge: np.ndarray
    values: np.ndarray
    feature_set: str
    feature_params: dict[str, float]
    sample_rate: float
    rig: dict[str, Any]
    provenance: dict[str, Any] = field(default_factory=dict)
    _cache: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        set_(self, "masses", _axis(self.masses, "masses", "[kg]"))
        set_(self, "velocities", _axis(self.velocities, "velocities", "[m/s]"))
        set_(self, "pressures_gauge", _axis(self.pressures_gauge, "pressures_gauge", "[Pa gauge]"))
        if self.masses[0] <= 0 or self.velocities[0] <= 0 or self.pressures_gauge[0] < 0:
            raise ResponseMapError("masses and velocities must be > 0 and pressures_gauge >= 0, got minima "
                                   f"{self.masses[0]!r} kg, {self.velocities[0]!r} m/s, {self.pressures_gauge[0]!r} Pa")
        fs = get_feature_set(self.feature_set)
        set_(self, "feature_params", fs.params(self.feature_params))
        values = np.asarray(self.values, dtype=float)
        expected = (fs.size, self.pressures_gauge.size, self.masses.size, self.velocities.size)
        if values.shape != expected:
            raise ResponseMapError(f"values must have shape (features, pressures, masses, velocities) = {expected}, "
                                   f"got {values.shape}")
        bad = ~(np.isfinite(values) & (values > 0))
        if bad.any():
            f, p, i, j = (int(k[0]) for k in np.nonzero(bad))
            raise ResponseMapError(f"feature {fs.labels[f]!r} must be finite and > 0 everywhere, got "
                                   f"{values[f, p, i, j]!r} at mass {self.masses[i]:g} kg, velocity "
                                   f"{self.velocities[j]:g} m/s, pressure {self.pressures_gauge[p]:g} Pa")
        set_(self, "values", values)
        set_(self, "sample_rate", check_sample_rate(self.sample_rate, error=ResponseMapError))
        try:
            from_dict(self.rig, source="map rig")
        except ParameterError as exc:
            raise ResponseMapError(f"the map's stand description is invalid: {exc}") from None

    @property
    def shape(self) -> tuple[int, int]:
        """(masses, velocities)."""
        return self.masses.size, self.velocities.size

    @property
    def labels(self) -> tuple[str, ...]:
        """Feature names."""
        return get_feature_set(self.feature_set).labels

    @property
    def stand(self) -> Rig:
        """The stand as a :class:`~impactometer.rig.Rig`."""
        return from_dict(self.rig, source="map rig")

    def describe(self) -> dict[str, Any]:
        """Plain summary for ``map info`` and reports."""
        fs = get_feature_set(self.feature_set)
        return {
            "schema_version": SCHEMA_VERSION, "feature_set": self.feature_set, "feature_params": self.feature_params,
            "features": {label: {"unit": unit, "min": float(self.values[k].min()), "max": float(self.values[k].max())}
                         for k, (label, unit) in enumerate(zip(fs.labels, fs.units, strict=False))},
            "grid": list(self.shape), "mass_range_kg": [float(self.masses[0]), float(self.masses[-1])],
            "velocity_range_m_s": [float(self.velocities[0]), float(self.velocities[-1])],
            "pressures_gauge_Pa": self.pressures_gauge.tolist(), "sample_rate_Hz": float(self.sample_rate),
            "stand": self.rig.get("name"), "contact_law": self.rig.get("contact", {}).get("law"),
            "size_MB": self.values.nbytes / 1e6, "provenance": self.provenance,
        }


def spline_basis(x: np.ndarray, x_new: np.ndarray, derivative: int = 0) -> np.ndarray:
    """Matrix B with ``B @ y`` = the not-a-knot cubic spline through (x, y) (or its derivative) at ``x_new``."""
    if x.size == 1:
        return np.full((np.size(x_new), 1), 1.0 if derivative == 0 else 0.0)
    return CubicSpline(x, np.eye(x.size), axis=0)(x_new, derivative)


def _check_size(n_features: int, n_p: int, n_m: int, n_v: int) -> None:
    total = n_features * n_p * n_m * n_v
    if total > MAX_VALUES:
        raise ParameterError(f"a {n_m}×{n_v} map with {n_p} pressure(s) and {n_features} features holds {total} "
                             f"values ({total * 8 / 1e9:.2f} GB), above the limit of {MAX_VALUES}; expected a smaller "
                             "grid or one map per pressure")


def grid_size(n: int | tuple[int, int], field: str) -> tuple[int, int]:
    """N -> (N, N); (n_m, n_v) checked: integers >= 2."""
    sizes = (n, n) if isinstance(n, (int, np.integer)) else tuple(n) if isinstance(n, (tuple, list)) else (n,)
    if len(sizes) != 2 or any(not is_integer(k) or k < 2 for k in sizes):
        raise ParameterError(f"{field}: grid size must be an integer >= 2 or a pair of them, got {n!r}")
    return int(sizes[0]), int(sizes[1])


def refine(rmap: ResponseMap, n: int | tuple[int, int]) -> ResponseMap:
    """The map interpolated to an N×N (or n_m × n_v) grid, uniform in mass and velocity over the same ranges.

    Interpolation is the tensor-product not-a-knot cubic spline through the map's nodes, layer by layer along the
    pressure axis (which is kept as it is).
    """
    n_m, n_v = grid_size(n, "refine")
    _check_size(len(rmap.labels), rmap.pressures_gauge.size, n_m, n_v)
    masses = np.linspace(rmap.masses[0], rmap.masses[-1], n_m)
    velocities = np.linspace(rmap.velocities[0], rmap.velocities[-1], n_v)
    bm = spline_basis(rmap.masses, masses)
    bv = spline_basis(rmap.velocities, velocities)
    values = np.empty((len(rmap.labels), rmap.pressures_gauge.size, n_m, n_v))
    for f in range(values.shape[0]):
        for p in range(values.shape[1]):
            values[f, p] = bm @ rmap.values[f, p] @ bv.T
    if np.any(values <= 0):
        raise ResponseMapError("refine: the cubic interpolation of the map is not positive everywhere; expected a "
                               "map whose features stay well above zero (use a denser base grid)")
    history = list(rmap.provenance.get("refinements", [])) + [{"from": list(rmap.shape), "to": [n_m, n_v],
                                                               "method": "tensor-product cubic spline, not-a-knot"}]
    return ResponseMap(masses=masses, velocities=velocities, pressures_gauge=rmap.pressures_gauge, values=values,
                       feature_set=rmap.feature_set, feature_params=rmap.feature_params, sample_rate=rmap.sample_rate,
                       rig=rmap.rig, provenance={**rmap.provenance, "refinements": history})


