"""The response-map analyses of the paper as tidy tables (lists of flat dicts, one row per configuration).

- :func:`map_size_table` -- Fig. 8: error and time per identification vs database size, brute vs fast;
- :func:`window_table` -- Fig. 9: error vs the integration window T of ``max-impulse``;
- :func:`recordings_table` -- a map built from noisy calibration recordings identifies held-back recordings.

Test impacts are simulated noise-free at the map's sample rate (``random``: seeded uniform masses 10-50 kg and drop
heights 5-50 cm at 200 kPa, as in the paper; ``grid125``: the paper's 125-case grid of
:func:`~impactometer.studies.base.paper_grid`, identified with one map per pressure). Errors are relative to the
truth; times are wall-clock per identification with the features already extracted.

Random draws follow the studies' seeding scheme (:func:`~impactometer.studies.base.hashed_seed`): they depend on
the root seed and the name of the draw only; the random test impacts are one draw, shared by Figs. 8 and 9.
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Sequence

import numpy as np

from ..errors import ParameterError
from ..identify.response_map import (
    build_map_from_recordings,
    build_map_simulated,
    identify_features,
    identify_recording,
    refine,
)
from ..identify.response_map.features import extract_batch, extract_features, recording_signal
from ..model import simulate_batch
from ..rig import Rig, get_rig
from ..sensors import record_batch
from .base import PAPER_HEIGHTS, PAPER_RANGES, hashed_seed, paper_grid

#: database sizes of the paper's Fig. 8
PAPER_SIZES = (10, 25, 50, 100, 250, 500, 1000, 2000, 2500, 3000)
CASES = ("random", "grid125")
#: name of the random test impacts' draw (one set, shared by Figs. 8 and 9)
TEST_DRAW = "response-map/test-impacts"
#: name of the draws of the map-from-recordings table
RECORDINGS_DRAW = "map-recordings"


def paper_axes(rig: Rig, n_m: int = 10, n_v: int = 10) -> tuple[np.ndarray, np.ndarray]:
    """Masses [kg] and velocities [m/s] (from uniform drop heights) of the paper's base grid."""
    heights = np.linspace(*PAPER_HEIGHTS, n_v)
    return np.linspace(*PAPER_RANGES["mass"], n_m), np.sqrt(2.0 * rig.gravity * heights)


def random_impacts(rig: Rig, n: int, seed) -> tuple[np.ndarray, np.ndarray]:
    """``n`` uniform masses [kg] and velocities [m/s] (from uniform drop heights) of the paper's ranges."""
    rng = np.random.default_rng(seed)
    masses = rng.uniform(*PAPER_RANGES["mass"], n)
    return masses, np.sqrt(2.0 * rig.gravity * rng.uniform(*PAPER_HEIGHTS, n))


def noise_seeds(seed: int, name: str, n: int) -> list[np.random.SeedSequence]:
    """Per-recording noise seeds of draw ``name`` (index 1: the draw's recordings, one stream each)."""
    return [hashed_seed(seed, name, 1, i) for i in range(n)]


