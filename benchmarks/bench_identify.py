"""Speed of the peak-to-peak identification: streaming throughput and batch time per recording.

Streaming: an endless-stream stand-in of 20 s at 50 kHz holding one noisy impact (0.1 s of bouncing) every 2 s,
pushed in chunks of 1, 64 and 4096 samples; printed as samples per second (the goal is >= 1e6 samples/s with
64-sample chunks on one core) and as the ratio against the obvious alternative, re-running the batch function on
the buffered impact after every chunk. Batch: time per 0.15-s recording for both variants.

    python benchmarks/bench_identify.py
"""

from __future__ import annotations

import contextlib
import time

import numpy as np

from impactometer.identify.peak_to_peak import identify_arrays
from impactometer.identify.streaming import StreamingIdentifier
from impactometer.model import simulate
from impactometer.rig import Scenario

FS = 50e3


def stream_signal(seconds: float = 20.0, every: float = 2.0, seed: int = 0):
    r = simulate(Scenario(mass=30.0, velocity=2.0, pressure_gauge=2e5), duration=0.1, sample_rate=FS)
    n = int(seconds * FS)
    rng = np.random.default_rng(seed)
    f = rng.normal(0.0, 0.02 * np.sqrt(np.mean(r.contact_force ** 2)), n)
    a = rng.normal(0.0, 0.02 * np.sqrt(np.mean(r.a2 ** 2)), n)
    starts = np.arange(int(0.5 * FS), n - r.time.size, int(every * FS))
    for s in starts:
        f[s:s + r.time.size] += r.contact_force
        a[s:s + r.time.size] += r.a2
    return f, a, starts.size


def throughput(f, a, chunk: int) -> tuple[float, int]:
    ident = StreamingIdentifier(FS)
    ident.push(f[:chunk], a[:chunk])  # compile outside the timing
    ident = StreamingIdentifier(FS)
    t = time.perf_counter()
    for k in range(0, f.size, chunk):
        ident.push(f[k:k + chunk], a[k:k + chunk])
    ident.finish()
    return f.size / (time.perf_counter() - t), len(ident.completed)


def naive(f, a, chunk: int, impact_start: int, impact_len: int) -> float:
    """Samples/s of re-running the batch function on the buffer after every chunk of one impact."""
    lo = impact_start - 2000
    t = time.perf_counter()
    count = 0
    for stop in range(lo + chunk, impact_start + impact_len, chunk):
        # too little data yet: the naive loop just tries again
        with contextlib.suppress(Exception):
            identify_arrays(f[lo:stop], a[lo:stop], FS)
        count += chunk
    return count / (time.perf_counter() - t)


def main() -> None:
    f, a, impacts = stream_signal()
    print(f"stream: {f.size} samples ({f.size / FS:.0f} s at {FS / 1e3:.0f} kHz), {impacts} impacts")
    print("| chunk [samples] | streaming [samples/s] | impacts identified |")
    print("|---|---|---|")
    for chunk in (1, 64, 4096):
        rate, done = throughput(f, a, chunk)
        print(f"| {chunk} | {rate:,.0f} | {done} |")
    start = int(0.5 * FS)
    window = slice(start - 2000, start + int(0.1 * FS))
    rate64, _ = throughput(f[window], a[window], 64)
    slow = naive(f, a, 64, start, int(0.1 * FS))
    print(f"\n64-sample chunks over one impact (40 ms before, 100 ms after contact): streaming {rate64:,.0f} "
          f"samples/s vs re-running the batch function after every chunk {slow:,.0f} samples/s "
          f"(x{rate64 / slow:,.0f})")
    rec = slice(start - 2500, start + int(0.1 * FS))
    for variant in ("robust", "paper"):
        identify_arrays(f[rec], a[rec], FS, variant=variant)
        t = time.perf_counter()
        reps = 20
        for _ in range(reps):
            identify_arrays(f[rec], a[rec], FS, variant=variant)
        print(f"batch {variant}: {(time.perf_counter() - t) / reps * 1e3:.1f} ms per {rec.stop - rec.start}-sample "
              "recording")


if __name__ == "__main__":
    main()
