"""Building a response map (paper section 5): by simulation with the fast simulator, or from a calibration set of
recordings with known mass and velocity.
"""

from __future__ import annotations

import time as _time
from collections.abc import Callable, Iterable, Mapping, Sequence
from typing import Any

import numpy as np
from scipy.interpolate import RBFInterpolator

from ... import __version__
from ...errors import ParameterError, ResponseMapError
from ...recording import Recording, check_sample_rate
from ...rig import PRESETS, STAND_KEY, Rig, check_recorded_on, get_rig, to_dict
from .database import ResponseMap, _axis, _check_size, grid_size, refine, spline_basis
from .features import extract_batch, extract_features, get_feature_set, recording_signal

#: most impacts a map build simulates (a 500×500 grid; about a thousand a second on two cores): larger maps come
#: from interpolating a simulated one (:func:`~.database.refine`)
MAX_SIMULATED = 250_000
#: two charge pressures closer than max(absolute, relative·p) are the same [Pa], [-]
PRESSURE_TOLERANCE = (1e3, 0.01)


def _provenance(source: str, **extra: Any) -> dict[str, Any]:
    return {"source": source, "created": _time.strftime("%Y-%m-%dT%H:%M:%SZ", _time.gmtime()),
            "impactometer_version": __version__, **extra}


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
        Charge pressure [Pa gauge]; a sequence gives a map with a pressure axis.
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
