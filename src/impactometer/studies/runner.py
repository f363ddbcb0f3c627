"""Run studies: fixed chunks of cases, evaluated in this process, a local process pool or a Dask cluster.

Finished chunks are persisted as they complete (see :mod:`.store`), so a rerun skips them. The chunks and every
case's random numbers are fixed by the options, never by the number of workers, so the tables are identical
whatever runs them.
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import ImpactometerError, ParameterError, SimulationError
from ..outputs import check_folder
from ..validation import check_integer
from . import store
from .base import Row, StudyOptions, indexed_cases, options_for
from .registry import STUDIES, get_study, load_studies
from .report import check_target, write_report
from .tables import to_csv

Task = tuple[int, list[Row]]


@dataclass(frozen=True, kw_only=True)
class StudyRun:
    """Outcome of one study run: the tidy table, where it was written and how long it took.

    ``wall_time`` is the time of this invocation [s]; ``compute_time`` the sum of the chunks' evaluation
    times [s], including chunks reused from an earlier run.
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


def evaluate_chunk(name: str, cases: list[Row], options: StudyOptions) -> tuple[list[Row], float]:
    """Evaluate one chunk of study ``name`` (module-level, so process pools and Dask workers can call it)."""
    load_studies()
    start = time.perf_counter()
    try:
        rows = [_plain(row) for row in get_study(name).evaluate(cases, options)]
    except ImpactometerError as exc:
        where = f"cases {cases[0]['case']}-{cases[-1]['case']}" if cases else "no cases"
        raise type(exc)(f"study {name!r}, {where}: {exc}") from exc
    return rows, time.perf_counter() - start


def _plain(row: Row) -> Row:
    """Row with numpy scalars turned into Python numbers (JSON-ready)."""
    out = {}
    for key, value in row.items():
        if isinstance(value, np.generic):
            value = value.item()
        out[key] = value
    return out


def _init_worker() -> None:  # pragma: no cover - runs in pool processes
    """One numba thread per pool process (the pool provides the parallelism)."""
    import numba

    numba.set_num_threads(1)


class _Serial:
    """Evaluate tasks one after the other in this process."""

    workers = 1

    def run(self, name: str, tasks: Sequence[Task], options: StudyOptions) -> Iterator[tuple[int, Any]]:
        for index, cases in tasks:
            yield index, evaluate_chunk(name, cases, options)

    def close(self) -> None:
        pass


class _Pool:
    """A local process pool (spawned processes, one numba thread each)."""

    def __init__(self, workers: int) -> None:
        import multiprocessing

        self.workers = workers
        self.pool = ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("spawn"),
                                        initializer=_init_worker)

    def run(self, name: str, tasks: Sequence[Task], options: StudyOptions) -> Iterator[tuple[int, Any]]:
        pending = {self.pool.submit(evaluate_chunk, name, cases, options): index for index, cases in tasks}
        try:
            while pending:
                done, _ = wait(pending, return_when=FIRST_COMPLETED)
                for future in done:
                    index = pending.pop(future)
                    try:
                        result = future.result()
                    except BrokenProcessPool:
                        raise SimulationError(f"a worker process died while running study {name!r} (out of memory?); "
                                              "finished chunks are kept: rerun to resume, with fewer --workers "
                                              "if memory is short") from None
                    yield index, result
        finally:
            for future in pending:
                future.cancel()

    def close(self) -> None:
        self.pool.shutdown(wait=True, cancel_futures=True)


class _Dask:
    """An existing Dask distributed cluster reached through its scheduler address."""

    def __init__(self, address: str) -> None:
        try:
            from dask.distributed import Client
        except ImportError:
            raise ParameterError("--scheduler needs Dask distributed; install the extra: "
                                 "pip install 'impactometer[dask]'") from None
        try:
            self.client = Client(address, timeout="5s", set_as_default=False)
        except (OSError, TimeoutError, ValueError) as exc:
            raise ParameterError(f"--scheduler: cannot connect to {address!r} ({exc}); expected the address of a "
                                 f"running Dask scheduler, e.g. tcp://HOST:8786") from None
        self.workers = max(1, sum(self.client.nthreads().values()))

    def run(self, name: str, tasks: Sequence[Task], options: StudyOptions) -> Iterator[tuple[int, Any]]:
        from dask.distributed import as_completed

        futures = {self.client.submit(evaluate_chunk, name, cases, options, pure=False): index
                   for index, cases in tasks}
        try:
            for future in as_completed(list(futures), loop=self.client.loop):
                yield futures[future], future.result()
        finally:
            for future in futures:
                future.cancel()

    def close(self) -> None:
        self.client.close()


