"""The model fit's answers on a fixed set of simulated records, written to a JSON file, and two such files compared:
a change meant to preserve behaviour must leave every answer equal bit for bit.

The records cover the paths of the model fit: the default stand and the stiff stand each on their own rig and with
no stand named in the file (the built-in stands compared), every contact family, 1 / 5 / 10 % noise, a stated
pressure 3 % off the truth (none in the file), a pressure that contradicts the file's (refused), a fit restricted to
the wrong law (fall-back), a record too short (refused) and pads outside every family from the independent stand
simulator of ``tests/foreign_stand.py``, and records of the stiff stand identified on the default stand named. Each
answer: M1, V0, their σ, method, path, contact law, adequacy verdict, warnings and the details as JSON (or the
refusal's message). The 46 records take the paths adequate (27), widened (1: an answer
that explains its record down to the noise but disagrees with the robust one), fell back (15) and refused (3); none of
them is shortened.

    python scripts/compare_answers.py write answers.json [--jobs 2] [--only foreign/]
    python scripts/compare_answers.py compare before.json after.json
"""

from __future__ import annotations

import argparse
import json
import sys
from multiprocessing import Pool
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))  # tests/foreign_stand.py

RECORD = {"sample_rate": 50e3, "duration": 0.05, "pre_trigger": 0.02}


def cases() -> list[tuple]:
    """(name, kind, arguments) of every record: deterministic."""
    out: list[tuple] = []
    for noise in (0.01, 0.05, 0.10):
        for mass, velocity, pressure, seed in ((30.0, 2.0, 100e3, 11), (10.0, 1.0, 20e3, 12), (50.0, 3.0, 400e3, 13)):
            out.append((f"default/{noise}/{seed}", "own", dict(rig=None, mass=mass, velocity=velocity,
                                                               pressure=pressure, seed=seed, noise=noise)))
        out.append((f"stiff/{noise}", "own", dict(rig="drop-stand-stiff", mass=20.0, velocity=2.5, pressure=300e3,
                                                  seed=31, noise=noise)))
    for law in ("kelvin-voigt", "hunt-crossley", "power"):
        out.append((f"law/{law}", "law", dict(law=law, mass=25.0, velocity=1.8, pressure=150e3, seed=21)))
    out.append(("fallback/kv", "restricted", dict(seed=31)))
    out.append(("fallback/kv10", "restricted", dict(seed=41, noise=0.10)))
    out.append(("outside", "outside", dict(seed=32)))
    for noise, seed in ((0.05, 11), (0.02, 32), (0.10, 33)):
        out.append((f"unnamed/default/{seed}", "unnamed", dict(rig=None, mass=30.0, velocity=2.0, pressure=100e3,
                                                               seed=seed, noise=noise)))
    for mass, velocity, pressure, seed in ((20.0, 2.5, 300e3, 31), (45.0, 3.2, 380e3, 32), (12.0, 1.5, 150e3, 33),
                                           (42.2, 2.62, 216e3, 505)):
        out.append((f"unnamed/stiff/{seed}", "unnamed", dict(rig="drop-stand-stiff", mass=mass, velocity=velocity,
                                                             pressure=pressure, seed=seed, noise=0.05)))
    for error in (-0.03, 0.03):
        for noise in (0.01, 0.05):
            out.append((f"gauge/{error}/{noise}", "gauge", dict(error=error, noise=noise, seed=71)))
    out.append(("refused/pressure", "contradicted", dict(seed=81)))
    out.append(("refused/short", "short", dict(seed=82)))
    for kind, seeds in (("masing", (1, 2, 3)), ("peak-oriented", (1, 2, 3)), ("power-set", (1, 2))):
        for seed in seeds:
            out.append((f"foreign/{kind}/{seed}", "foreign", dict(kind=kind, seed=seed)))
    for mass, velocity, pressure, seed in ((20.0, 2.5, 300e3, 31), (12.0, 1.5, 150e3, 33)):
        out.append((f"misstated/stiff-on-default/{seed}", "misstated", dict(mass=mass, velocity=velocity,
                                                                          pressure=pressure, seed=seed)))
    for seed in (4, 5):
        out.append((f"foreign/masing/quiet/{seed}", "foreign", dict(kind="masing", seed=seed, noise=0.01)))
    for kind in ("masing", "peak-oriented"):
        out.append((f"foreign/long/{kind}/0", "foreign", dict(kind=kind, seed=0, duration=0.1)))
    out.append(("foreign/peak-oriented/7", "foreign", dict(kind="peak-oriented", seed=7)))  # widened
    return out


def _simulated(rig, mass, velocity, pressure, seed, noise=0.05, **options):
    from impactometer.rig import Scenario
    from impactometer.sensors import record

    return record(Scenario(mass=mass, velocity=velocity, pressure_gauge=pressure), rig, seed=seed, noise=noise,
                  **{**RECORD, **options})


def _unnamed(rec):
    from impactometer.rig import STAND_KEY

    for key in ("rig", STAND_KEY):
        rec.metadata.pop(key, None)
    return rec


