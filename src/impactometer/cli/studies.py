"""``impactometer study NAME|all|list --out DIR``: the paper's studies, tables, figures and report."""

from __future__ import annotations

import json
import signal
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Annotated

import typer
from rich.markup import escape
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    SpinnerColumn,
    TextColumn,
    TimeElapsedColumn,
    TimeRemainingColumn,
)
from rich.table import Table
from rich.text import Text

from ..errors import ParameterError
from ..outputs import check_folder
from ..rig import get_rig
from ..studies import STUDIES, StudyOptions, available_studies, get_study, load_studies, run_studies
from ..studies.executors import check_backend
from ..studies.report import markdown, write_report
from .app import OVERWRITE, QuietProgress, app, console, error_console, given, quantity
from .simulate import ContactOpt


def _fraction(text: str, field: str) -> float:
    return quantity(text, "fraction", field)


def _print_list() -> None:
    load_studies()
    table = Table(title="studies")
    for column in ("name", "paper", "title", "settings (--set NAME.SETTING=JSON)", "status"):
        table.add_column(escape(column), overflow="fold")
    for name, study in STUDIES.items():
        missing = study.missing()
        defaults = {**study.defaults, "chunk_size": study.chunk_size}
        settings = ", ".join(f"{k}={json.dumps(_with_units(k, v))}" for k, v in defaults.items())
        table.add_row(name, study.figure or "–", study.title, settings,
                      "ready" if not missing else f"needs {', '.join(missing)}")
    console.print(table)


#: settings that carry a unit: shown with it (kPa, kHz, ms), and given with or without it (bare: SI)
SETTING_UNITS = {"pressures": ("pressure", "kPa", 1e3), "velocities": ("velocity", "m/s", 1.0),
                 "rates": ("frequency", "kHz", 1e3), "windows": ("time", "ms", 1e-3)}


def _with_units(key: str, value):
    """A setting as the list shows it: quantities as strings with a unit (``"20kPa"``)."""
    if key not in SETTING_UNITS or not isinstance(value, list):
        return value
    _, unit, scale = SETTING_UNITS[key]
    return [f"{v / scale:g}{unit}" for v in value]


def _parse_params(items: list[str] | None) -> dict:
    params = {}
    for item in items or []:
        key, sep, value = item.partition("=")
        if not sep or "." not in key:
            raise ParameterError(f"--set must look like STUDY.SETTING=VALUE (value in JSON), got {item!r}")
        try:
            params[key] = json.loads(value)
        except (ValueError, RecursionError):
            params[key] = value  # a bare word or a quantity with a unit ("20kPa"), checked by the study
    return params


def _with_methods(params: dict, methods: str | None, names: list[str]) -> dict:
    """``params`` with ``STUDY.methods`` set from ``--methods`` for each study of ``names`` that has the setting
    (unless ``--set`` gives it)."""
    if methods is None:
        return params
    having = {n: s.settings["methods"].choices for n, s in STUDIES.items() if "methods" in s.settings}
    takers = [n for n in names if n in having]
    if not takers:
        raise ParameterError(f"--methods: study {names[0]!r} compares no identification methods; the studies "
                             f"that do are {', '.join(having)}")
    known = having[takers[0]]
    chosen = [m.strip() for m in methods.split(",")]
    if not all(m in known for m in chosen):
        raise ParameterError(f"--methods must be a comma list of {', '.join(known)}, got {methods!r}")
    return {**{f"{n}.methods": chosen for n in takers}, **params}


class _BarOrDoing(BarColumn):
    """The bar of a study, or what it is doing while its first chunk is awaited (a study starts at 0 for a while:
    workers start, kernels compile)."""

    def render(self, task):
        doing = task.fields.get("doing")
        return Text(doing, overflow="fold") if doing else super().render(task)


