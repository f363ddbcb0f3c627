"""``impactometer study NAME|all|list --out DIR``: the paper's studies, tables, figures and report."""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Annotated

import typer
from rich.markup import escape
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn
from rich.table import Table

from ..errors import ParameterError
from ..outputs import check_folder
from ..rig import get_rig
from ..studies import STUDIES, StudyOptions, available_studies, get_study, load_studies, run_studies
from ..studies.report import markdown, write_report
from ..studies.runner import check_backend
from .app import OVERWRITE, app, console, given, quantity
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
    with given(rig=rig, contact=contact, seed=seed, seeds=seeds, grid=grid, noise=noise, sample_rate=sample_rate,
               duration=duration, pre_trigger=pre_trigger):
        options = StudyOptions(rig=get_rig(rig, contact=contact), seed=seed, seeds=seeds, grid=grid,
                               noise=_fraction(noise, "--noise"),
                               sample_rate=quantity(sample_rate, "frequency", "--sample-rate"),
                               duration=quantity(duration, "time", "--duration"),
                               pre_trigger=quantity(pre_trigger, "time", "--pre-trigger"),
                               params=_parse_params(setting), rig_is_default=rig is None and contact is None)
    columns = (TextColumn("{task.description:<14}"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
               TextColumn("ETA"), TimeRemainingColumn())
    start = time.perf_counter()
    with Progress(*columns, console=console, transient=False) as bar:
        tasks = {n: bar.add_task(n, total=None) for n in names}

        def progress(study_name: str, done: int, total: int) -> None:
            bar.update(tasks[study_name], completed=done, total=total)

        try:
            with use_device(device):
                runs = run_studies(names, out, options, workers=workers, scheduler=scheduler, force=force,
                                   progress=progress)
        except KeyboardInterrupt:
            console.print(f"interrupted: the finished chunks are kept in {out}; rerun the same command to resume")
            raise typer.Abort() from None
    table = Table(title=f"studies in {out} ({time.perf_counter() - start:.1f} s)")
    for column in ("study", "cases", "reused chunks", "wall [s]", "compute [s]", "table"):
        table.add_column(escape(column), overflow="fold", justify="left" if column in ("study", "table") else "right")
    for run in runs:
        table.add_row(run.name, str(run.cases), f"{run.reused_chunks}/{run.chunks}", f"{run.wall_time:.1f}",
                      f"{run.compute_time:.1f}", str(run.table))
    console.print(table)
    console.print(f"report written to {out / 'index.html'}")
