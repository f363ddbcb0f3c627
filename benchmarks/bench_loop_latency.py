"""Processor time of the absorber loop's model stream beside the latency budget the loop states.

The closed loop (``impactometer absorb``) acts on the identification's answer a stated latency L after the last
sample it used (``--latency``, default 1 ms: a compiled real-time core); it never counts this machine's processor
time, so that the same arguments give the same numbers anywhere. This benchmark measures what this implementation
takes: the records the loop reads (``--records`` impacts spread over the absorption study's grid, the absorber's
stand ``drop-stand``, 2 % noise, 50 kHz, the loop's identification window and pre-trigger) are pushed through the
loop's own stream (:func:`impactometer.control.identified.model_answers`, chunks of ``STREAM_CHUNK`` samples, one
compiled thread, one BLAS thread) and the processor time of each push is taken (``time.thread_time``, the least of
``--repeat`` runs, as other processes share the cores; the first record is run once beforehand: compilation and
caches). Printed: median, 90th percentile and largest processor time of the pushes that made a stream update and of
the push that gave the answer, beside L and the DAQ block's own duration.

    python benchmarks/bench_loop_latency.py [--records 20] [--repeat 3] [--record]
"""

from __future__ import annotations

import os

for _name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):  # one core, before numpy loads BLAS
    os.environ.setdefault(_name, "1")

import argparse  # noqa: E402 - after the thread settings
import time  # noqa: E402

import numpy as np  # noqa: E402

from impactometer.control.identified import (  # noqa: E402
    IDENTIFICATION_WINDOW,
    LATENCY,
    PRE_TRIGGER,
    STREAM_CHUNK,
    model_answers,
)
from impactometer.rig import ABSORPTION_RIG, Scenario, get_rig  # noqa: E402
from impactometer.sensors import record  # noqa: E402
from impactometer.studies.base import StudyOptions, scenario_grid  # noqa: E402
from recorded import recorded  # noqa: E402

SAMPLE_RATE = 50e3
NOISE = 0.02


def timed_pushes(recording, rig, pressure: float) -> list[tuple[float, int, bool]]:
    """(processor time [s], updates, whether it gave the answer) of each push of the loop's stream."""
    out = []
    pushes = model_answers(recording, rig, pressure_gauge=pressure, latency=LATENCY)
    while True:
        began = time.thread_time()
        try:
            _, updates, answer = next(pushes)
        except StopIteration:
            return out
        out.append((time.thread_time() - began, updates, answer is not None))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--records", type=int, default=20, help="impacts spread over the absorption grid")
    ap.add_argument("--repeat", type=int, default=3, help="runs per record; the least time of each push counts")
    ap.add_argument("--record", action="store_true", help="keep the output in docs/results/ and the docs")
    args = ap.parse_args()
    with recorded("bench_loop_latency", "Absorber loop: processor time of the model stream beside the stated latency",
                  args.record) as rec:
        measure(args, rec)


def measure(args, rec) -> None:
    rig = get_rig(ABSORPTION_RIG)
    grid = scenario_grid(StudyOptions(grid=5))
    cases = [grid[int(i)] for i in np.linspace(0, len(grid) - 1, args.records).round()]
    recordings = [(record(Scenario(mass=c["mass"], velocity=c["velocity"], pressure_gauge=c["pressure_gauge"]), rig,
                          sample_rate=SAMPLE_RATE, duration=IDENTIFICATION_WINDOW, noise=NOISE, seed=k,
                          pre_trigger=PRE_TRIGGER), c["pressure_gauge"]) for k, c in enumerate(cases)]
    timed_pushes(recordings[0][0], rig, recordings[0][1])  # compilation and caches
    updates, answers, totals = [], [], []
    answered = 0
    for recording, pressure in recordings:
        runs = [timed_pushes(recording, rig, pressure) for _ in range(args.repeat)]
        least = np.min([[took for took, _, _ in run] for run in runs], axis=0)  # the same pushes each run
        made = np.array([n > 0 for _, n, _ in runs[0]])
        gave = np.array([a for _, _, a in runs[0]])
        updates += list(least[made])
        if gave.any():
            answered += 1
            answers.append(float(least[gave][0]))
            totals.append(float(least[made].sum()))
    u, a, s = np.array(updates), np.array(answers), np.array(totals)
    block = STREAM_CHUNK / SAMPLE_RATE
    print(f"{len(recordings)} records of the absorption grid ({ABSORPTION_RIG}, {NOISE:.0%} noise, "
          f"{SAMPLE_RATE / 1e3:g} kHz), the loop's model stream in chunks of {STREAM_CHUNK} samples "
          f"({block * 1e3:.2f} ms of record); one compiled thread; least of {args.repeat} runs per push; "
          f"{answered} of {len(recordings)} answered\n")
    print("| push | pushes | median [ms] | 90th percentile [ms] | max [ms] | median / L |")
    print("|---|---|---|---|---|---|")
    for label, v in (("with a stream update", u), ("that gave the answer", a),
                     ("all updates up to the answer, summed", s)):
        print(f"| {label} | {v.size} | {np.median(v) * 1e3:.2f} | {np.percentile(v, 90) * 1e3:.2f} | "
              f"{v.max() * 1e3:.2f} | {np.median(v) / LATENCY:.2f} |")
    print(f"\nStated latency L = {LATENCY * 1e3:g} ms (the loop's default: from the last sample an answer used to "
          f"the valve command, for a compiled real-time core); the simulation never counts the times above.")
    rec.headline("absorber loop's model stream: processor time per update, median / 90th percentile, one core",
                 f"{np.median(u) * 1e3:.2f} ms / {np.percentile(u, 90) * 1e3:.2f} ms",
                 target=f"stated latency {LATENCY * 1e3:g} ms")


if __name__ == "__main__":
    main()
