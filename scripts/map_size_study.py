"""Fig. 8 analogue (error and time vs database size, brute vs fast) and the map-from-recordings check.

    python scripts/map_size_study.py                 # Fig. 8: both test sets, sizes 10..3000, all feature sets
    python scripts/map_size_study.py --recordings    # map from 10×10 recordings at 1 % noise, held-back recordings
    python scripts/map_size_study.py --sizes 3000 --cases random --n-random 100   # brute vs fast, more impacts

Prints markdown tables (the ones quoted in docs/response_map.md).
"""

from __future__ import annotations

import argparse
import os
import time

from impactometer.studies.map_tables import PAPER_SIZES, map_size_table, recordings_table


def markdown(rows: list[dict], columns: list[str], percent: tuple[str, ...] = (), micro: tuple[str, ...] = ()) -> str:
    """Rows as a markdown table; ``percent`` columns ×100 with %, ``micro`` columns in µs."""
    lines = ["| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]
    for row in rows:
        cells = []
        for c in columns:
            value = row[c]
            if c in percent:
                cells.append(f"{100 * value:.3g} %")
            elif c in micro:
                cells.append(f"{1e6 * value:.3g} µs")
            else:
                cells.append(str(value))
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


ERRORS = ("mass_error_mean", "mass_error_max", "velocity_error_mean", "velocity_error_max")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--recordings", action="store_true", help="run the map-from-recordings check instead")
    parser.add_argument("--sizes", default=",".join(str(s) for s in PAPER_SIZES))
    parser.add_argument("--features", default="peaks,max-impulse,impulse-profile")
    parser.add_argument("--cases", default="random,grid125")
    parser.add_argument("--n-random", type=int, default=10, help="number of random test impacts")
    args = parser.parse_args()
    start = time.perf_counter()
    print(f"load average at start: {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores\n")
    if args.recordings:
        rows = recordings_table(feature_sets=tuple(args.features.split(",")))
        print(markdown(rows, ["feature_set", "search", "map_grid", "n_cases", *ERRORS, "extrapolated"], ERRORS))
    else:
        rows = map_size_table(sizes=[int(s) for s in args.sizes.split(",")],
                              feature_sets=tuple(args.features.split(",")), cases=tuple(args.cases.split(",")),
                              n_random=args.n_random)
        print(markdown(rows, ["feature_set", "cases", "size", "search", "n_cases", *ERRORS,
                              "time_per_identification_s", "cpu_per_identification_s", "extrapolated"], ERRORS,
                       ("time_per_identification_s", "cpu_per_identification_s")))
    print(f"\nload average at end: {os.getloadavg()[0]:.2f}; {time.perf_counter() - start:.0f} s")


if __name__ == "__main__":
    main()
