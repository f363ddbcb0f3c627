"""Fuzz the command line with the reliability corpus and print the acceptance table.

Runs every case of ``tests/reliability_cases.py`` (damaged recordings, stands, maps, options, output targets) in
this process and random bad arguments to the Python functions (``tests/reliability_api.py``), recordings with
awkward channel names written and read back, then the cases that need processes of their own: two studies started
together into one folder, two recordings written together into one file,
outputs into a read-only folder (as a user without the right to override permissions), and the peak memory of
``impactometer identify`` on a CSV of 10 million rows. Prints, per category, the cases tried and those unhandled
(traceback, several-line error), silently wrong (a wrong answer without a warning) or losing data, then every case
that was not handled.

Usage::

    PYTHONPATH=src python scripts/reliability_fuzz.py [--folder DIR] [--rows 1e7] [--no-memory] [--all]
"""

from __future__ import annotations

import argparse
import collections
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT / "tests"), str(ROOT / "benchmarks")]  # the fuzz corpus; benchmarks/recorded.py

from recorded import recorded  # noqa: E402
from reliability_api import calls, fuzz  # noqa: E402
from reliability_cases import Corpus, round_trips  # noqa: E402
from reliability_corpus import VERDICTS, Case, Outcome, judge, run  # noqa: E402

PYTHON = sys.executable
ENV = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT / "src"), os.environ.get("PYTHONPATH", "")]),
           MPLBACKEND="Agg")


def cli(argv: list[str], *, prefix: tuple[str, ...] = (), timeout: float = 300) -> Outcome:
    """Run ``impactometer ARGV`` in a process of its own."""
    try:
        done = subprocess.run([*prefix, PYTHON, "-m", "impactometer", *argv], capture_output=True, text=True, env=ENV,
                              timeout=timeout)
    except subprocess.TimeoutExpired:
        return Outcome(code=None, output="", crash=f"ran past {timeout:g} s")
    return Outcome(code=done.returncode, output=done.stdout + done.stderr, stdout=done.stdout)


def race(category: str, name: str, argv: list[str], seed_of) -> tuple[Case, str, str]:
    """Two runs of ``impactometer ARGV`` with seeds 1 and 2 started together: handled where one wrote (its seed is the
    one ``seed_of()`` finds) and the other was refused; data loss where both reported success."""
    runs = [subprocess.Popen([PYTHON, "-m", "impactometer", *argv, "--seed", str(seed)], stdout=subprocess.PIPE,
                             stderr=subprocess.STDOUT, text=True, env=ENV) for seed in (1, 2)]
    results = [(p.wait(timeout=600), p.stdout.read()) for p in runs]
    case = Case(category, name, argv)
    codes = [code for code, _ in results]
    seed = seed_of()
    if sorted(codes) == [0, 2] and seed == (1 if codes[0] == 0 else 2):
        return case, "handled", f"one run wrote seed {seed}, the other was refused"
    if codes == [0, 0]:
        return case, "data-loss", f"both runs reported success; the output holds seed {seed}"
    verdict = judge(case, Outcome(code=max(codes), output=results[-1][1]))[0]
    return case, verdict if verdict != "handled" else "data-loss", f"exit {sorted(codes)}, seed {seed}"


def concurrent_studies(folder: Path, attempts: int = 3) -> list[tuple[Case, str, str]]:
    """Two ``study peak-force`` runs with different seeds started together into one folder, ``attempts`` times."""
    out = []
    for k in range(attempts):
        target = folder / f"race{k}"
        shutil.rmtree(target, ignore_errors=True)
        argv = ["study", "peak-force", "--out", str(target), "--grid", "2", "--workers", "1"]
        out.append(race("concurrent studies", f"attempt {k + 1}", argv, lambda t=target: _seed(t)))
    return out


