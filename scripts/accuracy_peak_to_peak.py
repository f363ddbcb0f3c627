"""Acceptance table of the peak-to-peak identification: stands × contact laws × noise, over the paper's grid.

Grid: the 125 cases of the paper's ranges (M1 10-50 kg × V0 1-3 m/s × p0 20-400 kPa, 5 values each; the grid of
:func:`impactometer.studies.base.scenario_grid`), recorded at 50 kHz by the sensor model (causal anti-alias
filter), ``--duration`` after first contact plus ``--pre-trigger``, Gaussian noise of each channel's RMS on force
and acceleration (``--seeds`` realisations; one run without noise), recorded and seeded as the studies do
(:func:`impactometer.studies.identification.clean_recordings`, ``with_noise`` and per-case
:func:`impactometer.studies.base.case_seed`). For every stand and contact law it prints
mean and max relative errors of mass and velocity of ``paper``, ``robust early`` and ``robust`` final, when the
answer is available (median) and how long after the second force peak t11 (median / max), the ±2σ coverage
(truth within two stated standard errors, mass / velocity) and the number of refusals (IdentificationError) and
of missing early answers.

    python scripts/accuracy_peak_to_peak.py                       # acceptance: 50 ms + 20 ms, 5 %, 5 seeds
    python scripts/accuracy_peak_to_peak.py --seeds 1 --subset 25  # a quick look (25 cases, one seed)
    python scripts/accuracy_peak_to_peak.py --duration 0.1 --pre-trigger 0.05 --noise 0 0.02 0.05 0.1 \\
        --stands drop-stand --laws kelvin-voigt hunt-crossley       # the 100 ms table
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))  # benchmarks/recorded.py

import argparse
import os
import time
from concurrent.futures import ProcessPoolExecutor, as_completed

import numpy as np

from impactometer.errors import IdentificationError
from impactometer.identify.peak_to_peak import identify
from impactometer.rig import get_rig
from impactometer.studies.base import StudyOptions, case_seed, scenario_grid
from impactometer.studies.identification import clean_recordings, with_noise
from recorded import recorded

NAMES = ("paper", "robust early", "robust")
#: name of the per-case noise draws (the studies' seeding scheme)
DRAW = "accuracy-peak-to-peak"

#: the README's headline rows are those of the default stand (the other stands' rows stay in the tables)
DEFAULT_STAND_NAMES = ("drop-stand", "drop-stand-pad")


def cases(values: int, subset: int | None) -> list[dict]:
    """The paper's grid (``values`` per axis), or an evenly spread ``subset`` of it."""
    grid = scenario_grid(StudyOptions(grid=values))
    if subset is not None and subset < len(grid):
        grid = [grid[int(i)] for i in np.linspace(0, len(grid) - 1, subset).round()]
    return grid


def evaluate(task) -> tuple[tuple, list]:
    """One (stand, law, noise, seed) over the cases: rows (variant, dM, dV, after t11, available_at, in 2σ M,
    in 2σ V, equations)."""
    stand, law, noise, seed, grid, duration, pre_trigger, contact_phase = task
    options = StudyOptions(rig=get_rig(stand, contact=law), sample_rate=50e3, duration=duration,
                           pre_trigger=pre_trigger)
    levels = {"contact_force": noise, "piston_acceleration": noise}
    recs = [with_noise(clean, levels, case_seed(options, DRAW, i, seed))
            for i, clean in enumerate(clean_recordings(grid, options))]
    rows = []
    for rec in recs:
        mass, velocity = rec.truth("mass_kg"), rec.truth("velocity_m_s")
        answers: dict = {}
        for name, options in (("paper", {"variant": "paper"}),
                              ("robust", {"variant": "robust", "contact_phase": contact_phase})):
            try:
                answers[name] = identify(rec, **options)
            except IdentificationError:
                answers[name] = None
        answers["robust early"] = answers["robust"].early if answers["robust"] is not None else None
        for name in NAMES:
            res = answers[name]
            if res is None:
                rows.append((name, np.nan, np.nan, np.nan, np.nan, False, False, None))
                continue
            rows.append((name, res.mass / mass - 1, res.velocity / velocity - 1, res.available_at - res.t11,
                         res.available_at, abs(res.mass - mass) <= 2 * res.mass_std,
                         abs(res.velocity - velocity) <= 2 * res.velocity_std, res.details.get("equations")))
    return (stand, law, noise), rows


def summarise(key, rows) -> list[str]:
    stand, law, noise = key
    out = []
    for name in NAMES:
        sel = [r for r in rows if r[0] == name]
        ok = [r for r in sel if np.isfinite(r[1])]
        missing = len(sel) - len(ok)
        if not ok:
            out.append(f"| {stand} | {law} | {noise:.0%} | {name} | - | - | - | - | - | - | - | {missing} |")
            continue
        dm, dv = np.abs([r[1] for r in ok]) * 100, np.abs([r[2] for r in ok]) * 100
        after = np.array([r[3] for r in ok]) * 1e3
        when = np.median([r[4] for r in ok]) * 1e3
        cover = "-" if name == "paper" or noise == 0 else \
            f"{np.mean([r[5] for r in ok]):.0%} / {np.mean([r[6] for r in ok]):.0%}"
        out.append(f"| {stand} | {law} | {noise:.0%} | {name} | {dm.mean():.2f} | {dm.max():.2f} | {dv.mean():.3f} | "
                   f"{dv.max():.3f} | {when:.1f} | {np.nanmedian(after):.1f} / {np.nanmax(after):.1f} | {cover} | "
                   f"{missing} |")
    return out


