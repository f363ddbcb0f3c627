"""Run studies: fixed chunks of cases, evaluated in this process, a local process pool or a Dask cluster.

Finished chunks are persisted as they complete (see :mod:`.store`), so a rerun skips them. The chunks and every
case's random numbers are fixed by the options, never by the number of workers, so the tables are identical
whatever runs them. A rerun keeps the table and figure of a study it finds finished (same options) and writes only
what is missing; ``force`` rewrites them.

Local worker processes exit with their parent: stopped (an exception, Ctrl-C, SIGTERM turned into one by the
command line), the run terminates them; killed (SIGKILL), each worker notices that its parent is gone and exits.
"""

from __future__ import annotations

import math
import os
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from contextlib import contextmanager, nullcontext
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
#: ``status(name, text)``: what a study run is doing before its chunks flow ("" once they do)
Status = Callable[[str, str], None]

#: compile time of the kernels of a study on a cold numba cache (every worker compiles its own), measured on 2 cores
COMPILE_TIME = "about 20-90 s"


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


def _compile_listener(callback: Callable[[], None]):
    """A numba event listener that calls ``callback()`` when the first compilation starts (a kernel found in
    numba's cache is loaded, not compiled, and calls nothing)."""
    from numba.core import event

    class Listener(event.Listener):
        called = False

        def on_start(self, ev) -> None:
            if not self.called:
                self.called = True
                callback()

        def on_end(self, ev) -> None:
            pass

    return Listener()


@contextmanager
def compiling(callback: Callable[[], None]) -> Iterator[None]:
    """Call ``callback()`` once if numba starts compiling a kernel in this process while the block runs."""
    from numba.core import event

    with event.install_listener("numba:compile", _compile_listener(callback)):
        yield


def _init_worker(events) -> None:  # pragma: no cover - runs in pool processes
    """Set up a pool process: exit with the parent, leave Ctrl-C to it, one numba thread (the pool provides the
    parallelism), and tell the parent through ``events`` that it is ready and when it starts compiling."""
    import multiprocessing
    import signal

    import numba
    from numba.core import event

    parent = multiprocessing.parent_process()
    if parent is not None:
        threading.Thread(target=_exit_with, args=(parent,), name="impactometer-parent-watch", daemon=True).start()
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C reaches the whole process group; the parent stops us
    numba.set_num_threads(1)
    global _worker_listener
    _worker_listener = _compile_listener(lambda: events.put("compiling"))
    event.register("numba:compile", _worker_listener)  # for the process's life
    events.put("ready")


_worker_listener = None  # a pool process's compile listener: says "compiling" at most once per chunk


def _evaluate_in_worker(name: str, cases: list[Row], options: StudyOptions) -> tuple[list[Row], float]:
    """:func:`evaluate_chunk` in a pool process (a chunk that compiles kernels says so once)."""
    if _worker_listener is not None:
        _worker_listener.called = False
    return evaluate_chunk(name, cases, options)


def _exit_with(parent) -> None:  # pragma: no cover - runs in pool processes
    """Wait for the parent process to end (its sentinel closes when it dies, however it dies), then exit: a killed
    run leaves no worker behind, blocked on a queue that will never be fed."""
    parent.join()
    os._exit(1)


class _Serial:
    """Evaluate tasks one after the other in this process."""

    workers = 1

    def run(self, name: str, tasks: Sequence[Task], options: StudyOptions,
            status: Status | None = None) -> Iterator[tuple[int, Any]]:
        def compiling_now() -> None:
            if status:
                status(name, f"compiling kernels (first run only, {COMPILE_TIME})")

        for index, cases in tasks:
            with compiling(compiling_now):
                result = evaluate_chunk(name, cases, options)
            if status:
                status(name, "")
            yield index, result

    def close(self, abort: bool = False) -> None:
        pass