def concurrent_writers(folder: Path, attempts: int = 3) -> list[tuple[Case, str, str]]:
    """Two ``record --out x.csv`` runs with different seeds started together, ``attempts`` times: one writes, the
    other is refused (both reported success before, the later rename replacing the first file)."""
    out = []
    for k in range(attempts):
        target = folder / f"writers{k}.csv"
        for path in (target, target.with_suffix(".json")):
            path.unlink(missing_ok=True)
        argv = ["record", "--out", str(target), "--duration", "1s"]
        out.append(race("concurrent writers", f"attempt {k + 1}", argv, lambda t=target: _sidecar_seed(t)))
    return out


def _seed(folder: Path):
    try:
        return json.loads((folder / "peak-force" / "result.json").read_text())["options"]["seed"]
    except (OSError, ValueError, KeyError):
        return None


def _sidecar_seed(path: Path):
    try:
        return json.loads(path.with_suffix(".json").read_text()).get("seed")
    except (OSError, ValueError, AttributeError):
        return None


def read_only_outputs(corpus: Corpus) -> list[tuple[Case, str, str]]:
    """Every command that writes, into a folder it may not write to."""
    folder = corpus.path("read-only")
    folder.mkdir(exist_ok=True)
    os.chmod(folder, 0o555)
    prefix: tuple[str, ...] = ()
    if os.geteuid() == 0:  # root writes anywhere: drop the capability that lets it
        if not shutil.which("setpriv"):
            return []
        prefix = ("setpriv", "--bounding-set=-dac_override", "--inh-caps=-dac_override")
    base = str(corpus.base)
    commands = {"record": ["record", "--out", str(folder / "r.csv")],
                "simulate --out": ["simulate", "--out", str(folder / "s.h5")],
                "simulate --plot": ["simulate", "--plot", str(folder / "s.png")],
                "identify --plot": ["identify", base, "--plot", str(folder / "i.png")],
                "inspect --plot": ["inspect", base, "--plot", str(folder / "i.png")],
                "absorb --plot": ["absorb", "--plot", str(folder / "a.png")],
                "map build": ["map", "build", "--out", str(folder / "m.h5"), "--grid", "3"],
                "demo": ["demo", "--out", str(folder / "demo"), "--no-absorb"],
                "study": ["study", "peak-force", "--out", str(folder / "study"), "--grid", "2"],
                "study report": ["study", "report", "--out", str(folder)]}
    out = []
    for label, argv in commands.items():
        case = Case("output targets", f"read-only folder: {label}", argv)
        verdict, reason = judge(case, cli(argv, prefix=prefix))
        out.append((case, verdict, reason))
    return out


def slow_cases(cases: list[Case]) -> list[tuple[Case, str, str]]:
    """Cases that must end within a bound of time (a runaway integrator), each in a process of its own."""
    out = []
    for case in (c for c in cases if c.slow):
        start = time.perf_counter()
        outcome = cli(case.argv, timeout=90)
        verdict, reason = judge(case, outcome)
        out.append((case, verdict, f"{reason} ({time.perf_counter() - start:.1f} s)"))
    return out


