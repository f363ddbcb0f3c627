"""House rules that a test can check: no import cycle, measured figures in the docs as the scripts printed them.
(ruff and mypy run as their own step of ``.ci/run``: ``ruff check . && mypy``; a module's size follows its concept,
which no line count decides.)"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_no_import_cycle_and_plotting_only_at_the_edge():
    """The layers point one way: no two modules of the package import each other, even through others, in their
    annotations, inside functions or through a package's ``__init__``; and below ``cli`` the figures are reached
    only from a result's ``.plot()`` (scripts/import_graph.py says what counts)."""
    done = subprocess.run([sys.executable, str(ROOT / "scripts" / "import_graph.py")], cwd=ROOT,
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stdout + done.stderr
    assert done.stdout.startswith("0 import cycle(s); 0 import(s) of the view layer"), done.stdout


def _graph(tmp_path, sources: dict[str, str]) -> subprocess.CompletedProcess:
    package = tmp_path / "impactometer"
    for name, text in sources.items():
        (package / name).parent.mkdir(parents=True, exist_ok=True)
        (package / name).write_text(text, encoding="utf-8")
    return subprocess.run([sys.executable, str(ROOT / "scripts" / "import_graph.py"), "--root", str(package)],
                          cwd=ROOT, capture_output=True, text=True)


def _cycles(done: subprocess.CompletedProcess) -> list[str]:
    return sorted(line for line in done.stdout.splitlines() if line.startswith("cycle:"))


def test_import_graph_counts_annotation_function_and_package_imports(tmp_path):
    """An import under ``if TYPE_CHECKING:``, one inside a function (a ``.plot()`` too) and the ``__init__`` of the
    package that holds the imported module are arrows of the graph."""
    done = _graph(tmp_path, {
        "__init__.py": "",
        "annotated.py": "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from .names import Name\n",
        "names.py": "from .annotated import Annotated\n",
        "caller.py": "def call():\n    from .called import function\n",
        "called.py": "from .caller import call\n",
        "result.py": "class Result:\n    def plot(self):\n        from .plotting.figures import draw\n",
        "plotting/__init__.py": "",
        "plotting/figures.py": "from ..result import Result\n",
        "logic/__init__.py": "from .core import solve\n",
        "logic/core.py": "def solve():\n    from .answer import Answer\n",
        "logic/answer.py": "class Answer:\n    def plot(self):\n        from ..plotting.logic_figure import draw\n",
        "plotting/logic_figure.py": "from ..logic.helpers import helper\n",
        "logic/helpers.py": "",
    })
    assert done.returncode == 1, done.stdout + done.stderr
    assert _cycles(done) == [
        "cycle: impactometer.annotated <-> impactometer.names", "cycle: impactometer.called <-> impactometer.caller",
        "cycle: impactometer.logic <-> impactometer.logic.answer <-> impactometer.logic.core "
        "<-> impactometer.plotting.logic_figure",
        "cycle: impactometer.plotting.figures <-> impactometer.result"]


def test_import_graph_reports_plotting_below_the_command_line(tmp_path):
    """Below ``cli`` the plotting package may be imported only inside a ``.plot()`` method; ``cli`` may import it
    anywhere; a figure that reads no logic back makes no cycle."""
    done = _graph(tmp_path, {
        "__init__.py": "",
        "plotting/__init__.py": "",
        "plotting/figures.py": "import numpy\n",
        "result.py": "class Result:\n    def plot(self):\n        from .plotting.figures import draw\n",
        "study.py": "def figure(rows):\n    from .plotting import figures\n",
        "table.py": "from .plotting.figures import draw\n",
        "cli/__init__.py": "from ..plotting.figures import draw\n",
    })
    assert done.returncode == 1, done.stdout + done.stderr
    assert _cycles(done) == []
    reported = [line.split(": ", 1)[1] for line in done.stdout.splitlines() if line.startswith("view imported")]
    assert reported == ["impactometer.study -> impactometer.plotting.figures (line 2)",
                        "impactometer.table -> impactometer.plotting.figures (line 1)"]


#: public functions and classes of the fitting engine still used only inside their package (each one takes a leading
#: underscore or moves where it is used; a name fixed leaves this list, and a new inner name fails the test)
INNER_ENGINE_NAMES: dict[str, list[str]] = {}


def _inner(done: subprocess.CompletedProcess) -> list[str]:
    prefix = "public name used only inside its package: "
    return sorted(line[len(prefix):].split(" (line")[0] for line in done.stdout.splitlines()
                  if line.startswith(prefix))


def test_inner_names_of_a_package_are_the_ones_nothing_outside_reads(tmp_path):
    """A public function or class that no module outside its subpackage imports or reads as a module's attribute
    is listed; a re-export by the package, an ``__all__``, a type a used name hands out (a base, a field, an
    argument or a return), and a use from a tests folder or a constant do not make one."""
    package = tmp_path / "impactometer"
    sources = {
        "__init__.py": "",
        "fit/__init__.py": "from .core import solve\n__all__ = ['solve', 'Answer']\n",
        "fit/core.py": ("from .parts import Part, helper\nclass Answer:\n    pass\n"
                        "def solve(x: Part) -> 'Answer':\n    return helper(x)\nSTEP = 1\n"),
        "fit/parts.py": ("class Base:\n    pass\nclass Part(Base):\n    pass\ndef helper(x):\n    return x\n"
                         "def inner():\n    pass\ndef read():\n    pass\ndef attribute():\n    pass\n"),
        "fit/examples.py": "__all__ = ['example']\ndef example():\n    pass\ndef unused():\n    pass\n",
        "cli.py": "from .fit import solve\nfrom .fit.parts import read\nfrom .fit import parts\nparts.attribute()\n",
    }
    for name, text in sources.items():
        (package / name).parent.mkdir(parents=True, exist_ok=True)
        (package / name).write_text(text, encoding="utf-8")
    (tmp_path / "tests").mkdir()
    (tmp_path / "tests" / "test_fit.py").write_text("from impactometer.fit.parts import inner\n", encoding="utf-8")
    done = subprocess.run([sys.executable, str(ROOT / "scripts" / "import_graph.py"), "--root", str(package),
                           "--inner", "fit"], cwd=ROOT, capture_output=True, text=True)
    assert done.returncode == 1, done.stdout + done.stderr
    assert _inner(done) == ["impactometer.fit.examples.unused", "impactometer.fit.parts.helper",
                            "impactometer.fit.parts.inner"]


def test_the_fitting_engine_has_no_public_name_used_only_inside_its_package():
    """identify/model_fit and calibrate offer the rest of the package only what it reads (scripts/import_graph.py
    --inner says what counts); :data:`INNER_ENGINE_NAMES` lists the ones left."""
    done = subprocess.run([sys.executable, str(ROOT / "scripts" / "import_graph.py"), "--inner", "identify.model_fit",
                           "calibrate"], cwd=ROOT, capture_output=True, text=True)
    expected = sorted(f"impactometer.{module}.{name}" for module, names in INNER_ENGINE_NAMES.items()
                      for name in names)
    assert _inner(done) == expected, done.stdout + done.stderr


def test_measured_figures_are_rendered_from_the_recorded_results():
    """docs/benchmarks.md and the README's headline table are what benchmarks/recorded.py renders from
    docs/results/ (the output the measuring scripts kept): edited by hand, they would drift from the measurements."""
    done = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "recorded.py"), "--check"], cwd=ROOT,
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stdout + done.stderr
