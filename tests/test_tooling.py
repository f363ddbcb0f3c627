"""House tooling: the sources are clean under ruff (the ``[tool.ruff]`` rules) and mypy (default checks on src/).

Both tools come with the ``test`` extra; where they are missing (e.g. the run against the lowest declared
versions, which installs pytest and hypothesis only) these checks are skipped.
"""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _run(tool: str, *args: str, cwd: Path) -> subprocess.CompletedProcess:
    if importlib.util.find_spec(tool) is None:
        pytest.skip(f"{tool} is not installed (it comes with the 'test' extra)")
    return subprocess.run([sys.executable, "-m", tool, *args], cwd=cwd, capture_output=True, text=True,
                          timeout=300)


def test_ruff_finds_nothing():
    done = _run("ruff", "check", "--no-cache", ".", cwd=ROOT)
    assert done.returncode == 0, done.stdout + done.stderr


def test_mypy_finds_nothing(tmp_path):
    if not (ROOT / "src" / "impactometer").is_dir():
        pytest.skip("the sources are not beside the tests")
    done = _run("mypy", "--cache-dir", str(tmp_path / "mypy-cache"), "src", cwd=ROOT)
    assert done.returncode == 0, done.stdout + done.stderr


def test_no_import_cycle():
    """The layers point one way: no two modules of the package import each other, even through others."""
    done = subprocess.run([sys.executable, str(ROOT / "scripts" / "import_graph.py")], cwd=ROOT,
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stdout + done.stderr


def test_no_module_above_400_lines():
    """One concept per module: none grows past about 400 lines."""
    long = {str(p.relative_to(ROOT)): n for p in (ROOT / "src").rglob("*.py")
            if (n := len(p.read_text(encoding="utf-8").splitlines())) > 410}
    assert not long, long
