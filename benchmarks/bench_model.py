"""Speed of the model-based identification beside the robust peak-to-peak one, in one process, on one core.

Records: ``--records`` scenarios spread over the paper's grid (M1 10-50 kg × V0 1-3 m/s × p0 20-400 kPa) on the
pad stand (``drop-stand``), 50 ms after first contact + 20 ms pre-trigger (a 70 ms record) at 50 kHz, 5 % noise.
For each record, in turn: the robust answer (``peak-to-peak/robust`` with its early answer, as ``identify`` gives
it), the model's answer with every contact law fitted and the smallest BIC kept (the default), and the model's
answer with the stand's own law only (``contact="hysteretic"``). Printed: median and 90th percentile of the wall
time per record (the least of ``--repeat`` runs, as other processes share the cores) and the ratio to the robust
method. The compiled code runs on one thread (numba); the first
record of each method is run once beforehand (compilation and caches).

    python benchmarks/bench_model.py [--records 20] [--record]
"""

from __future__ import annotations

import argparse
import time

import numba
import numpy as np

from impactometer.identify.model_fit import identify as identify_model
from impactometer.identify.peak_to_peak import identify as identify_robust
from impactometer.sensors import record_batch
from impactometer.studies.base import StudyOptions, scenario_grid
from recorded import recorded

METHODS = {
    "peak-to-peak/robust": lambda rec: identify_robust(rec),
    "model (3 laws, BIC)": lambda rec: identify_model(rec),
    "model (hysteretic only)": lambda rec: identify_model(rec, contact="hysteretic"),
}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--records", type=int, default=20, help="records spread over the paper's grid")
    ap.add_argument("--repeat", type=int, default=3, help="runs per record and method; the least counts")
    ap.add_argument("--record", action="store_true", help="keep the output in docs/results/ and the docs")
    args = ap.parse_args()
    with recorded("bench_model", "Model-based identification: time per record beside the robust method",
                  args.record) as rec:
        measure(args, rec)


def measure(args, rec) -> None:
    numba.set_num_threads(1)
    grid = scenario_grid(StudyOptions(grid=5))
    cases = [grid[int(i)] for i in np.linspace(0, len(grid) - 1, args.records).round()]
    recordings = record_batch([c["mass"] for c in cases], [c["velocity"] for c in cases],
                              [c["pressure_gauge"] for c in cases], "drop-stand", sample_rate=50e3, duration=0.05,
                              pre_trigger=0.02, noise=0.05, seed=2024)
    times: dict[str, list[float]] = {name: [] for name in METHODS}
    for method in METHODS.values():
        method(recordings[0])
    for recording in recordings:
        for name, method in METHODS.items():
            best = float("inf")
            for _ in range(args.repeat):  # the least of a few runs: other processes on the cores only add time
                start = time.perf_counter()
                try:
                    method(recording)
                except Exception as exc:  # noqa: BLE001 - a refusal still took its time; name it
                    print(f"{name}: {type(exc).__name__}: {exc}")
                best = min(best, time.perf_counter() - start)
            times[name].append(best)
    print(f"{len(recordings)} records of 70 ms (50 ms + 20 ms pre-trigger) at 50 kHz, pad stand, 5 % noise; "
          f"one compiled thread; least of {args.repeat} runs per record\n")
    print("| method | median [ms] | 90th percentile [ms] | median / robust |")
    print("|---|---|---|---|")
    base = float(np.median(times["peak-to-peak/robust"]))
    for name, values in times.items():
        median = float(np.median(values))
        print(f"| {name} | {median * 1e3:.0f} | {np.percentile(values, 90) * 1e3:.0f} | {median / base:.2f} |")
    rec.headline("model fit of a 70 ms pad record, median time per record (3 laws / one law), one core",
                 f"{np.median(times['model (3 laws, BIC)']) * 1e3:.0f} ms / "
                 f"{np.median(times['model (hysteretic only)']) * 1e3:.0f} ms", target="100 ms")


if __name__ == "__main__":
    main()
