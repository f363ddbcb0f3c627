"""The response map (paper section 5): features over a mass × velocity grid, optionally with a pressure axis.

Built by simulation with the fast simulator or from a calibration set of recordings with known mass and velocity,
and refined by interpolation (tensor-product cubic spline, not-a-knot) to any N×N.
"""

from __future__ import annotations

import time as _time
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.interpolate import CubicSpline, RBFInterpolator

from ... import __version__
from ...errors import ParameterError, ResponseMapError
from ...recording import Recording, check_sample_rate
from ...rig import PRESETS, STAND_KEY, Rig, check_recorded_on, from_dict, get_rig, to_dict
from .features import extract_batch, extract_features, get_feature_set, recording_signal

SCHEMA_VERSION = 1
#: largest map (number of stored feature values) refine or build will create: 800 MB in float64
MAX_VALUES = 100_000_000
#: most impacts a map build simulates (a 500×500 grid; about a thousand a second on two cores): larger maps come
#: from interpolating a simulated one (:func:`refine`)
MAX_SIMULATED = 250_000
#: two charge pressures closer than max(absolute, relative·p) are the same [Pa], [-]
PRESSURE_TOLERANCE = (1e3, 0.01)


def _axis(values, name: str, unit: str) -> np.ndarray:
    try:
        arr = np.asarray(values, dtype=float).ravel()
    except (TypeError, ValueError):
        raise ResponseMapError(f"{name} must be a non-empty, finite, strictly increasing axis {unit}, got "
                               f"{type(values).__name__} that does not hold numbers") from None
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
    pressures_gauge : (n_p,) Charge-pressure axis p0 [Pa gauge]; one entry for a map at a single pressure.
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


def _provenance(source: str, **extra: Any) -> dict[str, Any]:
    return {"source": source, "created": _time.strftime("%Y-%m-%dT%H:%M:%SZ", _time.gmtime()),
            "impactometer_version": __version__, **extra}


def _check_size(n_features: int, n_p: int, n_m: int, n_v: int) -> None:
    total = n_features * n_p * n_m * n_v
    if total > MAX_VALUES:
        raise ParameterError(f"a {n_m}×{n_v} map with {n_p} pressure(s) and {n_features} features holds {total} "
                             f"values ({total * 8 / 1e9:.2f} GB), above the limit of {MAX_VALUES}; expected a smaller "
                             "grid or one map per pressure")


def grid_size(n: int | tuple[int, int], field: str) -> tuple[int, int]:
    """N -> (N, N); (n_m, n_v) checked: integers >= 2."""
    sizes = (n, n) if isinstance(n, (int, np.integer)) else tuple(n) if isinstance(n, (tuple, list)) else (n,)
    if len(sizes) != 2 or any(isinstance(k, bool) or not isinstance(k, (int, np.integer)) or k < 2 for k in sizes):
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


#: scenarios per simulated batch of a map: enough to keep the CPU cores busy, or to fill a GPU
CPU_CHUNK, GPU_CHUNK = 2000, 65536


def _default_duration(features: str, params: Mapping[str, float], sample_rate: float) -> float:
    if "window" in params:
        return params["window"] + 2.0 / sample_rate
    return 0.08


