"""Fig. 9 analogue: identification error vs the integration window T of the `max-impulse` features.

    python scripts/map_window_study.py [--sizes 10,50,500] [--noise 0,0.01] [--features max-impulse]

10 seeded random impacts (masses 10-50 kg, drop heights 5-50 cm, 200 kPa), the paper's 10×10 simulated map per
window, refined to each size; test impacts noise-free or recorded with Gaussian noise (fraction of the channel RMS).
Prints a markdown table.
"""

from __future__ import annotations

import argparse

import numpy as np

from impactometer.studies.map_tables import window_table
from map_size_study import ERRORS, markdown


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", default="10,50,500")
    parser.add_argument("--noise", default="0,0.01")
    parser.add_argument("--features", default="max-impulse")
    args = parser.parse_args()
    rows = []
    for noise in (float(x) for x in args.noise.split(",")):
        rows += window_table(windows=tuple(np.arange(2, 42, 2) * 1e-3), sizes=[int(s) for s in args.sizes.split(",")],
                             noise=noise, features=args.features)
    for row in rows:
        row["window_ms"] = round(1e3 * row["window_s"], 3)
        row["noise"] = f"{100 * row['noise']:g} %"
    print(markdown(rows, ["window_ms", "noise", "size", "search", "n_cases", *ERRORS, "extrapolated"], ERRORS))


if __name__ == "__main__":
    main()
