"""Does a stand behave like the paper's? Stage A / stage B figures and the paper variant's accuracy on the grid.

Over the paper's 125-case grid (M1 10-50 kg, V0 1-3 m/s, p0 20-400 kPa gauge, 5 values each):

- with the valve wide open from first contact (the absorber's regime) and closed: pulses before the mass's deepest
  point, the end of stage A (start of the contact that lasts to the deepest point) and whether that contact does
  last to the deepest point, from the simulation's truth channels;
- the paper's eqs. (3)-(5) (``--variant paper``) on noise-free recordings at 50, 40, 20 and 10 kHz (50 ms after
  first contact, 20 ms of pre-trigger): velocity and mass errors.

    python scripts/stand_criteria.py                       # the built-in drop-stand
    python scripts/stand_criteria.py --rig drop-stand-stiff
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))  # benchmarks/recorded.py

import numpy as np

from impactometer import get_rig, simulate_batch
from impactometer.errors import IdentificationError, SimulationError
from impactometer.identify.inspection import inspect_recording
from impactometer.identify.peak_to_peak import identify
from impactometer.signals.pulses import contact_pulses
from impactometer.studies.base import StudyOptions, case_seed, scenario_grid
from impactometer.studies.identification import clean_recordings, with_noise
from recorded import recorded

DURATION = 0.5  # [s] simulated for the stage figures: past the deepest point in every case
RATES = (50e3, 40e3, 20e3, 10e3)
#: name of the per-case noise draws (the studies' seeding scheme)
DRAW = "stand-criteria"


def grid(rig, n: int = 5):
    """The paper's M1 × V0 × p0 grid (``studies.base.scenario_grid``) as three arrays."""
    rows = scenario_grid(StudyOptions(rig=rig, grid=n))
    return tuple(np.array([r[k] for r in rows]) for k in ("mass", "velocity", "pressure_gauge"))


def stages(rig, m, v, p):
    """Per case: pulses before the deepest point, stage-B start [s], whether contact lasts to the deepest point."""
    batch = simulate_batch(m, v, p, rig, channels=("contact_force", "u1", "u2"), duration=DURATION,
                           sample_rate=50e3)
    t = batch.time
    out = []
    for i in range(len(m)):
        force, u1 = batch["contact_force"][i], batch["u1"][i]
        deepest = int(np.argmax(u1))
        pulses = contact_pulses(t[:deepest + 1], force[:deepest + 1])
        touching = force[:deepest + 1] > 0.0
        # stage B: the last onset before the deepest point, if the force stays on from there
        onsets = np.flatnonzero(np.diff(touching.astype(np.int8)) == 1) + 1
        start = int(onsets[-1]) if onsets.size else 0
        sustained = bool(touching[start:deepest + 1].all()) and deepest > start
        out.append((len(pulses), t[start], sustained, t[deepest]))
    return out


def _cases(m, v, p) -> list[dict]:
    return [{"mass": float(a), "velocity": float(b), "pressure_gauge": float(c)} for a, b, c in zip(m, v, p,
                                                                                                   strict=True)]


def paper_errors(rig, m, v, p, rate):
    """Relative (mass, velocity) errors [-] of eqs. (3)-(5) per case on noise-free recordings at ``rate`` [Hz]."""
    options = StudyOptions(rig=rig, sample_rate=rate, duration=0.05, pre_trigger=0.02)
    recs = clean_recordings(_cases(m, v, p), options)
    errors = []
    for rec, mi, vi in zip(recs, m, v, strict=True):
        try:
            a = identify(rec, variant="paper")
            errors.append((a.mass / mi - 1.0, a.velocity / vi - 1.0))
        except IdentificationError:
            errors.append((np.nan, np.nan))
    return np.array(errors)


