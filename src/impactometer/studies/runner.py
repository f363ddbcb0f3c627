"""Run studies: fixed chunks of cases, evaluated where :mod:`.executors` says (this process, a local process pool
or a Dask cluster).

Finished chunks are persisted as they complete (see :mod:`.store`), so a rerun skips them. The chunks and every
case's random numbers are fixed by the options, never by the number of workers, so the tables are identical
whatever runs them. A rerun keeps the table and figure of a study it finds finished (same options) and writes only
what is missing; ``force`` rewrites them.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from contextlib import nullcontext
from dataclasses import dataclass
from pathlib import Path

from ..errors import ParameterError
from ..outputs import check_folder, save_figure
from ..tables import to_csv
from . import store
from .base import STUDIES, Row, StudyOptions, get_study, indexed_cases, load_studies, options_for
from .executors import Status, backend, closing_executor, plain_row
from .report import check_target, write_report

__all__ = ["StudyRun", "available_studies", "run_studies", "run_study"]


@dataclass(frozen=True, kw_only=True)
class StudyRun:
    """Outcome of one study run: the tidy table, where it was written and how long it took.

    ``wall_time`` is the time of this invocation [s]; ``compute_time`` the sum of the chunks' evaluation
    times [s], including chunks reused from an earlier run. ``kept`` is True when the table and figure of an
    earlier, finished run with the same options were found and left as they were.
    """

    name: str
    rows: list[Row]
    table: Path
    figure: Path
    cases: int
    chunks: int
    reused_chunks: int
    wall_time: float
    compute_time: float
    kept: bool = False


def run_study(name: str, out: str | Path, options: StudyOptions | None = None, *, workers: int | None = None,
              scheduler: str | None = None, force: bool = False, progress: Callable | None = None,
              status: Status | None = None, notice: Callable[[str], None] | None = None,
              executor=None) -> StudyRun:
    """Run study ``name`` into folder ``out`` (resuming from finished chunks) and write its table and figure.

    A table and figure that an earlier run with the same options finished are kept as they are (the returned run
    says ``kept``); missing ones are written.

    Parameters
    ----------
    name : str
        A registered study (see :data:`impactometer.studies.STUDIES`).
    out : path
        Output folder (created if missing).
    options : StudyOptions, optional
        Stand, grid, seeds, noise, ... (defaults: each study's default size on the built-in stand).
    workers : int, optional
        Local processes (default: all cores; 1 runs in this process).
    scheduler : str, optional
        Address of a Dask scheduler (``tcp://HOST:PORT``) to run the chunks on instead.
    force : bool
        Discard chunks of a run with other options and overwrite tables and figures, also those of an earlier run
        and those not written by a study run.
    progress : callable, optional
        ``progress(name, done_cases, total_cases)`` called as chunks finish.
    status : callable, optional
        ``status(name, text)``: what the run is doing until its first chunk lands (starting workers, compiling
        kernels), ``""`` once chunks flow.
    notice : callable, optional
        ``notice(text)`` for a one-line note (a stale lock of a killed run removed); default: a warning.
    executor : optional
        An executor from :func:`backend` to reuse (then ``workers`` and ``scheduler`` are ignored).

    Returns
    -------
    StudyRun
    """
    load_studies()
    study = get_study(name)
    missing = study.missing()
    if missing:
        raise ParameterError(f"study {name!r} needs {', '.join(missing)}, which is not available in this install")
    options = StudyOptions() if options is None else options
    if not isinstance(options, StudyOptions):
        raise ParameterError(f"options must be StudyOptions, got {options!r}")
    options = options_for(study, options)
    start = time.perf_counter()
    out = check_folder(out, "--out")
    with store.locked(out, notice=notice):
        return _run_locked(name, study, out, options, start, workers=workers, scheduler=scheduler, force=force,
                           progress=progress, status=status, executor=executor)


def _run_locked(name, study, out: Path, options: StudyOptions, start: float, *, workers, scheduler, force,
                progress, status, executor) -> StudyRun:
    """:func:`run_study` in ``out``, whose lock the caller holds."""
    key = options.key(name)
    finished = not force and store.finished(out, name, key)
    folder = store.prepare_folder(out, name, key, options.to_dict(), force=force)
    cases = indexed_cases(study, options)
    size = options.param(name, "chunk_size", study.chunk_size)  # checked with the options
    chunks = [cases[i:i + size] for i in range(0, len(cases), size)]
    results: dict[int, tuple[list[Row], float]] = {}
    for index, chunk in enumerate(chunks):
        found = store.read_chunk(folder, study=name, key=key, index=index, cases=chunk)
        if found is not None:
            results[index] = (found["rows"], float(found["seconds"]))
    reused = len(results)
    done = sum(len(chunks[i]) for i in results)
    if progress:
        progress(name, done, len(cases))
    tasks = [(i, chunk) for i, chunk in enumerate(chunks) if i not in results]
    own = executor is None and tasks
    runner = backend(workers, scheduler) if own else executor
    with closing_executor(runner) if own else nullcontext():
        for index, (rows, seconds) in (runner.run(name, tasks, options, status) if tasks else ()):
            store.write_chunk(folder, study=name, key=key, index=index, cases=chunks[index], rows=rows,
                              seconds=seconds)
            results[index] = (rows, seconds)
            done += len(chunks[index])
            if progress:
                progress(name, done, len(cases))
    rows = [row for i in range(len(chunks)) for row in results[i][0]]
    table, figure = out / f"{name}.csv", out / f"{name}.png"
    kept = finished and not tasks and table.exists() and figure.exists()
    if not (finished and table.exists()):
        store.atomic_write(table, to_csv(rows))
    if not (finished and figure.exists()):
        save_figure(study.drawing(rows, options).plot(), figure, dpi=110)
    compute = math.fsum(results[i][1] for i in results)
    run = StudyRun(name=name, rows=rows, table=table, figure=figure, cases=len(cases), chunks=len(chunks),
                   reused_chunks=reused, wall_time=time.perf_counter() - start, compute_time=compute, kept=kept)
    if not kept:
        store.write_result(folder, {
            "name": name, "title": study.title, "figure": study.figure, "cases": len(cases), "rows": len(rows),
            "chunks": len(chunks), "reused_chunks": reused, "wall_time": run.wall_time, "compute_time": compute,
            "workers": getattr(runner, "workers", 1) if tasks else 0, "options": options.to_dict(),
            "aggregate": [plain_row(r) for r in study.aggregate(rows)], "summary": study.summary(rows)})
    return run


def run_studies(names: Sequence[str], out: str | Path, options: StudyOptions | None = None, *,
                workers: int | None = None, scheduler: str | None = None, force: bool = False,
                progress: Callable | None = None, status: Status | None = None,
                notice: Callable[[str], None] | None = None, report: bool = True) -> list[StudyRun]:
    """Run several studies with one executor, then write ``out/index.html`` (see :func:`run_study`).

    The report is rewritten when a study wrote something or when it is missing; when every study was kept, an
    existing report is kept too.
    """
    load_studies()
    names = list(names)
    for name in names:
        get_study(name)
    check_folder(out, "--out")
    with store.locked(Path(out), notice=notice):
        page = check_target(out, force=force) if report else None
        with closing_executor(backend(workers, scheduler)) as executor:  # local processes start with the first chunk
            runs = [run_study(name, out, options, force=force, progress=progress, status=status, executor=executor)
                    for name in names]
        if page is not None and (force or not page.exists() or not all(run.kept for run in runs)):
            write_report(out, force=force)
    return runs


def available_studies() -> list[str]:
    """Registered studies whose dependencies are importable, in registry order."""
    load_studies()
    return [name for name, study in STUDIES.items() if not study.missing()]