def build_map_simulated(rig: Rig | str | None = None, pressure_gauge: float | Sequence[float] = 200e3, *,
                        masses: Sequence[float] | np.ndarray, velocities: Sequence[float] | np.ndarray,
                        features: str = "max-impulse",
                        feature_params: Mapping[str, float] | None = None, sample_rate: float = 50e3,
                        duration: float | None = None, refine_to: int | tuple[int, int] | None = None,
                        progress: Callable[[int, int], None] | None = None, chunk_size: int | None = None,
                        device: str | None = None) -> ResponseMap:
    """Response map by simulation of every grid node with the fast simulator (in parallel).

    Parameters
    ----------
    rig : Rig or str, optional
        The stand (default ``drop-stand``).
    pressure_gauge : float or sequence of float
        Charge pressure p0 [Pa gauge]; a sequence gives a map with a pressure axis.
    masses, velocities : sequence of float
        Grid axes M1 [kg] and V0 [m/s], increasing.
    features : str
        Feature set name (``max-impulse`` or ``peaks``).
    feature_params : mapping, optional
        Feature-set parameters, e.g. ``{"window": 0.02}`` [s].
    sample_rate : float
        Sample rate of the simulated force [Hz]; recordings identified with the map must have the same.
    duration : float, optional
        Simulated time after first contact [s] (default: what the feature set needs).
    refine_to : int or (int, int), optional
        Interpolate the simulated grid to this size afterwards (see :func:`refine`).
    progress : callable, optional
        ``progress(done, total)`` called with the simulated and the total number of grid nodes [-] before the first
        batch and after each one (e.g. to drive a progress bar).
    chunk_size : int, optional
        Scenarios simulated per parallel batch (default 2000 on the CPU, 65536 on a GPU).
    device : {"cpu", "gpu", "auto"}, optional
        Where the batches run (see :func:`impactometer.model.simulate_batch`).

    Returns
    -------
    ResponseMap
    """
    rig = get_rig(rig)
    fs = get_feature_set(features)
    params = fs.params(feature_params)
    masses = _axis(masses, "masses", "[kg]")
    velocities = _axis(velocities, "velocities", "[m/s]")
    pressures = _axis(np.atleast_1d(pressure_gauge), "pressure_gauge", "[Pa gauge]")
    _check_size(fs.size, pressures.size, masses.size, velocities.size)
    count = pressures.size * masses.size * velocities.size
    if count > MAX_SIMULATED:
        raise ParameterError(f"a {masses.size}×{velocities.size} grid at {pressures.size} pressure(s) needs {count} "
                             f"simulations, above the limit of {MAX_SIMULATED}; simulate a smaller grid and "
                             f"interpolate it (refine_to=, map build --refine {masses.size}x{velocities.size})")
    sample_rate = check_sample_rate(sample_rate, error=ParameterError)
    duration = _default_duration(features, params, sample_rate) if duration is None else float(duration)
    from ...model import simulate_batch
    from ...model.gpu import resolve_device

    device = resolve_device(device)
    if chunk_size is None:
        chunk_size = GPU_CHUNK if device == "gpu" else CPU_CHUNK
    grid_p, grid_m, grid_v = (a.ravel() for a in np.meshgrid(pressures, masses, velocities, indexing="ij"))
    values = np.empty((grid_m.size, fs.size))
    if progress is not None and not callable(progress):
        raise ParameterError(f"progress must be a callable progress(done, total) or None, got {progress!r}")
    if progress is not None:
        progress(0, grid_m.size)
    for start in range(0, grid_m.size, max(1, int(chunk_size))):
        part = slice(start, start + max(1, int(chunk_size)))
        batch = simulate_batch(grid_m[part], grid_v[part], grid_p[part], rig, duration=duration,
                               sample_rate=sample_rate, channels=("contact_force",), device=device)
        values[part], _ = extract_batch(batch.time, batch.data["contact_force"], features, params)
        if progress is not None:
            progress(min(part.stop, grid_m.size), grid_m.size)
    bad = np.flatnonzero(~np.all(np.isfinite(values) & (values > 0), axis=1))
    if bad.size:
        i = int(bad[0])
        raise ResponseMapError(f"feature set {features!r} found no features for {bad.size} scenario(s), first: "
                               f"mass={grid_m[i]:g} kg, velocity={grid_v[i]:g} m/s, pressure={grid_p[i]:g} Pa "
                               f"(duration {duration:g} s); expected two separated contact pulses: use a longer "
                               "duration, a smaller grid range or --features max-impulse")
    cube = values.T.reshape(fs.size, pressures.size, masses.size, velocities.size)
    rmap = ResponseMap(masses=masses, velocities=velocities, pressures_gauge=pressures, values=cube,
                       feature_set=features, feature_params=params, sample_rate=float(sample_rate),
                       rig=to_dict(rig), provenance=_provenance("simulation", base_grid=[masses.size, velocities.size],
                                                                duration_s=duration, integrator="fast", device=device))
    return rmap if refine_to is None else refine(rmap, refine_to)