class _Progress:
    """Progress of the studies on standard error: a bar per study with a count and, until its first chunk lands,
    what it is doing (starting workers, compiling kernels) on a terminal; elsewhere (a log, a pipe) plain lines:
    each thing it starts doing, every tenth of the cases, and the end of each study."""

    def __init__(self, names: list[str]) -> None:
        self.live = error_console.is_terminal
        self.bar = QuietProgress(SpinnerColumn(), TextColumn("{task.description:<14}"), MofNCompleteColumn(),
                                 TimeElapsedColumn(), TextColumn("ETA"), TimeRemainingColumn(), _BarOrDoing(),
                                 console=error_console, disable=not self.live, redirect_stdout=False,
                                 redirect_stderr=False)
        self.tasks = {n: self.bar.add_task(n, total=None, doing="") for n in names}
        self.said: dict[str, tuple[int, str]] = {}  # study -> (tenths of its cases said, last text said)
        self.start = time.perf_counter()

    def __enter__(self) -> _Progress:
        self.bar.start()
        return self

    def __exit__(self, *exc) -> None:
        self.stop()

    def stop(self) -> None:
        self.bar.stop()

    def _line(self, text: str) -> None:
        if not self.live:
            error_console.print(text, highlight=False, markup=False, soft_wrap=True)

    def progress(self, name: str, done: int, total: int) -> None:
        self.bar.update(self.tasks[name], completed=done, total=total)
        tenths, doing = self.said.get(name, (-1, ""))
        now = 10 * done // max(total, 1)
        if now > tenths:
            self.said[name] = (now, doing)
            elapsed = time.perf_counter() - self.start
            self._line(f"{name}: {done}/{total} cases{' done' if done == total else ''} ({elapsed:.0f} s)")

    def status(self, name: str, text: str) -> None:
        self.bar.update(self.tasks[name], doing=text)
        tenths, said = self.said.get(name, (-1, ""))
        if text and text != said:
            self.said[name] = (tenths, text)
            self._line(f"{name}: {text} ...")

    def notice(self, text: str) -> None:
        error_console.print(f"note: {text}", highlight=False, markup=False, soft_wrap=True)


class _Signals:
    terminated = False


@contextmanager
def _terminated_is_interrupted() -> Iterator[_Signals]:
    """SIGTERM (``kill``, a batch system ending the job) stops the run as Ctrl-C does: KeyboardInterrupt, so the
    workers are terminated and the folder's lock removed before the process exits."""
    signals = _Signals()
    if threading.current_thread() is not threading.main_thread():
        yield signals
        return

    def handler(number, frame) -> None:
        signals.terminated = True
        raise KeyboardInterrupt

    previous = signal.signal(signal.SIGTERM, handler)
    try:
        yield signals
    finally:
        signal.signal(signal.SIGTERM, previous)


