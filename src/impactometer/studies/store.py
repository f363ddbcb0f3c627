"""Persistence of study runs in an output folder: atomic writes, a manifest per study, one JSON file per chunk.

Layout of ``DIR``::

    DIR/index.html              the report
    DIR/<study>.csv, .png       the tidy table and the figure
    DIR/<study>/manifest.json   the options the chunks belong to (their key)
    DIR/<study>/chunk-00003.json  finished chunks (rows + compute time)
    DIR/<study>/result.json     aggregate table, summary and timings, read by the report
    DIR/.impactometer.lock      held by the run writing into DIR (a second run is refused); removed when it ends

Every file is written to a temporary name in the same folder, flushed, synced and renamed with ``os.replace``:
a killed run leaves either the previous file or the new one, never a half-written file under the final name.
A chunk is read back only if it parses and names the same study, options key, chunk number and cases (in full,
so a study whose case list changed never reuses a stale chunk).
"""

from __future__ import annotations

import json
import os
import sys
import tempfile
import warnings
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from ..errors import ParameterError
from ..outputs import write_failed

MANIFEST = "manifest.json"
RESULT = "result.json"
SCHEMA = 1
#: lock file of a study folder: held (an OS file lock) by the run writing into the folder
LOCK = ".impactometer.lock"
_held: dict[Path, int] = {}  # study folders this process holds -> nesting depth