def stage_split(rig, m, v, p, truth, noise):
    """inspect's stage-B start minus the true one [s] per case (NaN where inspect reports none)."""
    options = StudyOptions(rig=rig, sample_rate=50e3, duration=0.1, pre_trigger=0.02)
    levels = {"contact_force": noise, "piston_acceleration": noise}
    recs = [with_noise(clean, levels, case_seed(options, DRAW, i))
            for i, clean in enumerate(clean_recordings(_cases(m, v, p), options))]
    found = np.array([np.nan if (b := inspect_recording(r).stage_b_start) is None else b for r in recs])
    return found - truth


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rig", default="drop-stand")
    parser.add_argument("--grid", type=int, default=5)
    parser.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                        help="a stand parameter changed, e.g. --set contact.stiffness=1e6 (repeatable)")
    parser.add_argument("--record", action="store_true", help="keep the output in docs/results/ and the docs")
    args = parser.parse_args()
    name = "stand_criteria" if args.rig == "drop-stand" and not args.set else None
    with recorded(name or "stand_criteria_other", f"The stand against the paper's description: {args.rig}",
                  args.record and name is not None):
        measure(args)


def measure(args) -> None:
    rig = get_rig(args.rig)
    changes = dict(item.split("=", 1) for item in args.set)
    if changes:
        rig = rig.replace(**{k: (v if k == "contact.law" else float(v)) for k, v in changes.items()})
    m, v, p = grid(rig, args.grid)
    print(f"stand {rig.name!r}: contact {rig.contact}, friction {rig.friction.force:g} N; {m.size} cases")
    for label, area in (("valve wide open", rig.valve.max_area), ("valve closed", 0.0)):
        run = dataclasses.replace(rig, valve=dataclasses.replace(rig.valve, area=area))
        try:
            rows = stages(run, m, v, p)
        except SimulationError as exc:
            print(f"\n{label}: not simulated to the deepest point ({exc}); a stand without dead volume lets an "
                  "open valve empty the lower chamber at the end of the stroke")
            continue
        pulses = np.array([r[0] for r in rows])
        t_b = np.array([r[1] for r in rows])
        sustained = np.array([r[2] for r in rows])
        heavy = m >= 20.0
        print(f"\n{label}:")
        print(f"  pulses before the deepest point: median {np.median(pulses):.0f}, range {pulses.min()}-"
              f"{pulses.max()}, within 2-6: {np.mean((pulses >= 2) & (pulses <= 6)):.0%}")
        print(f"  stage A over (sustained contact starts) at: median {np.median(t_b) * 1e3:.1f} ms, max "
              f"{t_b.max() * 1e3:.1f} ms; within 40 ms for M1 >= 20 kg: {np.mean(t_b[heavy] <= 0.04):.0%}")
        print(f"  contact sustained to the deepest point: {np.mean(sustained):.0%} of the cases "
              f"(M1 >= 20 kg: {np.mean(sustained[heavy]):.0%}); pulses within 2-6 for M1 >= 20 kg: "
              f"{np.mean((pulses[heavy] >= 2) & (pulses[heavy] <= 6)):.0%}")
        if area == 0.0:
            for noise in (0.0, 0.02):
                diff = stage_split(rig, m, v, p, t_b, noise)
                ok = np.isfinite(diff)
                print(f"  inspect's stage-B start minus the true one at {noise:.0%} noise (100 ms records): median "
                      f"{np.median(diff[ok]) * 1e3:+.2f} ms, within ±0.5 ms in {np.mean(np.abs(diff[ok]) <= 5e-4):.0%}"
                      f", none found in {int((~ok).sum())} (stage B after the record's end: "
                      f"{int((t_b > 0.08).sum())})")
    print("\npaper variant (eqs. 3-5), noise-free, 50 ms after first contact:")
    print("| rate | V0 error max | V0 error mean | M1 error mean | M1 error max | failed |")
    print("|---:|---:|---:|---:|---:|---:|")
    for rate in RATES:
        e = paper_errors(rig, m, v, p, rate)
        ok = np.isfinite(e[:, 0])
        print(f"| {rate / 1e3:.0f} kHz | {np.abs(e[ok, 1]).max():.2%} | {np.abs(e[ok, 1]).mean():.2%} | "
              f"{np.abs(e[ok, 0]).mean():.2%} | {np.abs(e[ok, 0]).max():.2%} | {int((~ok).sum())} |")


if __name__ == "__main__":
    main()
