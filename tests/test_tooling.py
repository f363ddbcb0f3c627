"""House rules that a test can check: no import cycle, measured figures in the docs as the scripts printed them.
(ruff and mypy run as their own step of ``.ci/run``: ``ruff check . && mypy``; a module's size follows its concept,
which no line count decides.)"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_no_import_cycle():
    """The layers point one way: no two modules of the package import each other, even through others, in their
    annotations or inside functions (scripts/import_graph.py says what counts)."""
    done = subprocess.run([sys.executable, str(ROOT / "scripts" / "import_graph.py")], cwd=ROOT,
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stdout + done.stderr


def test_import_graph_counts_annotation_and_function_imports(tmp_path):
    """An import under ``if TYPE_CHECKING:`` and one inside a function are arrows of the graph; a function-level
    import of the plotting package (a ``.plot()`` reaching the view layer) is not."""
    package = tmp_path / "impactometer"
    sources = {
        "__init__.py": "",
        "annotated.py": "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from .names import Name\n",
        "names.py": "from .annotated import Annotated\n",
        "caller.py": "def call():\n    from .called import function\n",
        "called.py": "from .caller import call\n",
        "result.py": "def plot():\n    from .plotting import draw\n",
        "plotting/__init__.py": "from ..result import Result\n",
    }
    for name, text in sources.items():
        (package / name).parent.mkdir(parents=True, exist_ok=True)
        (package / name).write_text(text, encoding="utf-8")
    done = subprocess.run([sys.executable, str(ROOT / "scripts" / "import_graph.py"), "--root", str(package)],
                          cwd=ROOT, capture_output=True, text=True)
    assert done.returncode == 1, done.stdout + done.stderr
    assert sorted(line for line in done.stdout.splitlines() if line.startswith("cycle:")) == [
        "cycle: impactometer.annotated <-> impactometer.names", "cycle: impactometer.called <-> impactometer.caller"]


def test_measured_figures_are_rendered_from_the_recorded_results():
    """docs/benchmarks.md and the README's headline table are what benchmarks/recorded.py renders from
    docs/results/ (the output the measuring scripts kept): edited by hand, they would drift from the measurements."""
    done = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "recorded.py"), "--check"], cwd=ROOT,
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stdout + done.stderr
