"""Response-map identification: the continuous `fast` search against the paper's `brute` search, in one process.

The paper's 10×10 map (masses 10-50 kg × drop heights 5-50 cm, 200 kPa) is refined to N×N and 10 seeded random
impacts are identified from their already extracted features. Times are per identification: wall clock (best of
several repeats) and process CPU time; the ratio is brute / fast.

    python benchmarks/bench_response_map.py [--sizes 500,3000] [--features max-impulse,peaks]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from impactometer.identify.response_map import identify_features, refine
from impactometer.identify.response_map.build import build_map_simulated
from impactometer.rig import get_rig
from impactometer.studies.map_tables import _features_of, paper_axes, test_impacts
from recorded import recorded


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
    parser.add_argument("--record", action="store_true", help="keep the output in docs/results/ and the docs")
    args = parser.parse_args()
    with recorded("bench_response_map", "Response map: fast against brute search", args.record) as rec:
        measure(args, rec)


def measure(args, rec) -> None:
    rig = get_rig()
    masses, velocities = paper_axes(rig)
    m_true, v_true, p_true = test_impacts("random", rig, n=10, seed=0)
    print(f"10 random impacts on {rig.name}, maps at {p_true[0] / 1e3:g} kPa refined from the paper's 10×10 grid; "
          f"wall and CPU time per identification (features extracted), mean relative errors\n")
    print("| features | map size | search | wall / id [µs] | CPU / id [µs] | mass error | velocity error | "
          "brute / fast (wall) |")
    print("|---|---:|---|---:|---:|---:|---:|---:|")
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
                ratio = f"{walls['brute'] / walls['fast']:,.0f}" if search == "brute" else ""
                print(f"| {features} | {size} | {search} | {wall * 1e6:,.1f} | {cpu * 1e6:,.1f} | {em:.3%} | "
                      f"{ev:.3%} | {ratio} |")
            if size == max(int(s) for s in args.sizes.split(",")) and features == "impulse-profile":
                rec.headline(f"response map {size}×{size}, {features}: fast search per identification",
                             f"{walls['fast'] * 1e6:.0f} µs ({walls['brute'] / walls['fast']:,.0f}× brute)",
                             target="paper: > 350 ms")
            del rmap

if __name__ == "__main__":
    main()
