"""Response-map identification: the continuous `fast` search against the paper's `brute` search, in one process.

The paper's 10×10 map (masses 10-50 kg × drop heights 5-50 cm, 200 kPa) is refined to N×N and 10 seeded random
impacts are identified from their already extracted features. Times are per identification: wall clock (best of
several repeats) and process CPU time; the ratio is brute / fast.

    python benchmarks/bench_response_map.py [--sizes 500,3000] [--features max-impulse,peaks]
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

from impactometer.identify.response_map import identify_features, refine
from impactometer.identify.response_map.build import build_map_simulated
from impactometer.rig import get_rig
from impactometer.studies.map_tables import _features_of, paper_axes, test_impacts


def per_call(function, items, repeats: int) -> tuple[float, float]:
    """Best wall time and mean CPU time per call of ``function(item)`` over ``items`` [s]."""
    best = np.inf
    cpu_start = time.process_time()
    for _ in range(repeats):
        start = time.perf_counter()
        for item in items:
            function(item)
        best = min(best, (time.perf_counter() - start) / len(items))
    return best, (time.process_time() - cpu_start) / (repeats * len(items))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", default="10,100,500,1000,3000")
    parser.add_argument("--features", default="max-impulse,peaks,impulse-profile")
    args = parser.parse_args()
    rig = get_rig()
    masses, velocities = paper_axes(rig)
    m_true, v_true, p_true = test_impacts("random", rig, n=10, seed=0)
    print(f"load average at start: {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores")
    header = (f"{'features':16s} {'size':>5s} {'search':6s} {'wall/id':>11s} {'cpu/id':>11s} {'mass err':>9s} "
              f"{'vel err':>8s} {'brute/fast':>11s}")
    print(header)
    print("-" * len(header))
    for features in args.features.split(","):
        base = build_map_simulated(rig, p_true[0], masses=masses, velocities=velocities, features=features)
        ys = _features_of(m_true, v_true, p_true[0], rig, features, base.feature_params, base.sample_rate)
        for size in (int(s) for s in args.sizes.split(",")):
            rmap = base if size == 10 else refine(base, size)
            walls = {}
            for search in ("fast", "brute"):
                identify_features(ys[0], rmap, search=search)  # warm-up: compilation, cached surfaces
                repeats = 200 if search == "fast" else (3 if size >= 1000 else 20)
                wall, cpu = per_call(lambda y, rmap=rmap, search=search: identify_features(y, rmap, search=search), ys,
                                      repeats)
                results = [identify_features(y, rmap, search=search) for y in ys]
                em = np.mean([abs(r.mass / m - 1) for r, m in zip(results, m_true, strict=False)])
                ev = np.mean([abs(r.velocity / v - 1) for r, v in zip(results, v_true, strict=False)])
                walls[search] = wall
                ratio = f"{walls['brute'] / walls['fast']:11.0f}" if search == "brute" else ""
                print(f"{features:16s} {size:5d} {search:6s} {wall * 1e6:9.1f}µs {cpu * 1e6:9.1f}µs "
                      f"{em * 100:8.3f}% {ev * 100:7.3f}% {ratio}")
            del rmap
    print(f"load average at end: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
