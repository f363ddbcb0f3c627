"""Acceptance table of the peak-to-peak identification on the built-in stand.

Grid: M1 ∈ 10..50 kg × V0 ∈ 1..3 m/s × p0 ∈ 20..400 kPa (5 values each, 125 cases), recorded at 50 kHz by the
sensor model (zero-phase anti-alias filter), 0.1 s after first contact plus a pre-trigger, Gaussian noise of
0/2/5/10 % of each channel's RMS on force and acceleration (5 seeds; one run without noise), Kelvin-Voigt and
Hunt-Crossley contact. Prints mean and max relative errors of mass and velocity for ``paper``, ``robust`` early and
``robust`` final, the median time the answer is available, the ±2σ coverage and the number of refusals
(IdentificationError: the record does not allow an answer).

    python scripts/accuracy_peak_to_peak.py            # the full table (several minutes)
    python scripts/accuracy_peak_to_peak.py --values 3 --seeds 2 --noise 0 0.05   # a quick look
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from impactometer.errors import IdentificationError
from impactometer.identify.peak_to_peak import identify
from impactometer.rig import get_rig
from impactometer.sensors import record_batch

#: rows of the table -> options of identify()
VARIANTS = {"paper": {"variant": "paper"}, "robust": {"variant": "robust"},
            "robust + contact phase": {"variant": "robust", "contact_phase": True}}
NAMES = ("paper", "robust early", "robust", "robust + contact phase")


def grid(values: int):
    m, v, p = np.meshgrid(np.linspace(10, 50, values), np.linspace(1, 3, values), np.linspace(20e3, 400e3, values),
                          indexing="ij")
    return m.ravel(), v.ravel(), p.ravel()


def evaluate(recordings):
    """Rows (variant, mass error, velocity error, available after t11 [s], available_at [s], in 2σ M, in 2σ V)."""
    rows = []
    for rec in recordings:
        m, v = rec.truth("mass_kg"), rec.truth("velocity_m_s")
        answers = {}
        for name, options in VARIANTS.items():
            try:
                res = identify(rec, **options)
            except IdentificationError:
                answers[name] = None
                continue
            answers[name] = res
            if name == "robust":
                answers["robust early"] = res.early
        for name in NAMES:
            res = answers.get(name)
            if res is None:
                rows.append((name, np.nan, np.nan, np.nan, np.nan, False, False))
                continue
            dm, dv = res.mass / m - 1, res.velocity / v - 1
            rows.append((name, dm, dv, res.available_at - res.t11, res.available_at,
                         abs(res.mass - m) <= 2 * res.mass_std, abs(res.velocity - v) <= 2 * res.velocity_std))
    return rows


def summarise(rows, law: str, noise: float) -> list[str]:
    out = []
    for name in NAMES:
        sel = [r for r in rows if r[0] == name]
        ok = [r for r in sel if np.isfinite(r[1])]
        refused = len(sel) - len(ok)
        if not ok:
            out.append(f"| {law} | {noise:.0%} | {name} | - | - | - | - | - | - | - | {refused} |")
            continue
        dm = np.abs([r[1] for r in ok]) * 100
        dv = np.abs([r[2] for r in ok]) * 100
        after = np.median([r[3] for r in ok]) * 1e3
        after_max = np.max([r[3] for r in ok]) * 1e3
        when = np.median([r[4] for r in ok]) * 1e3
        cover = "-" if name == "paper" or noise == 0 else \
            f"{np.mean([r[5] for r in ok]):.0%} / {np.mean([r[6] for r in ok]):.0%}"
        final = "robust final" if name == "robust" else name
        out.append(f"| {law} | {noise:.0%} | {final} | {dm.mean():.2f} | {dm.max():.2f} | {dv.mean():.3f} | "
                   f"{dv.max():.3f} | {when:.1f} | {after:.1f} / {after_max:.1f} | {cover} | {refused} |")
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--values", type=int, default=5, help="values per grid axis (5 -> 125 cases)")
    ap.add_argument("--seeds", type=int, default=5, help="noise seeds per noisy case")
    ap.add_argument("--noise", type=float, nargs="+", default=[0.0, 0.02, 0.05, 0.10])
    ap.add_argument("--laws", nargs="+", default=["kelvin-voigt", "hunt-crossley"])
    ap.add_argument("--duration", type=float, default=0.1, help="record length after first contact [s]")
    ap.add_argument("--pre-trigger", type=float, default=0.05, help="record length before first contact [s]")
    args = ap.parse_args()
    m, v, p = grid(args.values)
    print(f"{m.size} cases, 50 kHz, duration {args.duration * 1e3:.0f} ms + {args.pre_trigger * 1e3:.0f} ms "
          "pre-trigger; errors in %, times in ms (median unless said), "
          "coverage = truth within ±2σ (mass / velocity)\n")
    print("| contact | noise | variant | mean dM | max dM | mean dV | max dV | available at | after t11 (median / max) "
          "| 2σ coverage | refused |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    t_start = time.perf_counter()
    for law in args.laws:
        rig = get_rig(None, contact=law)
        for noise in args.noise:
            rows = []
            for seed in range(1 if noise == 0 else args.seeds):
                recs = record_batch(m, v, p, rig, sample_rate=50e3, duration=args.duration, noise=noise,
                                    seed=1000 + seed, pre_trigger=args.pre_trigger)
                rows.extend(evaluate(recs))
            print("\n".join(summarise(rows, law, noise)), flush=True)
    print(f"\n({time.perf_counter() - t_start:.0f} s)")


if __name__ == "__main__":
    main()