@contextmanager
def locked(out: Path, *, notice: Callable[[str], None] | None = None) -> Iterator[Path]:
    """Hold the lock of study folder ``out`` (created if missing) while the block runs.

    Two runs never write into one folder at once: a second run, in this or another process, is refused with a
    ParameterError naming the process that holds the folder. The lock is the operating system's (flock) on
    ``out/.impactometer.lock``, which the run removes when the block ends, however it ends. A lock file left by a
    killed run (SIGKILL) holds no lock: it is taken over and reported through ``notice(text)`` (default: a
    warning), saying whether the process it names is still running. Nested use in the same process (a run writing
    its report) is allowed.
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    key = out.resolve()
    if key in _held:
        _held[key] += 1
        try:
            yield out
        finally:
            _held[key] -= 1
        return
    path = out / LOCK
    handle, previous = _acquire(path, out)
    try:
        handle.seek(0)
        handle.truncate()
        handle.write(f"process {os.getpid()}")
        handle.flush()
        if previous:
            _stale(previous, path, notice)
        _held[key] = 1
        try:
            yield out
        finally:
            del _held[key]
    finally:
        try:  # removed while still locked: a run that opened the old file sees it is gone and opens a new one
            if os.path.samestat(os.fstat(handle.fileno()), os.stat(path)):
                path.unlink()
        except OSError:
            pass
        handle.close()  # releases the lock


def _acquire(path: Path, out: Path):
    """Open and lock ``path``: (the open file, the text it held before); ParameterError while another run holds
    it."""
    while True:
        try:
            handle = open(path, "a+", encoding="utf-8")  # noqa: SIM115 - held open for the whole run
        except OSError as exc:
            raise write_failed(path, exc) from None
        handle.seek(0)
        text = handle.read().strip()
        if not _try_lock(handle):
            handle.close()
            raise ParameterError(f"--out: {str(out)!r} is being written by another study run "
                                 f"({text or 'another process'}); wait for it to finish or choose another --out")
        try:
            current = os.path.samestat(os.fstat(handle.fileno()), os.stat(path))
        except OSError:
            current = False
        if current:  # else its holder removed it between our open and our lock: lock the next one
            handle.seek(0)
            return handle, handle.read().strip()
        handle.close()


def _stale(previous: str, path: Path, notice: Callable[[str], None] | None) -> None:
    """Report the lock file of a run that ended without removing it (killed)."""
    pid = previous.removeprefix("process ").strip()
    if pid.isdigit() and int(pid) != os.getpid():
        state = "which is no longer running" if not _running(int(pid)) else "which no longer holds it"
        text = (f"removed a stale lock {str(path)!r} of process {pid}, {state} (a killed run; its finished chunks "
                "are kept)")
    else:
        text = f"removed a stale lock {str(path)!r} ({previous[:60]!r}) of a run that ended without removing it"
    if notice is None:
        warnings.warn(text, stacklevel=4)
    else:
        notice(text)


def _running(pid: int) -> bool:
    """Whether process ``pid`` exists (on this machine; on Windows, where signal 0 would end it, assumed)."""
    if sys.platform == "win32":  # pragma: no cover - Windows
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:  # exists, owned by someone else (or not ours to ask about)
        return True
    return True


def _try_lock(handle) -> bool:
    """Take an exclusive lock on an open file without waiting; False when another holds it."""
    if sys.platform == "win32":  # pragma: no cover - Windows
        import msvcrt

        try:
            handle.seek(0)
            msvcrt.locking(handle.fileno(), msvcrt.LK_NBLCK, 1)
        except OSError:
            return False
        return True
    import fcntl

    try:
        fcntl.flock(handle.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        return False
    return True


def atomic_write(path: Path, data: str | bytes) -> Path:
    """Write ``data`` to ``path`` atomically (temporary file in the same folder, fsync, ``os.replace``)."""
    path = Path(path)
    mode = "wb" if isinstance(data, bytes) else "w"
    options: dict[str, Any] = {} if mode == "wb" else {"encoding": "utf-8"}
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    except OSError as exc:
        raise write_failed(path, exc) from None
    try:
        with os.fdopen(fd, mode, **options) as handle:
            handle.write(data)
            handle.flush()
            os.fsync(handle.fileno())
        os.chmod(tmp, 0o644)
        os.replace(tmp, path)
    except BaseException as exc:
        Path(tmp).unlink(missing_ok=True)
        if isinstance(exc, OSError):
            raise write_failed(path, exc) from None
        raise
    return path


def chunk_path(folder: Path, index: int) -> Path:
    return folder / f"chunk-{index:05d}.json"


def write_chunk(folder: Path, *, study: str, key: str, index: int, cases: list[dict], rows: list[dict],
                seconds: float) -> Path:
    """Persist one finished chunk: its cases (in full), rows and compute time [s]."""
    payload = {"schema": SCHEMA, "study": study, "key": key, "chunk": index, "cases": cases, "seconds": seconds,
               "rows": rows}
    return atomic_write(chunk_path(folder, index), json.dumps(payload, allow_nan=True))


def read_chunk(folder: Path, *, study: str, key: str, index: int, cases: list[dict]) -> dict[str, Any] | None:
    """A persisted chunk if present and valid for these options and exactly these cases, else None."""
    path = chunk_path(folder, index)
    try:
        payload = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(payload, dict) or not isinstance(payload.get("rows"), list):
        return None
    expected = {"schema": SCHEMA, "study": study, "key": key, "chunk": index, "cases": cases}
    if any(payload.get(k) != v for k, v in expected.items()):
        return None
    return payload


def finished(out: Path, study: str, key: str) -> bool:
    """Whether ``out`` holds a finished run of ``study`` under options ``key`` (its manifest and result)."""
    folder = Path(out) / study
    try:
        manifest = json.loads((folder / MANIFEST).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return False
    return isinstance(manifest, dict) and manifest.get("key") == key and read_result(folder) is not None


def prepare_folder(out: Path, study: str, key: str, options: dict[str, Any], *, force: bool) -> Path:
    """The study's chunk folder under ``out``, checked against the options of an earlier run.

    A folder holding chunks of other options is refused unless ``force`` (then its chunks are discarded).
    Final tables of a study without a manifest are user files: refused unless ``force``.
    """
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise ParameterError(f"--out: {str(out)!r} exists and is not a folder; expected a folder for the study run")
    folder = out / study
    manifest = folder / MANIFEST
    if manifest.exists():
        try:
            previous = json.loads(manifest.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            previous = {}
        if previous.get("key") != key:
            if not force:
                raise ParameterError(
                    f"--out: {str(folder)!r} holds a '{study}' run with other options "
                    f"({_differences(previous.get('options'), options)}); pass --overwrite to discard it or choose "
                    f"another --out")
            for old in folder.glob("chunk-*.json"):
                old.unlink()
            (folder / RESULT).unlink(missing_ok=True)
    elif not force:
        for name in (f"{study}.csv", f"{study}.png"):
            if (out / name).exists():
                raise ParameterError(f"--out: {str(out / name)!r} exists and was not written by a study run; "
                                     f"pass --overwrite to overwrite it")
    folder.mkdir(parents=True, exist_ok=True)
    atomic_write(manifest, json.dumps({"schema": SCHEMA, "study": study, "key": key, "options": options},
                                      indent=1, default=repr))
    return folder


def _differences(before: Any, after: dict[str, Any]) -> str:
    """Short description of the options that differ between two runs."""
    if not isinstance(before, dict):
        return "unreadable manifest"
    changed = []
    for name in sorted(set(before) | set(after)):
        old, new = before.get(name), after.get(name)
        if json.dumps(old, sort_keys=True, default=repr) != json.dumps(new, sort_keys=True, default=repr):
            changed.append(f"{name}: {old!r} → {new!r}" if name != "rig" else "the stand")
    return "; ".join(changed) or "another version of the study"


def write_result(folder: Path, result: dict[str, Any]) -> Path:
    return atomic_write(folder / RESULT, json.dumps(result, indent=1, allow_nan=True, default=repr))


def read_result(folder: Path) -> dict[str, Any] | None:
    try:
        data = json.loads((Path(folder) / RESULT).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return data if isinstance(data, dict) else None