@app.command()
def study(
    name: Annotated[str, typer.Argument(
        help="A study name, 'all', 'list' (show the studies) or 'report' (rebuild DIR/index.html, print Markdown).")],
    out: Annotated[Path | None, typer.Option("--out", help="Output folder (tables, figures, index.html).")] = None,
    workers: Annotated[int | None, typer.Option("--workers", help="Local processes (default: all cores).")] = None,
    scheduler: Annotated[str | None, typer.Option(
        "--scheduler", help="Run on a Dask cluster: scheduler address tcp://HOST:PORT.")] = None,
    seed: Annotated[int, typer.Option("--seed", help="Root seed of every noise realisation.")] = 0,
    seeds: Annotated[int, typer.Option("--seeds", help="Noise realisations per case.")] = 1,
    grid: Annotated[int | None, typer.Option(
        "--grid", help="Values per axis of the M1×V0×p0 grid (5: the paper's 125 cases; default: per study).")]
    = None,
    noise: Annotated[str, typer.Option("--noise", metavar="FRACTION",
                                       help="Sensor noise of the non-noise studies (% of RMS).")] = "1%",
    sample_rate: Annotated[str, typer.Option("--sample-rate", metavar="FREQUENCY",
                                             help="DAQ rate of the non-sampling studies.")] = "50kHz",
    duration: Annotated[str, typer.Option("--duration", metavar="TIME", help="Record length after first contact.")]
    = "100ms",
    pre_trigger: Annotated[str, typer.Option("--pre-trigger", metavar="TIME",
                                             help="Record length before first contact.")] = "50ms",
    contact: ContactOpt = None,
    rig: Annotated[str | None, typer.Option(
        "--rig", metavar="STAND", help="Stand: a preset name or a TOML file (default: drop-stand, the pad stand; "
                                       "a study with a stand of its own uses it).")] = None,
    setting: Annotated[list[str] | None, typer.Option(
        "--set", help="Study setting STUDY.SETTING=JSON, e.g. noise.levels=[0,0.05] (repeatable).")] = None,
    methods: Annotated[str | None, typer.Option(
        "--methods", metavar="LIST", help="Identification methods of the studies that compare them (noise, "
                                          "sampling): a comma list of paper, robust, model (default: all three; "
                                          "model is the dearest). STUDY.methods in --set wins.")] = None,
    force: Annotated[bool, typer.Option(*OVERWRITE, help="Discard runs with other options; overwrite files.")]
    = False,
    device: Annotated[str, typer.Option(
        "--device", help="Where batches of simulations run: cpu, gpu (extra impactometer[gpu]) or auto (the GPU when "
                         "usable); local workers inherit it, Dask workers read IMPACTOMETER_DEVICE.")] = "cpu",
) -> None:
    """Run a study of the paper (or all of them): tables (CSV), figures (PNG) and DIR/index.html."""
    if name == "list":
        _print_list()
        return
    if out is None:
        raise ParameterError("--out is required: the folder for the tables, figures and index.html")
    check_folder(out, "--out")
    with given(workers=workers, scheduler=scheduler):
        check_backend(workers, scheduler)
    if name == "report":
        path = write_report(out, force=force)
        console.print(markdown(out), highlight=False, markup=False, soft_wrap=True)
        console.print(f"report written to {path}")
        return
    from ..model.gpu import resolve_device, use_device  # lazily: loads numba, which --help must not

    with given(device=device):
        device = resolve_device(device)  # a bad or unusable device fails before any study starts
    load_studies()
    if name == "all":
        names = available_studies()
        for skipped, study_obj in STUDIES.items():
            if skipped not in names:
                console.print(f"skipped study {skipped}: needs {', '.join(study_obj.missing())}")
    else:
        get_study(name)
        names = [name]
    params = _with_methods(_parse_params(setting), methods, names)
    with given(rig=rig, contact=contact, seed=seed, seeds=seeds, grid=grid, noise=noise, sample_rate=sample_rate,
               duration=duration, pre_trigger=pre_trigger):
        options = StudyOptions(rig=get_rig(rig, contact=contact), seed=seed, seeds=seeds, grid=grid,
                               noise=_fraction(noise, "--noise"),
                               sample_rate=quantity(sample_rate, "frequency", "--sample-rate"),
                               duration=quantity(duration, "time", "--duration"),
                               pre_trigger=quantity(pre_trigger, "time", "--pre-trigger"),
                               params=params, rig_is_default=rig is None and contact is None)
    start = time.perf_counter()
    report_found = (out / "index.html").exists()
    with _Progress(names) as bar, _terminated_is_interrupted() as signals:
        try:
            with use_device(device):
                runs = run_studies(names, out, options, workers=workers, scheduler=scheduler, force=force,
                                   progress=bar.progress, status=bar.status, notice=bar.notice)
        except KeyboardInterrupt:
            bar.stop()
            error_console.print(f"interrupted: the finished chunks are kept in {out}; rerun the same command to "
                                "resume", highlight=False, markup=False, soft_wrap=True)
            if signals.terminated:
                raise typer.Exit(128 + signal.SIGTERM) from None
            raise typer.Abort() from None
    # the folder on a line of its own (printed whole), the files in the table by name: a path is never broken
    console.print(f"studies in {out} ({time.perf_counter() - start:.1f} s)", highlight=False, markup=False)
    table = Table()
    for column in ("study", "cases", "reused chunks", "wall [s]", "compute [s]", "table", "files"):
        table.add_column(escape(column), overflow="fold",
                         justify="left" if column in ("study", "table", "files") else "right")
    for run in runs:
        table.add_row(run.name, str(run.cases), f"{run.reused_chunks}/{run.chunks}", f"{run.wall_time:.1f}",
                      f"{run.compute_time:.1f}", run.table.name, "kept (finished earlier)" if run.kept else "written")
    console.print(table)
    if all(run.kept for run in runs) and report_found and not force:
        console.print(f"finished earlier with these options: tables, figures and report {out / 'index.html'} kept "
                      "(--overwrite rewrites them)")
    else:
        console.print(f"report written to {out / 'index.html'}")
