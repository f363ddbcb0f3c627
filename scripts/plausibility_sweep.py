"""How often the plausibility warnings fire on valid recordings, and how often a wrong answer goes without one.

Simulates random drop tests (the two stands, the three contact laws, 2-10 kg pistons, 0-60 N friction, 5-80 kg at
0.5-4 m/s, 10-200 kHz, the three anti-alias designs, 12/16-bit or no ADC, 0-5 % noise, with or without pre-trigger),
identifies each with both variants and counts, per check, the warnings on answers within 5 % (mass) and 2 %
(velocity) of the truth (false alarms) and beyond (right alarms), and the answers beyond without a warning.

Usage::

    PYTHONPATH=src python scripts/plausibility_sweep.py [--impacts 150] [--seed 7]
"""

from __future__ import annotations

import argparse
import collections

import numpy as np

from impactometer.errors import ImpactometerError
from impactometer.identify.peak_to_peak import identify
from impactometer.rig import Scenario, get_rig
from impactometer.sensors import record
from impactometer.studies.base import PAPER_RANGES

#: an answer within these relative errors of the truth is good (mass, velocity)
GOOD = (0.05, 0.02)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--impacts", type=int, default=150)
    parser.add_argument("--seed", type=int, default=7)
    options = parser.parse_args(argv)
    rng = np.random.default_rng(options.seed)
    counts: collections.Counter = collections.Counter()
    for i in range(options.impacts):
        stand = get_rig(str(rng.choice(["drop-stand", "drop-stand-pad"])),
                        contact=str(rng.choice(["kelvin-voigt", "hunt-crossley", "hysteretic"])))
        stand = stand.replace(**{"cylinder.piston_mass": float(rng.uniform(2, 10)),
                                 "friction.force": float(rng.uniform(0, 60))})
        scenario = Scenario(mass=float(rng.uniform(5, 80)), velocity=float(rng.uniform(0.5, 4)),
                            pressure_gauge=float(rng.uniform(*PAPER_RANGES["pressure_gauge"])))
        try:
            rec = record(scenario, stand, sample_rate=float(rng.choice([10e3, 20e3, 50e3, 100e3, 200e3])),
                         duration=0.1, noise=float(rng.choice([0, 0.005, 0.01, 0.02, 0.05])), seed=i,
                         pre_trigger=float(rng.choice([0.0, 0.02, 0.05])),
                         anti_alias=str(rng.choice(["causal", "zero-phase", "none"])),
                         adc_bits=[None, 12, 16][int(rng.integers(3))])
        except ImpactometerError:
            continue
        for variant in ("robust", "paper"):
            try:
                found = identify(rec, variant=variant)
            except ImpactometerError:
                counts[f"{variant}: refused"] += 1
                continue
            good = abs(found.mass / scenario.mass - 1) <= GOOD[0] and \
                abs(found.velocity / scenario.velocity - 1) <= GOOD[1]
            counts[f"{variant}: answers"] += 1
            counts[f"{variant}: {'good' if good else 'off'}"] += 1
            for warning in found.warnings:
                check = " ".join(warning.split()[:3])
                counts[f"{variant}: warning '{check} ...' on {'a good' if good else 'an off'} answer"] += 1
            if not good and not found.warnings:
                counts[f"{variant}: off without a warning"] += 1
                print(f"impact {i}, {variant}: M1 {found.mass:.3g} for {scenario.mass:.3g} kg, V0 {found.velocity:.3g} "
                      f"for {scenario.velocity:.3g} m/s, {stand.contact.law}, no warning")
    for key in sorted(counts):
        print(f"{counts[key]:6d}  {key}")


if __name__ == "__main__":
    main()