def equations_used(rows) -> str:
    """Median counts of the equations of the final answers."""
    used = [r[7] for r in rows if r[0] == "robust" and r[7]]
    keys = ("onsets", "extrema", "stage_b_extrema", "separations", "stage_b_samples")
    return ", ".join(f"{k} {np.median([u.get(k, 0) for u in used]):g}" for k in keys) if used else "-"


def grid_arguments(ap: argparse.ArgumentParser, *, stands: list[str], laws: list[str], seeds: int) -> None:
    """The options of an accuracy table over the paper's grid: stands, laws, noise, seeds, grid, record length."""
    ap.add_argument("--stands", nargs="+", default=stands)
    ap.add_argument("--laws", nargs="+", default=laws)
    ap.add_argument("--noise", type=float, nargs="+", default=[0.05], help="noise levels (fraction of RMS)")
    ap.add_argument("--seeds", type=int, default=seeds, help="noise realisations per noisy case")
    ap.add_argument("--values", type=int, default=5, help="values per grid axis (5 -> 125 cases)")
    ap.add_argument("--subset", type=int, default=None, help="use this many cases spread over the grid")
    ap.add_argument("--duration", type=float, default=0.05, help="record length after first contact [s]")
    ap.add_argument("--pre-trigger", type=float, default=0.02, help="record length before first contact [s]")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    grid_arguments(ap, stands=["drop-stand-pad", "drop-stand-stiff"],
                   laws=["kelvin-voigt", "hunt-crossley", "hysteretic"], seeds=5)
    ap.add_argument("--contact-phase", action="store_true", help="robust: add the contact-phase fit")
    ap.add_argument("--jobs", type=int, default=os.cpu_count() or 1, help="worker processes")
    ap.add_argument("--record", action="store_true", help="keep the output in docs/results/ and the docs")
    args = ap.parse_args()
    name = "accuracy_peak_to_peak" if args.duration == 0.05 else f"accuracy_peak_to_peak_{args.duration * 1e3:.0f}ms"
    title = (f"Peak-to-peak identification: accuracy over the paper's grid, {args.duration * 1e3:.0f} ms + "
             f"{args.pre_trigger * 1e3:.0f} ms pre-trigger")
    with recorded(name, title, args.record) as rec:
        measure(args, rec)


def measure(args, rec) -> None:
    grid = cases(args.values, args.subset)
    tasks = [(stand, law, noise, seed, grid, args.duration, args.pre_trigger, args.contact_phase)
             for stand in args.stands for law in args.laws for noise in args.noise
             for seed in range(1 if noise == 0 else args.seeds)]
    print(f"{len(grid)} cases, 50 kHz, {args.duration * 1e3:.0f} ms after first contact + "
          f"{args.pre_trigger * 1e3:.0f} ms pre-trigger; errors in %, times in ms; coverage = truth within ±2σ "
          "(mass / velocity); missing = refused, or no early answer\n")
    results: dict = {}
    start = time.perf_counter()
    with ProcessPoolExecutor(max_workers=max(args.jobs, 1)) as pool:
        futures = [pool.submit(evaluate, task) for task in tasks]
        for done, future in enumerate(as_completed(futures), 1):
            key, rows = future.result()
            results.setdefault(key, []).extend(rows)
            elapsed = time.perf_counter() - start
            print(f"\r{done}/{len(tasks)} runs, {elapsed:.0f} s, about {elapsed / done * (len(tasks) - done):.0f} s "
                  "left", end="", file=sys.stderr, flush=True)
    print(file=sys.stderr)
    print("| stand | contact | noise | answer | mean dM | max dM | mean dV | max dV | available at | after t11 "
          "(median / max) | ±2σ coverage | missing |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    order = [(s, law, n) for s in args.stands for law in args.laws for n in args.noise]
    for key in order:
        print("\n".join(summarise(key, results[key])))
        final = [r for r in results[key] if r[0] == "robust" and np.isfinite(r[1])]
        if final and key[2] == 0.05 and args.duration == 0.05 and key[0] in DEFAULT_STAND_NAMES:  # the README's
            rec.headline(f"robust M1 / V0 mean error, {key[0]}, {key[1]} contact, 5 % noise, 50 ms",
                         f"{np.mean(np.abs([r[1] for r in final])):.2%} / {np.mean(np.abs([r[2] for r in final])):.2%}",
                         target="1.5 % / 0.4 %")
    print("\nequations of the final answers (median per record):")
    for key in order:
        print(f"  {key[0]}, {key[1]}, {key[2]:.0%}: {equations_used(results[key])}")
    print(f"\n({time.perf_counter() - start:.0f} s)")


if __name__ == "__main__":
    main()
