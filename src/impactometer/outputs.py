"""Output targets: checked before any work starts, and write failures reported in one line.

Every command and writer that saves something checks its target first -- a file name (not a folder, device, pipe or
socket), in an existing, writable folder, with a supported extension, not replacing an existing file unless asked
-- so that a bad target costs nothing, and turns an ``OSError`` while writing (disk full, permissions changed
meanwhile) into an :class:`~impactometer.errors.OutputError` naming the target. The file is written under a
temporary name beside its target and moved into place by :func:`publish`, which checks the target again: a whole
computation lies between the first check and the move, and another writer may have taken the name meanwhile.
"""

from __future__ import annotations

import errno
import os
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

from .errors import OutputError, ParameterError
from .validation import check_flag

#: what lets a caller of the Python writers replace an existing file, as their refusals name it
API_OVERWRITE = "overwrite=True (--overwrite)"
#: extensions of the HDF5 files written besides recordings (simulation histories, response maps)
HDF5_EXTENSIONS = (".h5", ".hdf5")


def as_path(value: Any, field: str = "path", *, error: type[Exception] = ParameterError, kind: str = "file") -> Path:
    """``value`` (a str or an os.PathLike) as a Path; ``error`` naming ``field`` for anything else (``kind``: what
    the name is of, ``file`` or ``folder``)."""
    if isinstance(value, Path):
        return value
    if isinstance(value, str) or (isinstance(value, os.PathLike) and isinstance(os.fspath(value), str)):
        if "\x00" in str(value):
            raise error(f"{field} must be a {kind} name without NUL characters, got {str(value)[:60]!r}")
        return Path(value)
    raise error(f"{field} must be a {kind} name (str or path), got {type(value).__name__}")


def figure_formats() -> list[str]:
    """File extensions matplotlib can save figures as (``.png``, ``.pdf``, ``.svg`` ...)."""
    from matplotlib.backend_bases import FigureCanvasBase

    return sorted(f".{ext}" for ext in FigureCanvasBase.get_supported_filetypes())


def _writable(folder: Path) -> bool:
    return os.access(folder, os.W_OK | os.X_OK)


def check_file(path: str | Path, field: str | None = None, *, overwrite: bool = False,
               extensions: Iterable[str] | None = None, flag: str = "--overwrite",
               error: type[Exception] = ParameterError) -> Path:
    """``path`` as a file target: not a folder, in an existing writable folder, with one of ``extensions``
    (case-insensitive) and, unless ``overwrite``, not an existing file; ``error`` naming ``field`` otherwise.

    ``flag`` is what the message tells the caller to pass to replace an existing file.
    """
    path = as_path(path, field or "path", error=error)
    check_flag("overwrite", overwrite, error=error)
    prefix = f"{field}: " if field else ""
    if path.is_dir():
        raise error(f"{prefix}{str(path)!r} is a folder; expected a file name")
    if path.exists() and not path.is_file():
        raise error(f"{prefix}{not_regular(path)}")
    if extensions is not None:
        allowed = sorted({e.lower() for e in extensions})
        found = f"extension {path.suffix!r}" if path.suffix else "no extension"
        if path.suffix.lower() not in allowed:
            raise error(f"{prefix}{str(path)!r} has {found}; expected one of {', '.join(allowed)}")
    if path.exists() and not overwrite:
        raise error(f"{prefix}{str(path)!r} exists; pass {flag} to overwrite it")
    folder = path.parent
    if not folder.exists():
        raise error(f"{prefix}folder {str(folder)!r} does not exist")
    if not folder.is_dir():
        raise error(f"{prefix}{str(folder)!r} is not a folder")
    if not _writable(folder) or (path.exists() and not os.access(path, os.W_OK)):
        raise error(f"{prefix}cannot write {str(path)!r} (permission denied); expected a writable folder")
    return path


def not_regular(path: Path) -> str:
    """The sentence for a target that exists and is not a regular file (a device, a pipe, a socket)."""
    return f"{str(path)!r} is not a regular file (a device, pipe or socket); expected a file name"