def test_impacts(cases: str, rig: Rig, *, n: int = 10, seed: int = 0,
                 pressure_gauge: float = 200e3) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(masses [kg], velocities [m/s], pressures [Pa gauge]) of a named set of test impacts.

    ``random``: ``n`` impacts at ``pressure_gauge`` [Pa], drawn from the root ``seed`` and :data:`TEST_DRAW`;
    ``grid125``: the paper's 125-case grid.
    """
    if cases == "random":
        masses, velocities = random_impacts(rig, n, hashed_seed(seed, TEST_DRAW, 0))
        return masses, velocities, np.full(n, float(pressure_gauge))
    if cases == "grid125":
        grid = paper_grid(5, rig=rig)
        m, v, p = (np.array([c[k] for c in grid]) for k in ("mass", "velocity", "pressure_gauge"))
        return m, v, p
    raise ParameterError(f"cases must be one of {list(CASES)}, got {cases!r}")


def _features_of(masses, velocities, pressure, rig, features, params, sample_rate) -> np.ndarray:
    """Features of noise-free simulated impacts at one pressure [Pa gauge], one row per impact."""
    batch = simulate_batch(masses, velocities, pressure, rig, duration=0.08, sample_rate=sample_rate,
                           channels=("contact_force",))
    values, _ = extract_batch(batch.time, batch.data["contact_force"], features, params)
    return values


def _identify_all(rmap, ys, search, passes: int = 1):
    """Identify every feature row; (masses, velocities, extrapolated count, wall and CPU seconds per identification).

    The wall time is the best of ``passes`` passes over all rows (other processes only ever add to it); the CPU
    time is the mean over all passes.
    """
    identify_features(ys[0], rmap, search=search, allow_extrapolation=True)  # warm-up (caches, compilation)
    best = np.inf
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # out-of-map answers are counted instead
        cpu = time.process_time()
        for _ in range(passes):
            start = time.perf_counter()
            results = [identify_features(y, rmap, search=search, allow_extrapolation=True) for y in ys]
            best = min(best, time.perf_counter() - start)
        cpu = time.process_time() - cpu
    return (np.array([r.mass for r in results]), np.array([r.velocity for r in results]),
            sum(r.extrapolated for r in results), best / len(ys), cpu / (passes * len(ys)))


def _row(**values) -> dict:
    return {k: (float(v) if isinstance(v, (np.floating, float)) else v) for k, v in values.items()}


def _error_columns(m_id, v_id, m_true, v_true) -> dict:
    em, ev = np.abs(m_id / m_true - 1.0), np.abs(v_id / v_true - 1.0)
    return {"mass_error_mean": em.mean(), "mass_error_max": em.max(), "velocity_error_mean": ev.mean(),
            "velocity_error_max": ev.max()}


def map_size_table(*, rig: Rig | str | None = None, sizes: Sequence[int] = PAPER_SIZES,
                   feature_sets: Sequence[str] = ("peaks", "max-impulse"), cases: Sequence[str] = CASES,
                   searches: Sequence[str] = ("brute", "fast"), base_grid: int = 10, n_random: int = 10,
                   seed: int = 0, sample_rate: float = 50e3, feature_params: dict | None = None) -> list[dict]:
    """Fig. 8 analogue: identification error and time vs database size.

    A ``base_grid`` × ``base_grid`` map is simulated at each test pressure and refined by interpolation to every
    size (one map per pressure for ``grid125``). Rows: feature_set, cases, size, search, n_cases, mass/velocity
    error mean and max [-], time_per_identification_s (wall clock, best of 20 passes for fast and small maps),
    cpu_per_identification_s (process CPU time, mean), extrapolated (answers outside the map).
    """
    rig = get_rig(rig)
    rows = []
    for features in feature_sets:
        params = (feature_params or {}) if features == "max-impulse" else {}
        for case in cases:
            m_true, v_true, p_true = test_impacts(case, rig, n=n_random, seed=seed)
            acc: dict[tuple[int, str], list] = {}
            for pressure in np.unique(p_true):
                sel = p_true == pressure
                ys = _features_of(m_true[sel], v_true[sel], pressure, rig, features, params, sample_rate)
                base = build_map_simulated(rig, pressure, masses=paper_axes(rig, base_grid, base_grid)[0],
                                           velocities=paper_axes(rig, base_grid, base_grid)[1], features=features,
                                           feature_params=params, sample_rate=sample_rate)
                for size in sizes:
                    rmap = base if size == base_grid else refine(base, int(size))
                    for search in searches:
                        passes = 20 if search == "fast" or size <= 100 else 1
                        m_id, v_id, n_out, seconds, cpu = _identify_all(rmap, ys, search, passes)
                        entry = acc.setdefault((size, search), [[], [], 0, 0.0, 0.0])
                        entry[0].append(m_id / m_true[sel])
                        entry[1].append(v_id / v_true[sel])
                        entry[2] += n_out
                        entry[3] += seconds * sel.sum()
                        entry[4] += cpu * sel.sum()
                    del rmap
            for (size, search), (mr, vr, n_out, total, cpu) in acc.items():
                mr, vr = np.concatenate(mr), np.concatenate(vr)
                rows.append(_row(feature_set=features, cases=case, size=int(size), search=search, n_cases=mr.size,
                                 **_error_columns(mr, vr, 1.0, 1.0), time_per_identification_s=total / mr.size,
                                 cpu_per_identification_s=cpu / mr.size, extrapolated=int(n_out)))
    return rows


def window_table(*, rig: Rig | str | None = None, windows: Sequence[float] = tuple(np.arange(2, 32, 2) * 1e-3),
                 sizes: Sequence[int] = (50,), searches: Sequence[str] = ("brute", "fast"), base_grid: int = 10,
                 n_random: int = 10, seed: int = 0, sample_rate: float = 50e3, noise: float = 0.0,
                 features: str = "max-impulse") -> list[dict]:
    """Fig. 9 analogue: identification error vs the window T [s] of ``max-impulse`` (paper: 50×50 database).

    With ``noise`` > 0 the test impacts are recordings (:func:`~impactometer.sensors.record_batch`, Gaussian noise of
    that fraction of each channel's RMS, seeded) instead of noise-free simulations; the map is simulated.
    Rows: window_s, noise, size, search, n_cases, mass/velocity error mean and max [-], extrapolated.
    """
    rig = get_rig(rig)
    m_true, v_true, p_true = test_impacts("random", rig, n=n_random, seed=seed)
    masses, velocities = paper_axes(rig, base_grid, base_grid)
    recordings = None
    if noise > 0:
        recordings = record_batch(m_true, v_true, p_true[0], rig, sample_rate=sample_rate, duration=0.08,
                                  noise=noise, seeds=noise_seeds(seed, TEST_DRAW, m_true.size))
    rows = []
    for window in windows:
        params = {"window": float(window)}
        if recordings is None:
            ys = _features_of(m_true, v_true, p_true[0], rig, features, params, sample_rate)
        else:
            ys = np.array([extract_features(*recording_signal(r), features, params)[0] for r in recordings])
        base = build_map_simulated(rig, p_true[0], masses=masses, velocities=velocities, features=features,
                                   feature_params=params, sample_rate=sample_rate)
        for size in sizes:
            rmap = base if size == base_grid else refine(base, int(size))
            for search in searches:
                m_id, v_id, n_out, _, _ = _identify_all(rmap, ys, search)
                rows.append(_row(window_s=float(window), noise=float(noise), size=int(size), search=search,
                                 n_cases=m_true.size,
                                 **_error_columns(m_id, v_id, m_true, v_true), extrapolated=int(n_out)))
    return rows


def recordings_table(*, rig: Rig | str | None = None, grid: int = 10, map_grid: int = 50, noise: float = 0.01,
                     n_held_back: int = 20, feature_sets: Sequence[str] = ("peaks", "max-impulse"),
                     searches: Sequence[str] = ("brute", "fast"), pressure_gauge: float = 200e3, seed: int = 0,
                     sample_rate: float = 50e3, window: float = 0.02) -> list[dict]:
    """A map from ``grid`` × ``grid`` noisy calibration recordings identifies held-back noisy recordings.

    Calibration: the paper's grid (masses 10-50 kg × drop heights 5-50 cm) recorded with Gaussian noise ``noise``
    (fraction of each channel's RMS); held back: ``n_held_back`` recordings at seeded random masses and heights
    inside the grid (other noise seeds). The map is interpolated to ``map_grid`` × ``map_grid``.
    Rows: feature_set, search, map_grid, n_cases, mass/velocity error mean and max [-], extrapolated.
    """
    rig = get_rig(rig)
    masses, velocities = paper_axes(rig, grid, grid)
    mm, vv = (a.ravel() for a in np.meshgrid(masses, velocities, indexing="ij"))
    calibration = record_batch(mm, vv, pressure_gauge, rig, sample_rate=sample_rate, duration=0.08, noise=noise,
                               seeds=[hashed_seed(seed, RECORDINGS_DRAW, 2, i) for i in range(mm.size)])
    m_true, v_true = random_impacts(rig, n_held_back, hashed_seed(seed, RECORDINGS_DRAW, 0))
    held = record_batch(m_true, v_true, pressure_gauge, rig, sample_rate=sample_rate, duration=0.08, noise=noise,
                        seeds=noise_seeds(seed, RECORDINGS_DRAW, n_held_back))
    rows = []
    for features in feature_sets:
        params = {"window": window} if features == "max-impulse" else {}
        rmap = build_map_from_recordings(calibration, grid=map_grid, features=features, feature_params=params,
                                         rig=rig, source=f"record_batch noise={noise:g}")
        for search in searches:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", UserWarning)  # counted in the extrapolated column
                results = [identify_recording(r, rmap, search=search, allow_extrapolation=True) for r in held]
            m_id = np.array([r.mass for r in results])
            v_id = np.array([r.velocity for r in results])
            rows.append(_row(feature_set=features, search=search, map_grid=map_grid, n_cases=len(held),
                             **_error_columns(m_id, v_id, m_true, v_true),
                             extrapolated=sum(r.extrapolated for r in results)))
    return rows
