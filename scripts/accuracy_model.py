"""Accuracy of the model-based identification (``identify --method model``) against the Cramér-Rao bound, over the
paper's grid.

Grid: the 125 cases of the paper's ranges (M1 10-50 kg × V0 1-3 m/s × p0 20-400 kPa, 5 values each), or an evenly
spread ``--subset``; recorded at 50 kHz by the sensor model (causal anti-alias filter), ``--duration`` after first
contact plus ``--pre-trigger``, Gaussian noise of each channel's RMS (``--noise``), ``--seeds`` realisations,
seeded as the studies do (the records of ``scripts/accuracy_peak_to_peak.py``). For every stand and contact law
(the record's; the fit chooses among all laws by BIC) it prints the mean and max relative errors of mass and
velocity of the model's answer and of the robust peak-to-peak answer it started from, the ±2σ coverage (truth
within two stated standard errors, mass / velocity), the efficiency (mean |error| / mean Cramér-Rao σ at the truth;
an efficient unbiased estimate gives sqrt(2/π) = 0.80), the mean Cramér-Rao σ, how often the law of the record
was chosen, the paths of the model-adequacy test (adequate, shortened, widened), the fall-backs to the robust
answer, refusals, and the median wall time of one identification (one
process, one compiled thread; the robust answer's time included).

    python scripts/accuracy_model.py --subset 12 --seeds 1            # a quick look
    python scripts/accuracy_model.py                                   # 125 cases, one seed, pad stand
    python scripts/accuracy_model.py --subset 25 --fit-pressure        # pre-charge unknown, as in the CRB tables
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))  # benchmarks/recorded.py

import argparse
import time
from dataclasses import replace

import numba
import numpy as np

from accuracy_peak_to_peak import DRAW, cases, grid_arguments  # the same records as the peak-to-peak table
from impactometer.errors import IdentificationError
from impactometer.identify.model_fit import cramer_rao, identify
from impactometer.rig import get_rig
from impactometer.studies.base import StudyOptions, case_seed
from impactometer.studies.identification import clean_recordings, with_noise
from recorded import recorded


def evaluate(stand: str, law: str, noise: float, seed: int, grid, duration: float, pre_trigger: float,
             fit_pressure: bool = False) -> list:
    """Rows (dM, dV, robust dM, robust dV, in 2σ M, in 2σ V, CRB σM/M, CRB σV/V, law chosen, path, seconds,
    adequacy verdict) of one stand, law, noise level and seed over the cases; a refusal gives None."""
    rig = get_rig(stand, contact=law)
    options = StudyOptions(rig=rig, sample_rate=50e3, duration=duration, pre_trigger=pre_trigger)
    levels = {"contact_force": noise, "piston_acceleration": noise}
    rows = []
    for i, clean in enumerate(clean_recordings(grid, options)):
        rec = with_noise(clean, levels, case_seed(options, DRAW, i, seed))
        mass, velocity = rec.truth("mass_kg"), rec.truth("velocity_m_s")
        pressure = rec.metadata["pressure_gauge_Pa"]
        if fit_pressure:  # a record that does not state its pre-charge: the fit estimates it
            rec = replace(rec, metadata={k: v for k, v in rec.metadata.items() if k != "pressure_gauge_Pa"})
        start = time.perf_counter()
        try:
            answer = identify(rec, rig=rig)
        except IdentificationError as exc:
            print(f"refused: {grid[i]}: {exc}", file=sys.stderr)
            rows.append(None)
            continue
        seconds = time.perf_counter() - start
        bound = cramer_rao(rec, rig=rig, mass=mass, velocity=velocity, pressure_gauge=pressure,
                           pressure_gauge_unknown=fit_pressure)
        robust = answer.details["robust"]
        rows.append((answer.mass / mass - 1, answer.velocity / velocity - 1,
                     robust.get("mass_kg", np.nan) / mass - 1, robust.get("velocity_m_s", np.nan) / velocity - 1,
                     abs(answer.mass - mass) <= 2 * answer.mass_std,
                     abs(answer.velocity - velocity) <= 2 * answer.velocity_std, bound.mass_relative,
                     bound.velocity_relative, answer.details.get("contact_law"), answer.details["path"], seconds,
                     (answer.details.get("adequacy") or {}).get("verdict", "")))
    return rows


def summarise(stand: str, law: str, noise: float, rows: list) -> str:
    ok = [r for r in rows if r is not None]
    refused = len(rows) - len(ok)
    if not ok:
        return f"| {stand} | {law} | {noise:.0%} | 0 | - | - | - | - | - | - | - | - | - | - | - | - | {refused} | - |"
    a = np.array([r[:8] for r in ok], dtype=float)
    dm, dv, rm, rv = (np.abs(a[:, k]) * 100 for k in range(4))
    crb_m, crb_v = a[:, 6] * 100, a[:, 7] * 100
    chosen = sum(r[8] == law for r in ok)
    fallbacks = sum(r[9] == "fallback" for r in ok)
    verdicts = " / ".join(str(sum(r[11] == v for r in ok)) for v in ("adequate", "shortened", "widened"))
    return (f"| {stand} | {law} | {noise:.0%} | {len(ok)} | {dm.mean():.3f} | {dm.max():.2f} | {dv.mean():.3f} | "
            f"{dv.max():.3f} | {np.nanmean(rm):.2f} / {np.nanmean(rv):.3f} | "
            f"{a[:, 4].mean():.0%} / {a[:, 5].mean():.0%} | "
            f"{dm.mean() / crb_m.mean():.2f} / {dv.mean() / crb_v.mean():.2f} | {crb_m.mean():.3f} / "
            f"{crb_v.mean():.3f} | {chosen} | {verdicts} | {fallbacks} | {refused} | "
            f"{np.median([r[10] for r in ok]) * 1e3:.0f} |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    grid_arguments(ap, stands=["drop-stand"], laws=["hysteretic", "kelvin-voigt", "hunt-crossley"], seeds=1)
    ap.add_argument("--fit-pressure", action="store_true",
                    help="records without their pre-charge in the metadata: the fit estimates it (and the bound "
                         "counts it among the unknowns)")
    ap.add_argument("--record", action="store_true", help="keep the output in docs/results/ and the docs")
    args = ap.parse_args()
    title = (f"Model-based identification: accuracy against the Cramér-Rao bound, {args.duration * 1e3:.0f} ms + "
             f"{args.pre_trigger * 1e3:.0f} ms pre-trigger")
    name = "accuracy_model" + ("" if args.duration == 0.05 else f"_{args.duration * 1e3:.0f}ms") + (
        "" if list(args.stands) == ["drop-stand"] else "_" + "_".join(args.stands).replace("-", "_"))
    with recorded(name, title, args.record) as rec:
        measure(args, rec)


def measure(args, rec) -> None:
    numba.set_num_threads(1)
    grid = cases(args.values, args.subset)
    print(f"pre-charge {'fitted (not in the metadata)' if args.fit_pressure else 'known (metadata)'}; "
          f"{len(grid)} cases × {args.seeds} seed(s), 50 kHz, {args.duration * 1e3:.0f} ms after first contact + "
          f"{args.pre_trigger * 1e3:.0f} ms pre-trigger; errors and σ in %; coverage = truth within ±2σ "
          "(mass / velocity); efficiency = mean |error| / mean CRB σ (mass / velocity); chosen = the record's law "
          "chosen by BIC; time = median wall time of one identification (one core)\n")
    start = time.perf_counter()
    print("| stand | contact | noise | n | mean dM | max dM | mean dV | max dV | robust mean dM / dV | ±2σ coverage | "
          "efficiency | mean CRB σM / σV | chosen | adequate / shortened / widened | fall-backs | refused | "
          "time [ms] |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for stand in args.stands:
        for law in args.laws:
            for noise in args.noise:
                rows = []
                for seed in range(args.seeds):
                    rows += evaluate(stand, law, noise, seed, grid, args.duration, args.pre_trigger,
                                     args.fit_pressure)
                print(summarise(stand, law, noise, rows), flush=True)
                ok = [r for r in rows if r is not None]
                if ok and noise == 0.05 and args.duration == 0.05 and len(grid) == 125:
                    rec.headline(f"model M1 / V0 mean error, {stand}, {law} contact, 5 % noise, 50 ms",
                                 f"{np.mean(np.abs([r[0] for r in ok])):.2%} / "
                                 f"{np.mean(np.abs([r[1] for r in ok])):.2%}", target="0.6 % / 0.25 %")
    print(f"\n({time.perf_counter() - start:.0f} s)")


if __name__ == "__main__":
    main()
