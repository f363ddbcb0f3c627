"""The docs name the code's tuning constants by link instead of restating their numbers: every link of the form
[`module.NAME`](../src/impactometer/....py) must point at a module that defines NAME at its top level, so that a
renamed or removed constant breaks this test rather than leaving the docs silently wrong."""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
#: the docs that name constants by link (each must hold at least one such link)
LINKING_DOCS = ("identification.md", "response_map.md", "recordings.md", "absorption.md")
#: [`module.NAME`](relative/path/to/module.py) -- a code link whose text names a module and one of its names
CODE_LINK = re.compile(r"\[`(?P<name>[A-Za-z_][\w.]*)`\]\((?P<path>[^)\s#]+\.py)\)")


def top_level_names(source: str) -> set[str]:
    """Names bound at the top level of a module: assignments (tuple targets included), functions and classes."""
    names: set[str] = set()

    def bind(target: ast.expr) -> None:
        if isinstance(target, ast.Name):
            names.add(target.id)
        elif isinstance(target, (ast.Tuple, ast.List)):
            for element in target.elts:
                bind(element)

    for node in ast.parse(source).body:
        if isinstance(node, ast.Assign):
            for target in node.targets:
                bind(target)
        elif isinstance(node, (ast.AnnAssign, ast.AugAssign)):
            bind(node.target)
        elif isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            names.add(node.name)
    return names


def module_name(path: Path) -> str:
    """The name a link uses for the module at ``path``: its stem, or its package's name for ``__init__.py``."""
    return path.parent.name if path.stem == "__init__" else path.stem


def link_problems(text: str, doc: Path) -> tuple[int, list[str]]:
    """(links found, what is wrong with them) for the code links in ``text`` of the doc at ``doc``."""
    problems, found = [], 0
    for match in CODE_LINK.finditer(text):
        found += 1
        name, link = match["name"], match["path"]
        line = text.count("\n", 0, match.start()) + 1
        where = f"{doc.name}:{line}: [`{name}`]({link})"
        target = (doc.parent / link).resolve()
        if not target.is_file():
            problems.append(f"{where}: no such file")
            continue
        *module, constant = name.split(".")
        if module and module[-1] != module_name(target):
            problems.append(f"{where}: the text names module {module[-1]!r}, the link goes to {target.name}")
        if constant not in top_level_names(target.read_text(encoding="utf-8")):
            problems.append(f"{where}: {target.relative_to(ROOT)} defines no top-level {constant!r}")
    return found, problems


@pytest.mark.parametrize("doc", LINKING_DOCS)
def test_linked_constants_exist(doc):
    path = DOCS / doc
    found, problems = link_problems(path.read_text(encoding="utf-8"), path)
    assert found, f"{doc} names no constant by a code link"
    assert not problems, "\n".join(problems)


def test_every_doc_links_existing_constants():
    for path in sorted(DOCS.glob("*.md")):
        _, problems = link_problems(path.read_text(encoding="utf-8"), path)
        assert not problems, "\n".join(problems)


def test_checker_catches_a_renamed_constant_and_a_wrong_module():
    doc = DOCS / "identification.md"
    good = "fires at [`trigger.TRIGGER_SIGMAS`](../src/impactometer/signals/trigger.py) σ"
    assert link_problems(good, doc) == (1, [])
    renamed = good.replace("TRIGGER_SIGMAS", "TRIGGER_SIGMA")
    assert "defines no top-level 'TRIGGER_SIGMA'" in link_problems(renamed, doc)[1][0]
    elsewhere = good.replace("trigger.py", "pulses.py")
    assert any("names module 'trigger'" in p for p in link_problems(elsewhere, doc)[1])
    missing = good.replace("trigger.py", "no_such_module.py")
    assert "no such file" in link_problems(missing, doc)[1][0]
    package = "[`io.MANIFEST_TOLERANCE`](../src/impactometer/io/__init__.py)"
    assert link_problems(package, doc) == (1, [])
    pair = "[`onsets.FOOT_TOP_MAX`](../src/impactometer/identify/peak_to_peak/onsets.py)"
    assert link_problems(pair, doc) == (1, [])