class _Pool:
    """A local process pool (spawned processes, one numba thread each, that exit with this process)."""

    #: seconds between looks at the workers' messages while no chunk finishes
    poll = 0.2

    def __init__(self, workers: int) -> None:
        import multiprocessing

        context = multiprocessing.get_context("spawn")
        self.workers = workers
        self.events = context.SimpleQueue()  # "ready" and "compiling" from the workers
        self.ready = 0
        self.compiling = False
        self.pool = ProcessPoolExecutor(max_workers=workers, mp_context=context, initializer=_init_worker,
                                        initargs=(self.events,))

    def _read(self) -> None:
        """Read the workers' messages (a few per chunk at most: read as chunks land, the pipe never fills)."""
        while not self.events.empty():
            message = self.events.get()
            self.ready += message == "ready"
            self.compiling |= message == "compiling"

    def _phase(self, name: str, status: Status | None) -> None:
        """Say what the pool is doing until the first chunk of study ``name`` lands."""
        if status is None:
            return
        if self.compiling:
            status(name, f"compiling kernels in {self.workers} workers (first run only, {COMPILE_TIME})")
        elif not self.ready:
            status(name, f"starting {self.workers} worker processes")
        else:
            status(name, "running the first chunks")

    def run(self, name: str, tasks: Sequence[Task], options: StudyOptions,
            status: Status | None = None) -> Iterator[tuple[int, Any]]:
        pending = {self.pool.submit(_evaluate_in_worker, name, cases, options): index for index, cases in tasks}
        waiting = True  # for the first chunk
        self.compiling = False
        try:
            while pending:
                self._read()
                if waiting:
                    self._phase(name, status)
                done, _ = wait(pending, timeout=self.poll if waiting else None, return_when=FIRST_COMPLETED)
                if done and waiting:
                    waiting = False
                    if status:
                        status(name, "")
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

    def close(self, abort: bool = False) -> None:
        """Shut the pool down: after the running chunks finish, or at once (``abort``: terminate the workers)."""
        if abort:
            for process in list((getattr(self.pool, "_processes", None) or {}).values()):
                process.terminate()
        self.pool.shutdown(wait=True, cancel_futures=True)
        self.events.close()


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

    def run(self, name: str, tasks: Sequence[Task], options: StudyOptions,
            status: Status | None = None) -> Iterator[tuple[int, Any]]:
        from dask.distributed import as_completed

        futures = {self.client.submit(evaluate_chunk, name, cases, options, pure=False): index
                   for index, cases in tasks}
        if status:
            status(name, f"waiting for the first chunks from the cluster ({self.workers} threads; a first run "
                         "compiles kernels on every worker)")
        try:
            for number, future in enumerate(as_completed(list(futures), loop=self.client.loop)):
                if number == 0 and status:
                    status(name, "")
                yield futures[future], future.result()
        finally:
            for future in futures:
                future.cancel()

    def close(self, abort: bool = False) -> None:
        self.client.close()


@contextmanager
def _closing(executor) -> Iterator[Any]:
    """``executor`` for the block, closed after it: at once (its workers terminated) when the block raised or was
    interrupted (Ctrl-C, or SIGTERM turned into KeyboardInterrupt), else after its last chunk."""
    try:
        yield executor
    except BaseException:
        executor.close(abort=True)
        raise
    executor.close()


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
    with _closing(runner) if own else nullcontext():
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
        store.save_figure(study.plot(rows, options), figure)
    compute = math.fsum(results[i][1] for i in results)
    run = StudyRun(name=name, rows=rows, table=table, figure=figure, cases=len(cases), chunks=len(chunks),
                   reused_chunks=reused, wall_time=time.perf_counter() - start, compute_time=compute, kept=kept)
    if not kept:
        store.write_result(folder, {
            "name": name, "title": study.title, "figure": study.figure, "cases": len(cases), "rows": len(rows),
            "chunks": len(chunks), "reused_chunks": reused, "wall_time": run.wall_time, "compute_time": compute,
            "workers": getattr(runner, "workers", 1) if tasks else 0, "options": options.to_dict(),
            "aggregate": [_plain(r) for r in study.aggregate(rows)], "summary": study.summary(rows)})
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
        with _closing(backend(workers, scheduler)) as executor:  # local processes start with the first chunk
            runs = [run_study(name, out, options, force=force, progress=progress, status=status, executor=executor)
                    for name in names]
        if page is not None and (force or not page.exists() or not all(run.kept for run in runs)):
            write_report(out, force=force)
    return runs


def available_studies() -> list[str]:
    """Registered studies whose dependencies are importable, in registry order."""
    load_studies()
    return [name for name, study in STUDIES.items() if not study.missing()]
