"""Where the chunks of a study run: in this process, in a local process pool, or on a Dask cluster.

Every executor has ``run(name, tasks, options, status)``, yielding ``(index, (rows, seconds))`` as chunks finish,
and ``close(abort)``. Local worker processes exit with their parent: stopped (an exception, Ctrl-C, SIGTERM turned
into one by the command line), the run terminates them; killed (SIGKILL), each worker notices that its parent is
gone and exits.
"""

from __future__ import annotations

import os
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from contextlib import contextmanager
from typing import Any

from ..errors import ImpactometerError, ParameterError, SimulationError
from ..jsonable import plain
from ..validation import check_integer
from .base import Row, StudyOptions, get_study, load_studies

Task = tuple[int, list[Row]]
#: ``status(name, text)``: what a study run is doing before its chunks flow ("" once they do)
Status = Callable[[str, str], None]

#: compile time of the kernels of a study on a cold numba cache (every worker compiles its own), measured on 2 cores
COMPILE_TIME = "about 20-90 s"


def evaluate_chunk(name: str, cases: list[Row], options: StudyOptions) -> tuple[list[Row], float]:
    """Evaluate one chunk of study ``name`` (module-level, so process pools and Dask workers can call it)."""
    load_studies()
    start = time.perf_counter()
    try:
        rows = [plain_row(row) for row in get_study(name).evaluate(cases, options)]
    except ImpactometerError as exc:
        where = f"cases {cases[0]['case']}-{cases[-1]['case']}" if cases else "no cases"
        raise type(exc)(f"study {name!r}, {where}: {exc}") from exc
    return rows, time.perf_counter() - start


def plain_row(row: Row) -> Row:
    """Row with numpy scalars and arrays turned into Python numbers and lists (JSON-ready; NaN kept: the chunk
    store and the CSV writer spell it)."""
    return plain(row, nonfinite="keep")


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


#: seconds a Dask scheduler has to complete its handshake (the client's own timeout covers the TCP connect only: a
#: listener that accepts and stays silent, or answers another protocol, would hold it for minutes)
CONNECT_DEADLINE = 15.0
#: seconds a Dask run waits, saying so, while the cluster has no worker alive, before it gives up
NO_WORKER_DEADLINE = 300.0


def connect(address: str, deadline: float | None = None):
    """A ``dask.distributed.Client`` of the scheduler at ``address``, or a ParameterError within ``deadline`` [s]
    (default :data:`CONNECT_DEADLINE`)."""
    from dask.distributed import Client

    deadline = CONNECT_DEADLINE if deadline is None else deadline
    _probe(address, deadline)
    outcome: dict[str, Any] = {}

    def connect() -> None:
        try:
            outcome["client"] = Client(address, timeout="5s", set_as_default=False)
        except Exception as exc:  # reported below, in one line
            outcome["error"] = exc

    attempt = threading.Thread(target=connect, name="impactometer-dask-connect", daemon=True)
    attempt.start()
    attempt.join(deadline)
    expected = "expected the address of a running Dask scheduler, e.g. tcp://HOST:8786"
    if attempt.is_alive():
        raise ParameterError(f"--scheduler: {address!r} accepted the connection but no Dask scheduler answered within "
                             f"{deadline:g} s (another service on that port?); {expected}")
    if "error" in outcome:
        raise ParameterError(f"--scheduler: cannot connect to {address!r} ({outcome['error']}); {expected}")
    return outcome["client"]


def _probe(address: str, deadline: float) -> None:
    """ParameterError unless a ``tcp://`` address speaks first as a Dask scheduler does: on accepting, a scheduler
    sends its handshake, a message whose first 8 bytes count its frames (little-endian, a handful). A listener that
    stays silent (a web server waiting for its request, a stalled process) or sends something else is refused
    before a client is made, which would otherwise wait on it in a thread of its own."""
    import socket
    import struct

    scheme, _, rest = address.partition("://")
    if scheme != "tcp":
        return  # tls/ws/ucx: the client's own handshake decides
    host, _, port = rest.rpartition(":")
    expected = "expected the address of a running Dask scheduler, e.g. tcp://HOST:8786"
    try:
        with socket.create_connection((host.strip("[]"), int(port)), timeout=deadline) as probe:
            probe.settimeout(deadline)
            head = b""
            while len(head) < 8:
                chunk = probe.recv(8 - len(head))
                if not chunk:
                    break
                head += chunk
    except TimeoutError:
        raise ParameterError(f"--scheduler: {address!r} accepted the connection but sent no Dask handshake within "
                             f"{deadline:g} s (another service on that port?); {expected}") from None
    except (OSError, ValueError) as exc:
        raise ParameterError(f"--scheduler: cannot connect to {address!r} ({exc}); {expected}") from None
    if len(head) < 8 or not 0 < struct.unpack("<Q", head)[0] <= 64:
        raise ParameterError(f"--scheduler: {address!r} answered, but not as a Dask scheduler (it sent "
                             f"{head[:8]!r}); {expected}")


class _Dask:
    """An existing Dask distributed cluster reached through its scheduler address."""

    #: seconds between looks at the cluster while no chunk finishes
    poll = 0.2

    def __init__(self, address: str, *, no_worker_deadline: float | None = None) -> None:
        try:
            import dask.distributed  # noqa: F401
        except ImportError:
            raise ParameterError("--scheduler needs Dask distributed; install the extra: "
                                 "pip install 'impactometer[dask]'") from None
        self.client = connect(address)
        self.address = address
        self.no_worker_deadline = NO_WORKER_DEADLINE if no_worker_deadline is None else no_worker_deadline
        self.workers = max(1, sum(self.client.nthreads().values()))

    def _alive(self) -> int:
        """Workers the scheduler knows now."""
        return len(self.client.nthreads())

    def run(self, name: str, tasks: Sequence[Task], options: StudyOptions,
            status: Status | None = None) -> Iterator[tuple[int, Any]]:
        from dask.distributed import as_completed

        futures = {self.client.submit(evaluate_chunk, name, cases, options, pure=False): index
                   for index, cases in tasks}
        waiting = f"waiting for the first chunks from the cluster ({self.workers} threads; a first run compiles " \
                  "kernels on every worker)"
        if status:
            status(name, waiting)
        finished = as_completed(list(futures), loop=self.client.loop)
        lonely_since: float | None = None  # when the cluster was first seen without a worker
        last_look = time.monotonic()
        try:
            while not finished.is_empty():
                batch = finished.next_batch(block=False)
                for future in batch:
                    if status and waiting:
                        status(name, "")
                        waiting = ""
                    yield futures[future], future.result()
                if batch:
                    lonely_since = None
                    continue
                time.sleep(self.poll)
                now = time.monotonic()
                if now - last_look < 10 * self.poll:
                    continue
                last_look = now
                if self._alive():
                    if lonely_since is not None and status:
                        status(name, waiting)
                    lonely_since = None
                    continue
                lonely_since = now if lonely_since is None else lonely_since
                if now - lonely_since > self.no_worker_deadline:
                    raise SimulationError(f"no Dask worker has been alive at {self.address!r} for "
                                          f"{self.no_worker_deadline:g} s while study {name!r} waited; finished "
                                          "chunks are kept: start workers and rerun to resume")
                if status:
                    status(name, f"no Dask worker is alive at {self.address}: waiting for one "
                                 f"({now - lonely_since:.0f} s of {self.no_worker_deadline:g} s)")
        finally:
            for future in futures:
                future.cancel()

    def close(self, abort: bool = False) -> None:
        self.client.close()


@contextmanager
def closing_executor(executor) -> Iterator[Any]:
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
