"""Run one study of the paper (or all of them) as the command line does and print its run and summary tables.

    python scripts/record_study.py all                        # impactometer study all, default sizes
    python scripts/record_study.py absorption --grid 5        # any option of `impactometer study` after the name
    python scripts/record_study.py absorption --grid 5 --record   # ... kept in docs/results/ and docs/benchmarks.md
    python scripts/record_study.py absorption --grid 3 --set absorption.latency=3ms --as latency3ms_grid3 --record
                                                              # ... kept beside it as study_absorption_latency3ms_grid3
    python scripts/record_study.py absorption --grid 5 --workers 2 --set absorption.policy=early --as policy_early \
        --headlines --record                                  # a labelled record that gives the README's rows too

The study runs in a temporary folder with ``impactometer study NAME --out FOLDER [OPTIONS]`` (its progress on
standard error) and the tables printed are those of ``impactometer study report``.
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))  # benchmarks/recorded.py

from impactometer.studies.report import collect, markdown, summary_rows  # noqa: E402
from recorded import recorded  # noqa: E402

#: summary lines of a study that head the README's table: study -> (start of the quantity, the goal)
HEADLINES = {"absorption": (("R_B of the predictive strategy", "median <= 1.2, p90 <= 1.5"),
                            ("identification answered within 10 ms", ">= 90 %"),
                            ("whole event: 90th percentile", "<= 3 (design target)"))}
TITLES = {"all": "Studies of the paper (Figs. 3-9, 10), default sizes",
          "absorption": "Adaptive absorption: strategies over the impact grid",
          "valve-design": "Adaptive absorption: valve size and response",
          "absorber-design": "Absorber design: pre-charge × pad × valve × piston mass",
          "map-size": "Response map: map size and search (Fig. 8 analogue)",
          "map-recordings": "Response map built from recordings"}


def _policy(name: str, options: list[str]) -> str:
    """The absorber's policy a headline row was measured with, as the row names it (", policy early, the default")."""
    if name != "absorption":
        return ""
    from impactometer.studies.absorption import DEFAULTS
    default = DEFAULTS["policy"]
    given = [o.split("=", 1)[1] for o in options if o.startswith("absorption.policy=")]
    policy = given[-1] if given else default
    return f", policy {policy}" + (", the default" if policy == default else "")


def main(argv: list[str]) -> int:
    if not argv or argv[0].startswith("-"):
        print(__doc__, file=sys.stderr)
        return 2
    record = "--record" in argv
    headlines = "--headlines" in argv  # a labelled record gives the README's headline rows too
    name, options = argv[0], [a for a in argv[1:] if a not in ("--record", "--headlines")]
    label = ""
    if "--as" in options:  # a second record of the same study (a what-if), kept under its own name
        at = options.index("--as")
        if at + 1 >= len(options):
            print("--as needs a name", file=sys.stderr)
            return 2
        label = options[at + 1]
        options = options[:at] + options[at + 2:]
    title = TITLES.get(name, f"Study {name}") + (f" ({' '.join(o for o in options if '=' in o)})" if label else "")
    with tempfile.TemporaryDirectory(prefix="impactometer-study-") as folder:
        command = [sys.executable, "-m", "impactometer", "study", name, "--out", folder, *options]
        with recorded(f"study_{name.replace('-', '_')}" + (f"_{label}" if label else ""), title, record,
                      argv=[sys.argv[0], *argv]) as kept:
            done = subprocess.run(command, stdout=subprocess.DEVNULL, check=False)
            if done.returncode != 0:
                raise SystemExit(done.returncode)  # nothing recorded
            print(f"`impactometer study {name} {' '.join(options)}`; run and summary tables of "
                  "`impactometer study report`:\n")
            print(markdown(folder))
            for line in summary_rows(collect(folder)):
                wanted = line["study"] == name and (headlines or not label)
                for start, goal in HEADLINES.get(line["study"], ()) if wanted else ():
                    if str(line.get("quantity", "")).startswith(start):
                        kept.headline(f"{line['study']} ({' '.join(options)}{_policy(name, options)}): "
                                      f"{line['quantity']}", str(line["ours"]), target=goal)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
