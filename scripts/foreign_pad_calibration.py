"""A pad of another simulator calibrated from six drops, then held-back drops reproduced and identified with it.

The drops come from the independent simulator of ``tests/foreign_stand.py`` (written without impactometer's model
code): the built-in pad stand's cylinder, gas, friction and stops with a ``power-set`` pad (power-law loading
F = k·δ^n, a plastic set φ·δmax that stays, unloading and reloading along a power law of its own exponent), drawn
per pad from the simulator's ranges (n 1.3-1.8, k 5e5-1e6 N/m at 1 cm, φ 0.15-0.4, unloading exponent 1.5-3).
Per pad: ``--drops`` calibration drops (100 ms after contact, 5 % RMS noise, the light gate's V0 with a 0.5 % σ,
M1 and p0 as stated) calibrated from the built-in stand (``impactometer.calibrate``: every contact-law family,
the contact's parameters, the seal friction and both dead volumes fitted); then ``--held-back`` drops (50 ms after
contact + 20 ms pre-trigger, 5 % noise, only p0 stated) reproduced with the calibrated stand
(``impactometer.calibrate.validate``: force NRMSE with V0 held at the light gate's), and identified with it by the
model fit (``rig=`` the calibrated stand's file, which carries its parameters' σ), by the robust peak-to-peak
method and, for reference, by the model fit on the true stand (what is left to the calibration).

    python scripts/foreign_pad_calibration.py [--pads 2] [--drops 6] [--held-back 10] [--seed 1] [--record]

Printed: per pad, the law and parameters calibrated, χ²/dof, the held-back median and max force NRMSE; then per
method the mean and max |relative error| of M1 and V0 over every held-back drop and the share whose truth lies
within ±2σ.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))  # recorded.py
sys.path.insert(0, str(ROOT / "tests"))  # foreign_stand.py

import numpy as np  # noqa: E402 - after the paths

import foreign_stand as fs  # noqa: E402
from impactometer.calibrate import calibrate, validate  # noqa: E402
from impactometer.errors import ImpactometerError  # noqa: E402
from impactometer.identify.model_fit import identify as identify_model  # noqa: E402
from impactometer.identify.peak_to_peak import identify as identify_robust  # noqa: E402
from impactometer.rig import Rig, get_rig  # noqa: E402
from recorded import recorded  # noqa: E402

#: the methods compared on the held-back drops: name -> (record, calibrated stand file, true stand) -> answer (the
#: calibrated stand is read from the file calibrate writes, with the uncertainty of its parameters); the model
#: on the true stand (the simulator's pad in the power law, its cylinder as the built-in stand's) is the reference
#: that tells what the calibration leaves
METHODS = {"model (calibrated stand)": lambda record, rig, truth: identify_model(record, rig=rig),
           "peak-to-peak/robust": lambda record, rig, truth: identify_robust(record),
           "model (true stand, reference)": lambda record, rig, truth: identify_model(record, rig=truth)}
#: relative σ of the light gate's V0 stated with each calibration drop [-]
GATE = 0.005
NOISE = 0.05


def true_stand(pad) -> Rig:
    """The foreign stand in the package's terms: the built-in stand with the pad's power law (its k·δ^n stated as
    the secant stiffness at 1 cm)."""
    return get_rig("drop-stand").replace(**{"contact.law": "power", "contact.stiffness": pad.k * 0.01 ** (pad.n - 1),
                                            "contact.exponent": pad.n, "contact.unloading_exponent": pad.mu,
                                            "contact.set_fraction": pad.set_fraction})


def drops_of(pad, rng: np.random.Generator, count: int, *, duration: float, truth: bool, gate_rng=None):
    """``count`` records of ``pad`` at drops drawn by the foreign simulator; with ``truth`` the metadata state M1
    and the light gate's V0 as a calibration set needs them. Returns (records, drops)."""
    records, cases = [], []
    for _ in range(count):
        drop = fs.draw_drop(rng)
        rec = fs.record(pad, drop, seed=int(rng.integers(2**31)), noise=NOISE, duration=duration)
        if truth:
            rec.metadata.update(mass_kg=drop.mass,
                                velocity_m_s=drop.velocity * (1.0 + GATE * gate_rng.standard_normal()))
        records.append(rec)
        cases.append(drop)
    return records, cases


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--pads", type=int, default=2, help="power-set pads, each calibrated on its own drops")
    ap.add_argument("--drops", type=int, default=6, help="calibration drops per pad")
    ap.add_argument("--held-back", type=int, default=10, help="held-back drops per pad")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--record", action="store_true", help="keep the output in docs/results/ and the docs")
    args = ap.parse_args()
    with recorded("foreign_pad_calibration", "A power-set pad of another simulator: calibrated from six drops, "
                  "held-back drops reproduced and identified", args.record) as rec:
        measure(args, rec)


