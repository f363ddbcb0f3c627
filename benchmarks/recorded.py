"""Measured output kept as documentation, so that the figures in the docs are the ones a script printed.

A benchmark or acceptance script run with ``--record`` prints as usual and also writes what it printed to
``docs/results/NAME.md``, headed by the command, the date and the machine (cores, processor, load average before and
after, library versions), plus the headline figures it names to ``docs/results/NAME.json``; then
``docs/benchmarks.md`` and the headline table of ``README.md`` are rendered anew from every recorded result
(:func:`render`). ``python benchmarks/recorded.py`` renders them without measuring; ``--check`` fails when the
rendered files differ from those on disk (the test suite runs it).
"""

from __future__ import annotations

import argparse
import contextlib
import datetime
import io
import json
import os
import platform
import shlex
import sys
from collections.abc import Iterator
from importlib import metadata
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "docs" / "results"
BENCHMARKS = ROOT / "docs" / "benchmarks.md"
README = ROOT / "README.md"
#: the order of the sections in docs/benchmarks.md (a result not listed comes after these, by name)
ORDER = ("stand_criteria", "bench_simulate", "bench_simulate_gpu", "accuracy_peak_to_peak",
         "accuracy_peak_to_peak_100ms", "accuracy_model", "accuracy_model_100ms",
         "accuracy_model_drop_stand_stiff", "independent_stand", "bench_identify", "bench_model", "bench_loop_latency",
         "bench_calibrate", "bench_response_map",
         "study_map_size", "study_map_recordings", "study_all", "study_absorption", "study_absorption_latency0ms_grid3",
         "study_absorption_latency1ms_grid3", "study_absorption_latency3ms_grid3", "study_absorption_oracle4ms",
         "study_absorber_design",
         "study_valve_design",
         "reliability_fuzz")
HEADLINE_START = "<!-- headline figures: rendered by benchmarks/recorded.py from docs/results/*.json -->"
HEADLINE_END = "<!-- end of headline figures -->"
LIBRARIES = ("numpy", "scipy", "numba", "h5py")


class _Tee(io.TextIOBase):
    def __init__(self, *streams):
        self.streams = streams

    def write(self, text: str) -> int:
        for stream in self.streams:
            stream.write(text)
        return len(text)

    def flush(self) -> None:
        for stream in self.streams:
            stream.flush()


class Record:
    """What a recorded run keeps besides its printed output: headline figures for the README's table."""

    def __init__(self) -> None:
        self.headlines: list[dict[str, str]] = []

    def headline(self, what: str, value: str, *, target: str = "") -> None:
        """A figure for the README's headline table: what was measured, the value (with its unit) and the goal."""
        self.headlines.append({"what": what, "value": value, "target": target})


def _machine() -> str:
    try:
        model = next(line.split(":", 1)[1].strip() for line in Path("/proc/cpuinfo").read_text().splitlines()
                     if line.startswith("model name"))
    except (OSError, StopIteration):
        model = platform.processor() or platform.machine()
    versions = ", ".join(f"{name} {_version(name)}" for name in LIBRARIES)
    return f"{os.cpu_count()} cores ({model}), Python {platform.python_version()}, {versions}"


def _version(name: str) -> str:
    try:
        return metadata.version(name)
    except metadata.PackageNotFoundError:
        return "absent"


def _load() -> str:
    try:
        return f"{os.getloadavg()[0]:.1f}"
    except OSError:
        return "unknown"