#: address schemes of a Dask scheduler reachable from another process
SCHEDULER_SCHEMES = ("tcp", "tls", "ws", "wss", "ucx")


def check_backend(workers: int | None = None, scheduler: str | None = None) -> None:
    """ParameterError unless ``workers`` (an integer >= 1) or ``scheduler`` (``tcp://HOST:PORT``) is well formed;
    nothing is started or contacted."""
    if scheduler is not None:
        if workers is not None:
            raise ParameterError(f"give either --workers or --scheduler, got workers={workers!r} and "
                                 f"scheduler={scheduler!r}")
        scheme, _, rest = scheduler.partition("://") if isinstance(scheduler, str) else ("", "", "")
        host, _, port = rest.rpartition(":")
        if scheme not in SCHEDULER_SCHEMES or not host or not port.isdigit() or not 0 < int(port) < 65536:
            raise ParameterError(f"--scheduler must be an address like tcp://HOST:PORT (scheme "
                                 f"{', '.join(SCHEDULER_SCHEMES)}), got {scheduler!r}")
    elif workers is not None:
        check_integer("--workers", workers, low=1)


def backend(workers: int | None = None, scheduler: str | None = None):
    """The executor for ``workers`` local processes (default: all cores) or a Dask ``scheduler`` address."""
    check_backend(workers, scheduler)
    if scheduler is not None:
        return _Dask(scheduler)
    if workers is None:
        workers = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1
    return _Serial() if workers == 1 else _Pool(workers)


def run_study(name: str, out: str | Path, options: StudyOptions | None = None, *, workers: int | None = None,
              scheduler: str | None = None, force: bool = False, progress: Callable | None = None,
              executor=None) -> StudyRun:
    """Run study ``name`` into folder ``out`` (resuming from finished chunks) and write its table and figure.

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
        Discard chunks of a run with other options and overwrite tables not written by a study run.
    progress : callable, optional
        ``progress(name, done_cases, total_cases)`` called as chunks finish.
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
    with store.locked(out):
        return _run_locked(name, study, out, options, start, workers=workers, scheduler=scheduler, force=force,
                           progress=progress, executor=executor)


def _run_locked(name, study, out: Path, options: StudyOptions, start: float, *, workers, scheduler, force,
                progress, executor) -> StudyRun:
    """:func:`run_study` in ``out``, whose lock the caller holds."""
    key = options.key(name)
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
    try:
        for index, (rows, seconds) in (runner.run(name, tasks, options) if tasks else ()):
            store.write_chunk(folder, study=name, key=key, index=index, cases=chunks[index], rows=rows,
                              seconds=seconds)
            results[index] = (rows, seconds)
            done += len(chunks[index])
            if progress:
                progress(name, done, len(cases))
    finally:
        if own:
            runner.close()
    rows = [row for i in range(len(chunks)) for row in results[i][0]]
    table = store.atomic_write(out / f"{name}.csv", to_csv(rows))
    figure = store.save_figure(study.plot(rows, options), out / f"{name}.png")
    compute = math.fsum(results[i][1] for i in results)
    run = StudyRun(name=name, rows=rows, table=table, figure=figure, cases=len(cases), chunks=len(chunks),
                   reused_chunks=reused, wall_time=time.perf_counter() - start, compute_time=compute)
    store.write_result(folder, {
        "name": name, "title": study.title, "figure": study.figure, "cases": len(cases), "rows": len(rows),
        "chunks": len(chunks), "reused_chunks": reused, "wall_time": run.wall_time, "compute_time": compute,
        "workers": getattr(runner, "workers", 1) if tasks else 0, "options": options.to_dict(),
        "aggregate": [_plain(r) for r in study.aggregate(rows)], "summary": study.summary(rows)})
    return run


def run_studies(names: Sequence[str], out: str | Path, options: StudyOptions | None = None, *,
                workers: int | None = None, scheduler: str | None = None, force: bool = False,
                progress: Callable | None = None, report: bool = True) -> list[StudyRun]:
    """Run several studies with one executor, then write ``out/index.html`` (see :func:`run_study`)."""
    load_studies()
    names = list(names)
    for name in names:
        get_study(name)
    check_folder(out, "--out")
    with store.locked(Path(out)):
        if report:
            check_target(out, force=force)
        executor = backend(workers, scheduler)
        try:
            runs = [run_study(name, out, options, force=force, progress=progress, executor=executor)
                    for name in names]
        finally:
            executor.close()
        if report:
            write_report(out, force=force)
    return runs


def available_studies() -> list[str]:
    """Registered studies whose dependencies are importable, in registry order."""
    load_studies()
    return [name for name, study in STUDIES.items() if not study.missing()]
