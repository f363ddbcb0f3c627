"""House rules that a test can check: no import cycle, modules of a readable size, measured figures in the docs
as the scripts printed them. (ruff and mypy run as their own step of ``.ci/run``: ``ruff check . && mypy``.)"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_no_import_cycle():
    """The layers point one way: no two modules of the package import each other, even through others."""
    done = subprocess.run([sys.executable, str(ROOT / "scripts" / "import_graph.py")], cwd=ROOT,
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stdout + done.stderr


def test_measured_figures_are_rendered_from_the_recorded_results():
    """docs/benchmarks.md and the README's headline table are what benchmarks/recorded.py renders from
    docs/results/ (the output the measuring scripts kept): edited by hand, they would drift from the measurements."""
    done = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "recorded.py"), "--check"], cwd=ROOT,
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stdout + done.stderr


def test_no_module_above_400_lines():
    """One concept per module: none grows past about 400 lines."""
    long = {str(p.relative_to(ROOT)): n for p in (ROOT / "src").rglob("*.py")
            if (n := len(p.read_text(encoding="utf-8").splitlines())) > 410}
    assert not long, long
