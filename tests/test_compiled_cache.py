"""numba's cache files are removed when the package's sources are not those they were made from."""

from __future__ import annotations

import os
from pathlib import Path

import impactometer
from impactometer.compiled_cache import ROOT, STAMP, remove_stale, sources_fingerprint


def _package(tmp_path):
    root = tmp_path / "pkg"
    (root / "sub" / "__pycache__").mkdir(parents=True)
    (root / "a.py").write_text("x = 1\n")
    (root / "sub" / "b.py").write_text("y = 2\n")
    return root


def _caches(root):
    for name in ("b.f-3.py311.nbi", "b.f-3.py311.1.nbc"):
        (root / "sub" / "__pycache__" / name).write_bytes(b"cached")
    (root / "sub" / "__pycache__" / "b.cpython-311.pyc").write_bytes(b"bytecode")


def test_caches_made_from_other_sources_are_removed_once(tmp_path):
    root = _package(tmp_path)
    _caches(root)
    assert remove_stale(root) == 2  # no fingerprint stored: the caches' sources are unknown
    assert (root / STAMP).read_text(encoding="ascii") == sources_fingerprint(root)
    assert (root / "sub" / "__pycache__" / "b.cpython-311.pyc").exists()  # Python's own bytecode is left alone
    _caches(root)
    assert remove_stale(root) == 0  # the same sources: the caches are kept
    assert len(list((root / "sub" / "__pycache__").glob("*.nb?"))) == 2
    (root / "a.py").write_text("x = 10\n")  # another file than the cached functions' own
    assert remove_stale(root) == 2
    assert not list((root / "sub" / "__pycache__").glob("*.nb?"))


def test_a_touched_file_of_the_same_size_changes_the_fingerprint(tmp_path):
    root = _package(tmp_path)
    before = sources_fingerprint(root)
    stat = (root / "a.py").stat()
    os.utime(root / "a.py", ns=(stat.st_atime_ns, stat.st_mtime_ns + 10**9))
    assert sources_fingerprint(root) != before


def test_a_folder_that_cannot_be_written_is_left_as_it_is(tmp_path, monkeypatch):
    root = _package(tmp_path)
    _caches(root)

    def refuse(*args, **kwargs):
        raise PermissionError("read-only")

    monkeypatch.setattr(type(root), "unlink", refuse)
    assert remove_stale(root) == 0
    assert len(list((root / "sub" / "__pycache__").glob("*.nb?"))) == 2


def test_the_package_checks_its_own_caches_when_imported():
    assert ROOT.samefile(Path(impactometer.__file__).parent)
    if os.access(ROOT / STAMP.parent, os.W_OK):  # the import stored the fingerprint of the sources as they are
        assert (ROOT / STAMP).read_text(encoding="ascii") == sources_fingerprint(ROOT)