def _pressure_groups(pressures: np.ndarray) -> list[np.ndarray]:
    order = np.argsort(pressures)
    groups, current = [], [order[0]]
    for i in order[1:]:
        ref = pressures[current[0]]
        if pressures[i] - ref <= max(PRESSURE_TOLERANCE[0], PRESSURE_TOLERANCE[1] * ref):
            current.append(i)
        else:
            groups.append(np.array(current))
            current = [i]
    groups.append(np.array(current))
    return groups


def _tensor_axes(m: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """Axes and node order when the points form a full tensor grid, else None."""
    um, iv_m = np.unique(np.round(m, 9), return_inverse=True)
    uv, iv_v = np.unique(np.round(v, 9), return_inverse=True)
    if um.size * uv.size != m.size or um.size < 2 or uv.size < 2:
        return None
    order = np.full((um.size, uv.size), -1)
    order[iv_m, iv_v] = np.arange(m.size)
    return (None if np.any(order < 0) else (um, uv, order))


def _interpolate_scattered(m, v, y, masses, velocities) -> tuple[np.ndarray, str]:
    """Features at scattered (m, v) -> values on the grid (n_features, n_m, n_v)."""
    tensor = _tensor_axes(m, v)
    if tensor is not None:
        um, uv, order = tensor
        bm, bv = spline_basis(um, masses), spline_basis(uv, velocities)
        return np.stack([bm @ y[order, k] @ bv.T for k in range(y.shape[1])]), "tensor-product cubic spline"
    lo = np.array([masses[0], velocities[0]])
    span = np.array([masses[-1] - masses[0], velocities[-1] - velocities[0]])
    points = (np.column_stack([m, v]) - lo) / span
    gm, gv = np.meshgrid(masses, velocities, indexing="ij")
    target = (np.column_stack([gm.ravel(), gv.ravel()]) - lo) / span
    rbf = RBFInterpolator(points, np.log(y), kernel="thin_plate_spline", degree=1)
    return np.exp(rbf(target)).T.reshape(y.shape[1], masses.size, velocities.size), "thin-plate RBF (log features)"


def build_map_from_recordings(recordings: Sequence[Recording], *, grid: int | tuple[int, int] = (50, 50),
                              features: str = "max-impulse", feature_params: Mapping[str, float] | None = None,
                              rig: Rig | str | None = None, pressure_gauge: float | None = None,
                              mass_range: tuple[float, float] | None = None,
                              velocity_range: tuple[float, float] | None = None,
                              source: str = "recordings") -> ResponseMap:
    """Response map from a calibration set: recordings with known mass and velocity, interpolated onto a grid.

    Recordings at the nodes of a full mass × velocity grid are interpolated with the tensor-product cubic spline;
    scattered ones with a thin-plate RBF on the logarithm of the features. Recordings at distinct charge pressures
    (metadata ``pressure_gauge_Pa``) give a map with a pressure axis, one layer per pressure.

    Parameters
    ----------
    recordings : sequence of Recording
        Each with metadata ``mass_kg`` and ``velocity_m_s`` (and ``pressure_gauge_Pa`` unless ``pressure_gauge``).
    grid : int or (int, int)
        Size of the map (masses × velocities).
    features, feature_params : see :func:`build_map_simulated`.
    rig : Rig or str, optional
        The stand (default: the preset named in the recordings' ``rig`` metadata, else ``drop-stand``); where the
        recordings state the fingerprint of their stand's parameters, it must be this stand's.
    pressure_gauge : float, optional
        Charge pressure [Pa gauge] of recordings that do not state it.
    mass_range, velocity_range : (float, float), optional
        Grid ranges [kg], [m/s] (default: the range of the recordings).
    source : str
        Where the recordings came from (kept in the provenance).
    """
    if isinstance(recordings, (str, bytes, Recording)) or not isinstance(recordings, Iterable):
        raise ResponseMapError(f"recordings must be a sequence of Recording, got {type(recordings).__name__}")
    recs = list(recordings)
    if any(not isinstance(r, Recording) for r in recs):
        raise ResponseMapError(f"recordings must be a sequence of Recording, got one of "
                               f"{type(next(r for r in recs if not isinstance(r, Recording))).__name__}")
    if len(recs) < 6:
        raise ResponseMapError(f"a map from recordings needs at least 6 recordings, got {len(recs)}")
    rates = sorted({float(r.sample_rate) for r in recs})
    if rates[-1] - rates[0] > 1e-6 * rates[-1]:
        raise ResponseMapError(f"recordings must share one sample rate, got {rates} Hz; resample them first")
    truth = np.empty((len(recs), 3))
    for i, r in enumerate(recs):
        row = [r.truth("mass_kg"), r.truth("velocity_m_s"), r.truth("pressure_gauge_Pa")]
        row[2] = pressure_gauge if row[2] is None else row[2]
        if None in row:
            missing = [k for k, x in zip(("mass_kg", "velocity_m_s", "pressure_gauge_Pa"), row, strict=False)
                       if x is None]
            raise ResponseMapError(f"{r.source}: metadata {missing} missing; expected the known truth of every "
                                   "calibration recording (metadata or manifest)")
        truth[i] = row
    prints = {str(r.metadata[STAND_KEY]) for r in recs if r.metadata.get(STAND_KEY) is not None}
    if len(prints) > 1:
        raise ResponseMapError(f"recordings come from stands with different parameters (fingerprints "
                               f"{sorted(prints)}); expected one stand")
    names = sorted({str(r.metadata["rig"]) for r in recs if isinstance(r.metadata.get("rig"), str)})
    if rig is None and len(names) == 1 and names[0] in PRESETS:
        rig = names[0]
    stand = get_rig(rig)
    for r in recs[:1] if prints else ():
        check_recorded_on(r, to_dict(stand), error=ResponseMapError,
                          hint="pass the stand they were recorded on (rig=, map build --rig FILE)")
    fs = get_feature_set(features)
    params = fs.params(feature_params)
    y = np.array([extract_features(*recording_signal(r), features, params)[0] for r in recs])
    n_m, n_v = grid_size(grid, "grid")
    m_low, m_high = mass_range or (truth[:, 0].min(), truth[:, 0].max())
    v_low, v_high = velocity_range or (truth[:, 1].min(), truth[:, 1].max())
    masses = _axis(np.linspace(m_low, m_high, n_m), "mass range", "[kg]")
    velocities = _axis(np.linspace(v_low, v_high, n_v), "velocity range", "[m/s]")
    groups = _pressure_groups(truth[:, 2])
    _check_size(fs.size, len(groups), masses.size, velocities.size)
    layers, methods = [], set()
    for g in groups:
        if g.size < 6:
            raise ResponseMapError(f"only {g.size} recording(s) at {truth[g[0], 2]:g} Pa; expected at least 6 per "
                                   "charge pressure")
        layer, method = _interpolate_scattered(truth[g, 0], truth[g, 1], y[g], masses, velocities)
        layers.append(layer)
        methods.add(method)
    return ResponseMap(masses=masses, velocities=velocities,
                       pressures_gauge=np.array([truth[g, 2].mean() for g in groups]),
                       values=np.stack(layers, axis=1), feature_set=features, feature_params=params,
                       sample_rate=rates[0], rig=to_dict(stand),
                       provenance=_provenance("recordings", recordings=len(recs), origin=source,
                                              interpolation=sorted(methods)))