def job(case: tuple) -> dict:
    """One record's answer (or refusal) as plain JSON values."""
    import numba

    from impactometer.errors import ImpactometerError
    from impactometer.identify.model_fit import identify
    from impactometer.rig import get_rig

    numba.set_num_threads(1)
    name, kind, a = case
    try:
        if kind == "own":
            rec = _simulated(a["rig"], a["mass"], a["velocity"], a["pressure"], a["seed"], a["noise"])
            answer = identify(rec, rig=a["rig"])
        elif kind == "law":
            rig = get_rig(contact=a["law"])
            answer = identify(_simulated(rig, a["mass"], a["velocity"], a["pressure"], a["seed"]), rig=rig)
        elif kind == "restricted":
            rec = _simulated(None, 30.0, 2.0, 100e3, a["seed"], a.get("noise", 0.05))
            answer = identify(rec, contact="kelvin-voigt")
        elif kind == "outside":
            rig = get_rig().replace(**{"contact.stiffness": 1.2e6, "contact.restitution": 0.55})
            answer = identify(_simulated(rig, 30.0, 2.0, 100e3, a["seed"]), contact="hysteretic",
                              uncertain=["friction.force"])
        elif kind == "unnamed":
            rec = _unnamed(_simulated(a["rig"], a["mass"], a["velocity"], a["pressure"], a["seed"], a["noise"]))
            answer = identify(rec)
        elif kind == "gauge":
            rec = _simulated(None, 30.0, 2.0, 100e3, a["seed"], a["noise"])
            rec.metadata.pop("pressure_gauge_Pa")
            answer = identify(rec, pressure_gauge=100e3 * (1.0 + a["error"]))
        elif kind == "misstated":  # a record of the stiff stand identified on the default stand, named
            rec = _simulated("drop-stand-stiff", a["mass"], a["velocity"], a["pressure"], a["seed"])
            answer = identify(rec, rig="drop-stand")
        elif kind == "contradicted":
            answer = identify(_simulated(None, 30.0, 2.0, 100e3, a["seed"]), pressure_gauge=110e3)
        elif kind == "short":
            answer = identify(_simulated(None, 30.0, 2.0, 100e3, a["seed"], duration=0.002))
        else:
            from foreign_stand import foreign_case

            rec, _, _ = foreign_case(a["kind"], a["seed"], noise=a.get("noise", 0.05), duration=a.get("duration", 0.05))
            answer = identify(rec)
    except ImpactometerError as exc:
        return {"name": name, "refused": f"{type(exc).__name__}: {exc}"}
    details = answer.details
    adequacy = details.get("adequacy") or {}
    return {"name": name, "mass": answer.mass, "velocity": answer.velocity, "mass_std": answer.mass_std,
            "velocity_std": answer.velocity_std, "method": answer.method, "path": details["path"],
            "law": details.get("contact_law"), "verdict": adequacy.get("verdict"), "warnings": list(answer.warnings),
            "details": json.loads(json.dumps(answer.to_dict(), default=float))}


def write(path: Path, jobs: int, only: str | None = None) -> None:
    todo = [case for case in cases() if only is None or case[0].startswith(only)]
    if jobs > 1:
        with Pool(jobs) as pool:
            rows = pool.map(job, todo, chunksize=1)
    else:
        rows = [job(case) for case in todo]
    path.write_text(json.dumps(rows, indent=1))
    paths: dict[str, int] = {}
    for row in rows:
        key = row.get("verdict") or row.get("path") or "refused"
        paths[key] = paths.get(key, 0) + 1
    print(f"{len(rows)} records written to {path}; paths {paths}")


def compare(before: Path, after: Path) -> int:
    old = {row["name"]: row for row in json.loads(before.read_text())}
    new = {row["name"]: row for row in json.loads(after.read_text())}
    differ = 0
    for name in sorted(set(old) | set(new)):
        a, b = old.get(name), new.get(name)
        if a == b:
            continue
        differ += 1
        if a is None or b is None:
            print(f"{name}: only in {'after' if a is None else 'before'}")
            continue
        keys = sorted(key for key in set(a) | set(b) if a.get(key) != b.get(key))
        print(f"{name}: differs in {keys}")
        for key in keys:
            if key != "details":
                print(f"  {key}: {a.get(key)!r} -> {b.get(key)!r}")
    print(f"{len(old)} records before, {len(new)} after; {differ} differ (bit-for-bit comparison)")
    return 1 if differ else 0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    w = sub.add_parser("write")
    w.add_argument("path", type=Path)
    w.add_argument("--jobs", type=int, default=1)
    w.add_argument("--only", help="the records whose name starts with this")
    c = sub.add_parser("compare")
    c.add_argument("before", type=Path)
    c.add_argument("after", type=Path)
    args = parser.parse_args()
    if args.command == "write":
        write(args.path, args.jobs, args.only)
    else:
        sys.exit(compare(args.before, args.after))


if __name__ == "__main__":
    main()