#: errors of os.link where the file system has no hard links (FAT, some network and FUSE file systems)
_NO_LINKS = {errno.EPERM, errno.EXDEV, errno.EMLINK, errno.ENOSYS, getattr(errno, "EOPNOTSUPP", -1),
             getattr(errno, "ENOTSUP", -1)}


def publish(temporary: Path, path: Path, *, overwrite: bool, flag: str = "--overwrite") -> None:
    """Move the finished file ``temporary`` onto ``path`` (in the same folder).

    With ``overwrite`` an existing regular file is replaced (``os.replace``); a target that has become something
    else (a device, a folder) is refused. Without, the file is hard-linked into place, which fails where ``path``
    exists: a second writer that found the name free at its start, as this one did, is refused here instead of
    silently replacing the file the first one wrote. On a file system without hard links the target is checked
    just before ``os.replace``. OutputError naming the target (``flag``: what lets the caller replace it).
    """
    if overwrite:
        if path.exists() and not path.is_file():
            raise OutputError(f"cannot write {not_regular(path)}")
        os.replace(temporary, path)
        return
    taken = OutputError(f"cannot write {str(path)!r}: it was created while this file was being written (another "
                        f"writer?) and is kept; pass {flag} to replace it")
    try:
        os.link(temporary, path)
    except FileExistsError:
        raise taken from None
    except OSError as exc:
        if exc.errno not in _NO_LINKS:
            raise
        if os.path.lexists(path):
            raise taken from None
        os.replace(temporary, path)
        return
    os.unlink(temporary)


def check_folder(path: str | Path, field: str) -> Path:
    """``path`` as an output folder: an existing writable folder, or one that can be created (its nearest existing
    parent a writable folder). ParameterError naming ``field`` otherwise."""
    path = as_path(path, field, kind="folder")
    if path.exists():
        if not path.is_dir():
            raise ParameterError(f"{field}: {str(path)!r} exists and is not a folder; expected a folder")
        if not _writable(path):
            raise ParameterError(f"{field}: cannot write into {str(path)!r} (permission denied); expected a "
                                 "writable folder")
        return path
    parent = path.absolute().parent
    while not parent.exists():
        parent = parent.parent
    if not parent.is_dir():
        raise ParameterError(f"{field}: cannot create {str(path)!r}: {str(parent)!r} is not a folder")
    if not _writable(parent):
        raise ParameterError(f"{field}: cannot create {str(path)!r} in {str(parent)!r} (permission denied); "
                             "expected a writable folder")
    return path


def write_failed(path: str | Path, exc: OSError) -> OutputError:
    """The one-line error for an ``OSError`` raised while writing ``path``."""
    reason = exc.strerror or " ".join(str(exc).split()) or type(exc).__name__
    return OutputError(f"cannot write {str(path)!r}: {reason}")


def write_atomically(path: Path, write: Callable[[Path], object], *, overwrite: bool,
                     flag: str = "--overwrite") -> Path:
    """Call ``write`` on a temporary name beside ``path``, then move the file into place (:func:`publish`); an
    ``OSError`` becomes the OutputError naming ``path``, and the temporary file never stays."""
    temporary = path.with_name(f".{path.stem}.partial-{os.getpid()}{path.suffix}")
    try:
        write(temporary)
        publish(temporary, path, overwrite=overwrite, flag=flag)
    except OutputError:
        raise
    except OSError as exc:
        raise write_failed(path, exc) from None
    finally:
        temporary.unlink(missing_ok=True)
    return path


def save_figure(fig, path: str | Path, *, dpi: int = 120, overwrite: bool = True) -> Path:
    """Save a matplotlib figure (format from the extension) next to ``path`` and move it into place
    (:func:`write_atomically`); close it (in pyplot, which drew it)."""
    import matplotlib.pyplot as plt

    try:
        return write_atomically(Path(path), lambda temporary: fig.savefig(temporary, dpi=dpi), overwrite=overwrite)
    finally:
        plt.close(fig)
