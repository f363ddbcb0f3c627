"""Speed of the peak-to-peak identification: streaming throughput, time per push call, batch time per recording.

Streaming: an endless-stream stand-in of 20 s at 50 kHz holding one noisy impact (0.1 s) every 2 s, pushed in
chunks of 1, 64 and 4096 samples; printed as samples per second (the goal is >= 1e6 samples/s with 64-sample
chunks on one core). Two stands: the stiff stand (the rod bounces on the mass throughout) and the pad stand (a
rebound or two, then sustained contact, where the answer is updated each time the impact has doubled in length).
Per push call (64-sample chunks over the impacts): the distribution of wall times, all calls and the calls that
returned an answer (at 50 kHz a 64-sample chunk arrives every 1.28 ms; one sample every 20 µs). Batch: time per
0.15-s recording for both variants.

    python benchmarks/bench_identify.py [--record]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from impactometer.identify.peak_to_peak import identify_arrays
from impactometer.identify.peak_to_peak.streaming import StreamingIdentifier
from impactometer.model import simulate
from impactometer.rig import Scenario, get_rig
from recorded import recorded

FS = 50e3
STANDS = ("drop-stand-stiff", "drop-stand-pad")


def stream_signal(stand: str, seconds: float = 20.0, every: float = 2.0, seed: int = 0):
    r = simulate(Scenario(mass=30.0, velocity=2.0, pressure_gauge=2e5), get_rig(stand), duration=0.1,
                 sample_rate=FS)
    n = int(seconds * FS)
    rng = np.random.default_rng(seed)
    f = rng.normal(0.0, 0.02 * np.sqrt(np.mean(r.contact_force ** 2)), n)
    a = rng.normal(0.0, 0.02 * np.sqrt(np.mean(r.a2 ** 2)), n)
    starts = np.arange(int(0.5 * FS), n - r.time.size, int(every * FS))
    for s in starts:
        f[s:s + r.time.size] += r.contact_force
        a[s:s + r.time.size] += r.a2
    return f, a, starts.size


def throughput(f, a, chunk: int) -> tuple[float, int, np.ndarray, np.ndarray]:
    """Samples/s, impacts identified, wall time of every push call [s], whether it returned an answer."""
    ident = StreamingIdentifier(FS)
    ident.push(f[:chunk], a[:chunk])  # compile outside the timing
    ident = StreamingIdentifier(FS)
    times, answered = [], []
    t = time.perf_counter()
    for k in range(0, f.size, chunk):
        t0 = time.perf_counter()
        out = ident.push(f[k:k + chunk], a[k:k + chunk])
        times.append(time.perf_counter() - t0)
        answered.append(bool(out))
    ident.finish()
    return f.size / (time.perf_counter() - t), len(ident.completed), np.array(times), np.array(answered)


def distribution(times: np.ndarray) -> str:
    us = times * 1e6
    return (f"{us.size} calls: median {np.median(us):,.0f} µs, 99 % {np.percentile(us, 99):,.0f} µs, "
            f"max {us.max():,.0f} µs")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--record", action="store_true", help="keep the output in docs/results/ and the docs")
    args = parser.parse_args()
    with recorded("bench_identify", "Peak-to-peak identification: streaming and batch speed", args.record) as rec:
        measure(rec)


def measure(rec) -> None:
    for stand in STANDS:
        f, a, impacts = stream_signal(stand)
        print(f"\n{stand}: {f.size} samples ({f.size / FS:.0f} s at {FS / 1e3:.0f} kHz), {impacts} impacts")
        print("| chunk [samples] | streaming [samples/s] | impacts identified |")
        print("|---|---|---|")
        for chunk in (1, 64, 4096):
            rate, done, times, answered = throughput(f, a, chunk)
            print(f"| {chunk} | {rate:,.0f} | {done} |")
            if chunk == 64:
                calls = (times, answered)
            if chunk == 64 and stand in ("drop-stand", "drop-stand-pad"):  # the README's row: the default stand
                rec.headline(f"streaming, 64-sample chunks, {stand}", f"{rate / 1e6:.2f} M samples/s",
                             target=">= 1 M samples/s")
        times, answered = calls
        print(f"push calls, 64-sample chunks: all {distribution(times)}; returning an answer "
              f"{distribution(times[answered])}")
        start = int(0.5 * FS)
        window = slice(start - 2000, start + int(0.1 * FS))
        rate64, _, times, answered = throughput(f[window], a[window], 64)
        print(f"64-sample chunks over one impact (40 ms before, 100 ms after contact): {rate64:,.0f} samples/s; "
              f"push calls returning an answer: {distribution(times[answered])}")
        record = slice(start - 2500, start + int(0.1 * FS))
        for variant in ("robust", "paper"):
            identify_arrays(f[record], a[record], FS, variant=variant)
            t = time.perf_counter()
            reps = 10
            for _ in range(reps):
                identify_arrays(f[record], a[record], FS, variant=variant)
            print(f"batch {variant}: {(time.perf_counter() - t) / reps * 1e3:.1f} ms per "
                  f"{record.stop - record.start}-sample recording")


if __name__ == "__main__":
    main()