@contextlib.contextmanager
def recorded(name: str, title: str, record: bool, argv: list[str] | None = None) -> Iterator[Record]:
    """Run the block; with ``record`` keep what it printed as ``docs/results/NAME.md`` and re-render the docs.

    ``title`` heads the section in docs/benchmarks.md; ``argv`` (default: this process's) is the command shown.
    """
    result = Record()
    if not record:
        yield result
        return
    argv = list(sys.argv if argv is None else argv)
    script = Path(argv[0]).resolve()
    shown = [str(script.relative_to(ROOT)) if script.is_relative_to(ROOT) else argv[0],
             *[a for a in argv[1:] if a != "--record"]]
    buffer = io.StringIO()
    load_before, started = _load(), datetime.datetime.now(datetime.UTC)
    with contextlib.redirect_stdout(_Tee(sys.stdout, buffer)):
        yield result
    minutes = (datetime.datetime.now(datetime.UTC) - started).total_seconds() / 60
    header = (f"## {title}\n\n`python {shlex.join(shown)}` -- {started:%Y-%m-%d}, {minutes:.1f} min, load average "
              f"{load_before} before and {_load()} after; {_machine()}.\n\n")
    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / f"{name}.md").write_text(header + _as_markdown(buffer.getvalue()), encoding="utf-8")
    (RESULTS / f"{name}.json").write_text(json.dumps({"title": title, "headlines": result.headlines}, indent=1)
                                          + "\n", encoding="utf-8")
    render()


def _as_markdown(text: str) -> str:
    """Printed output as Markdown: tables and blank lines as they are, other lines kept as separate paragraphs."""
    lines, out = text.strip("\n").splitlines(), []
    for line in lines:
        if line.startswith("#"):
            out.extend(["", "#" + line.strip(), ""])  # a printed heading sits below the section's title
        elif line.startswith("|") or not line.strip():
            out.append(line)
        else:
            if out and out[-1].startswith("|"):
                out.append("")
            out.append(line + "  ")  # a hard line break: the printed lines stay lines
    return "\n".join(out).replace("\n\n\n", "\n\n").strip() + "\n"


def _names() -> list[str]:
    found = {p.stem for p in RESULTS.glob("*.md")}
    return [n for n in ORDER if n in found] + sorted(found - set(ORDER))


def rendered() -> tuple[str, str]:
    """(docs/benchmarks.md, README.md) as rendered from docs/results/."""
    names = _names()
    sections = [(RESULTS / f"{n}.md").read_text(encoding="utf-8") for n in names]
    contents = "\n".join(f"- [{json.loads((RESULTS / f'{n}.json').read_text())['title']}](#{_anchor(n)})"
                         for n in names)
    page = ("# Measured figures\n\nEvery table below is what a script printed when it was run with `--record`; the "
            "line under each title names the command, the date and the machine. Rendered by "
            "`python benchmarks/recorded.py` from `docs/results/`: edit the scripts, not this page.\n\n"
            f"{contents}\n\n" + "\n".join(f'<a id="{_anchor(n)}"></a>\n\n{text}'
                                            for n, text in zip(names, sections, strict=True)))
    rows = [h for n in names for h in json.loads((RESULTS / f"{n}.json").read_text())["headlines"]]
    table = "\n".join(["| figure | measured | goal |", "| --- | --- | --- |",
                       *[f"| {h['what']} | {h['value']} | {h['target']} |" for h in rows]])
    readme = README.read_text(encoding="utf-8")
    if HEADLINE_START in readme and HEADLINE_END in readme:
        head, rest = readme.split(HEADLINE_START, 1)
        readme = f"{head}{HEADLINE_START}\n{table}\n{HEADLINE_END}{rest.split(HEADLINE_END, 1)[1]}"
    return page, readme


def _anchor(name: str) -> str:
    return name.replace("_", "-")


def render() -> None:
    """Write docs/benchmarks.md and the README's headline table from docs/results/."""
    page, readme = rendered()
    BENCHMARKS.write_text(page, encoding="utf-8")
    README.write_text(readme, encoding="utf-8")


def main() -> int:
    parser = argparse.ArgumentParser(description="Render docs/benchmarks.md and the README's headline figures "
                                                 "from docs/results/.")
    parser.add_argument("--check", action="store_true", help="fail if the files on disk differ from the render")
    args = parser.parse_args()
    if args.check:
        page, readme = rendered()
        stale = [str(p.relative_to(ROOT)) for p, text in ((BENCHMARKS, page), (README, readme))
                 if not p.exists() or p.read_text(encoding="utf-8") != text]
        if stale:
            print(f"out of date: {', '.join(stale)}; run python benchmarks/recorded.py", file=sys.stderr)
            return 1
        return 0
    render()
    return 0


if __name__ == "__main__":
    sys.exit(main())