def peak_memory(corpus: Corpus, rows: int) -> tuple[float, float, Path]:
    """Peak resident memory [MB] and wall time [s] of ``impactometer identify`` on a CSV of ``rows`` rows."""
    import numpy as np

    path = corpus.path(f"rows{rows:.0e}.csv")
    if not path.exists():
        rng = np.random.default_rng(0)
        f0, a0, fs, t0 = corpus.f, corpus.a, corpus.rec.sample_rate, corpus.rec.start_time
        with open(path, "w") as handle:
            handle.write("time [s],contact_force [N],piston_acceleration [m/s^2]\n")
            for start in range(0, rows, 1_000_000):
                i = np.arange(start, min(start + 1_000_000, rows))
                inside = i < f0.size
                f = np.where(inside, f0[np.minimum(i, f0.size - 1)], rng.normal(0.0, 20.0, i.size))
                a = np.where(inside, a0[np.minimum(i, a0.size - 1)], rng.normal(0.0, 5.0, i.size))
                np.savetxt(handle, np.column_stack([t0 + i / fs, f, a]), fmt=["%.9f", "%.4f", "%.4f"], delimiter=",")
    probe = ("import resource, subprocess, sys, time; t = time.perf_counter(); "
             "subprocess.run(sys.argv[1:], stdout=subprocess.DEVNULL, check=True); "
             "print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss, time.perf_counter() - t)")
    done = subprocess.run([PYTHON, "-c", probe, PYTHON, "-m", "impactometer", "identify", str(path), "--json"],
                          capture_output=True, text=True, env=ENV, check=True)
    kilobytes, seconds = done.stdout.split()
    return float(kilobytes) / 1024.0, float(seconds), path


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--folder", type=Path, help="Where the corpus is built (default: a temporary folder).")
    parser.add_argument("--rows", type=float, default=1e7, help="Rows of the CSV whose identification is measured.")
    parser.add_argument("--no-memory", action="store_true", help="Skip the memory measurement.")
    parser.add_argument("--all", action="store_true", help="List every case with its verdict.")
    parser.add_argument("--api-calls", type=int, default=4000, help="Random calls of the Python functions.")
    parser.add_argument("--record", action="store_true", help="keep the output in docs/results/ and the docs")
    options = parser.parse_args(argv)
    with recorded("reliability_fuzz", "Reliability: the fuzz corpus and random calls of the Python functions",
                  options.record, argv=None if argv is None else [sys.argv[0], *argv]):
        return measure(options)


def measure(options) -> int:
    folder = options.folder or Path(tempfile.mkdtemp(prefix="impactometer-fuzz-"))
    corpus = Corpus(folder)
    results: list[tuple[Case, str, str]] = []
    outcomes: dict[str, Outcome] = {}
    cases = corpus.cases()
    for case in cases:
        if case.slow:
            continue
        outcome = run(case)
        outcomes[case.name] = outcome
        verdict, reason = judge(case, outcome, outcomes.get(case.same_as) if case.same_as else None)
        results.append((case, verdict, reason))
    results += round_trips(folder) + slow_cases(cases) + concurrent_studies(folder) + concurrent_writers(folder)
    results += read_only_outputs(corpus)
    made, failures = fuzz(calls(corpus.rec, corpus.base, corpus.map, folder), options.api_calls, seed=0)
    for k in range(made):  # one row per call: the distinct failures count once each
        case = Case("Python API", f"call {k}", [])
        results.append((case, "unhandled", failures[k]) if k < len(failures) else (case, "handled", "ok"))
    table: dict[str, collections.Counter] = collections.defaultdict(collections.Counter)
    for case, verdict, _ in results:
        table[case.category]["tried"] += 1
        table[case.category][verdict] += 1
    print("| category | tried | unhandled | silent-wrong | data loss | over-refused |")
    print("|---|---:|---:|---:|---:|---:|")
    total = collections.Counter()
    for category, counts in table.items():
        total.update(counts)
        print(f"| {category} | {counts['tried']} | {counts['unhandled']} | {counts['silent-wrong']} | "
              f"{counts['data-loss']} | {counts['over-refused']} |")
    print(f"| total | {total['tried']} | {total['unhandled']} | {total['silent-wrong']} | {total['data-loss']} | "
          f"{total['over-refused']} |")
    shown = [r for r in results if r[1] != "handled" or (options.all and r[0].category != "Python API")]
    for case, verdict, reason in shown:
        print(f"  [{verdict}] {case.category} / {case.name}: {reason}")
    if not options.no_memory:
        rows = int(options.rows)
        megabytes, seconds, path = peak_memory(corpus, rows)
        print(f"peak memory of 'impactometer identify' on a CSV of {rows} rows ({path.stat().st_size / 1e6:.0f} MB): "
              f"{megabytes:.0f} MB, {seconds:.1f} s")
    os.chmod(corpus.path("read-only"), 0o755)
    bad = sum(total[v] for v in VERDICTS if v not in ("handled", "over-refused"))
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