def measure(args, rec) -> None:
    errors: dict[str, list[tuple[float, float, bool, bool]]] = {name: [] for name in METHODS}
    refusals: dict[str, list[str]] = {name: [] for name in METHODS}
    nrmse_medians, nrmse_max = [], []
    print("| pad | n | φ | m | law calibrated | calibrated parameters | χ²/dof | held-back force NRMSE median / "
          "max | time [s] |")
    print("|---|---|---|---|---|---|---|---|---|")
    for p in range(args.pads):
        rng = np.random.default_rng([args.seed, p])
        pad = fs.draw_pad("power-set", rng)
        start = time.perf_counter()
        calibration_set, _ = drops_of(pad, rng, args.drops, duration=0.1, truth=True,
                                      gate_rng=np.random.default_rng([args.seed, p, 1]))
        result = calibrate(calibration_set, rig="drop-stand")
        stand_file = result.to_toml(Path(tempfile.mkdtemp()) / "calibrated.toml")
        held, truths = drops_of(pad, rng, args.held_back, duration=0.05, truth=False)
        gated = [r.with_metadata(mass_kg=t.mass, velocity_m_s=t.velocity) for r, t in zip(held, truths, strict=True)]
        check = validate(result.rig, gated)
        nrmse = np.array([d.force_nrmse for d in check.drops])
        nrmse_medians.append(float(np.median(nrmse)))
        nrmse_max.append(float(np.max(nrmse)))
        shown = ", ".join(f"{k.removeprefix('contact.')} {v:.4g}" for k, v in result.parameters.items()
                          if k.startswith("contact."))
        print(f"| {p} (k {pad.k:.3g}) | {pad.n:.3f} | {pad.set_fraction:.3f} | {pad.mu:.3f} | {result.law} | {shown} | "
              f"{result.reduced_chi2:.3f} | {np.median(nrmse):.2%} / {np.max(nrmse):.2%} | "
              f"{time.perf_counter() - start:.0f} |", flush=True)
        for record, truth in zip(held, truths, strict=True):
            for name, method in METHODS.items():
                try:
                    answer = method(record, str(stand_file), true_stand(pad))
                except ImpactometerError as exc:  # a refusal is counted and named, not scored
                    refusals[name].append(f"{type(exc).__name__}: {exc}")
                    continue
                dm, dv = answer.mass / truth.mass - 1.0, answer.velocity / truth.velocity - 1.0
                errors[name].append((abs(dm), abs(dv), abs(answer.mass - truth.mass) <= 2.0 * answer.mass_std,
                                     abs(answer.velocity - truth.velocity) <= 2.0 * answer.velocity_std))
    total = args.pads * args.held_back
    print(f"\n{total} held-back drops ({args.pads} pads × {args.held_back}), 50 ms + 20 ms pre-trigger at 50 kHz, "
          f"{NOISE:.0%} RMS noise; M1 8-60 kg, V0 0.8-3.5 m/s, p0 100-380 kPa\n")
    print("| method | answers | mean abs dM | max abs dM | mean abs dV | max abs dV | M1 within ±2σ | V0 within ±2σ |")
    print("|---|---|---|---|---|---|---|---|")
    for name, rows in errors.items():
        a = np.array(rows, dtype=float).reshape(-1, 4)
        print(f"| {name} | {len(rows)} of {total} | {a[:, 0].mean():.2%} | {a[:, 0].max():.2%} | {a[:, 1].mean():.2%} "
              f"| {a[:, 1].max():.2%} | {a[:, 2].mean():.0%} | {a[:, 3].mean():.0%} |")
    for name, reasons in refusals.items():
        for reason in reasons:
            print(f"\n{name} refused a record: {reason}")
    model = np.array(errors["model (calibrated stand)"], dtype=float)
    print(f"\nheld-back force NRMSE over the pads: median of the medians {np.median(nrmse_medians):.2%}, "
          f"largest {max(nrmse_max):.2%}")
    rec.headline("power-set pad of another simulator, 6 drops calibrated: held-back median force NRMSE; model "
                 "mean abs dM and ±2σ coverage of M1 / V0 with the calibrated stand",
                 f"{np.median(nrmse_medians):.1%}; {model[:, 0].mean():.2%}; {model[:, 2].mean():.0%} / "
                 f"{model[:, 3].mean():.0%}", target="5 %; 1 %; 85 %")


if __name__ == "__main__":
    main()
