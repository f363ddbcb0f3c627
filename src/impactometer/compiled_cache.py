"""numba's on-disk cache of compiled functions kept consistent with the package's sources.

numba caches each compiled function (``cache=True``) beside its source file, in ``__pycache__`` (``.nbi`` index,
``.nbc`` machine code), and judges a cache entry by the timestamp and size of that one file. A compiled function that
calls a compiled function of another file has the callee's code inlined into its own, so after that other file
changes numba still loads the caller's old machine code, with the old callee in it: the package would compute with
code that is no longer in its sources. At import the package therefore compares a fingerprint of all its source
files (relative path, size and modification time of each ``.py`` file) with the one stored beside its caches
(:data:`STAMP`); where they differ, it removes every cache file of the package, so that each function is compiled
again from the sources as they are, and stores the new fingerprint. A release installed with pip writes fresh files,
so this matters where the sources are edited in place (an editable install, a checkout on ``PYTHONPATH``). Where the
package's folders cannot be written (a read-only installation), numba keeps its cache elsewhere and nothing is
removed here.
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

#: the package's folder
ROOT = Path(__file__).resolve().parent
#: the file, in the package's top ``__pycache__``, holding the fingerprint of the sources its caches were made from
STAMP = Path("__pycache__") / "numba-sources.stamp"
#: the suffixes of numba's cache files (index, machine code)
CACHE_SUFFIXES = (".nbi", ".nbc")


def sources_fingerprint(root: Path = ROOT) -> str:
    """A SHA-256 digest of the relative path, size [B] and modification time [ns] of every ``.py`` file under
    ``root``."""
    digest = hashlib.sha256()
    for path in sorted(root.rglob("*.py")):
        stat = path.stat()
        digest.update(f"{path.relative_to(root).as_posix()}\0{stat.st_size}\0{stat.st_mtime_ns}\n".encode())
    return digest.hexdigest()


def remove_stale(root: Path = ROOT) -> int:
    """Remove numba's cache files under ``root`` when its sources are not those the caches were made from (see the
    module's documentation) and store the sources' fingerprint; the number of files removed (0 when the caches are
    current or the folders cannot be written)."""
    stamp = root / STAMP
    try:
        current = sources_fingerprint(root)
        if stamp.is_file() and stamp.read_text(encoding="ascii") == current:
            return 0
        removed = 0
        for path in root.rglob("*.nb[ic]"):
            if path.suffix in CACHE_SUFFIXES and path.parent.name == "__pycache__":
                path.unlink(missing_ok=True)
                removed += 1
        stamp.parent.mkdir(exist_ok=True)
        written = stamp.with_name(f"{stamp.name}.{os.getpid()}")
        written.write_text(current, encoding="ascii")
        os.replace(written, stamp)  # whole or not at all, also where several processes start at once
        return removed
    except OSError:
        return 0
