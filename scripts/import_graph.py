"""Import graph of the package: cycles between modules, the internal imports made inside functions, and the
imports of the view layer from below the command line.

    python scripts/import_graph.py          # cycles and view imports (exit status 1 if any), a count of
                                            # function-level imports
    python scripts/import_graph.py -v       # ... and which module imports which inside its functions
    python scripts/import_graph.py --inner identify.model_fit calibrate
                                            # public names of those subpackages used only inside them (exit
                                            # status 1 if any)

Every import is an arrow of the graph, wherever it is made: one under ``if TYPE_CHECKING:`` (a module that names
another in its annotations depends on it as much as one that calls it) and one inside a function (it still runs);
and importing ``a.b.c`` runs the ``__init__`` of the package ``a.b`` first, so it is an arrow to that package too
(and so through whatever the package re-exports), unless the package holds the importing module (then it is
already being imported). A cycle through any of these is a cycle.

A public function or class (no leading underscore) defined at the top of a module of a subpackage is part of what
the subpackage offers the rest of the package; one that no module outside the subpackage imports or reads (``from
.x import name`` or ``x.name`` with ``x`` a module of the subpackage; a parent package's re-export, a module's
``__all__`` and the types a used name hands out in its bases, fields and signatures count; the tests and the docs do
not) is an inner name and takes a leading underscore, or moves to the module that uses it. (Module constants are the
documented settings of a method and are not counted.)

The view layer (``plotting``) sits beside the command line, above everything else: below ``cli`` it may be imported
only inside a result's ``.plot()`` method (python-control's pattern: the computation never imports matplotlib), and
since such an import is an arrow like any other, a figure that called back into the logic below would make a cycle.
"""

from __future__ import annotations

import argparse
import ast
import sys
from collections import defaultdict
from pathlib import Path

PACKAGE = "impactometer"
#: the view layer: reached from below the command line only by ``.plot()`` methods, inside the method
VIEW = f"{PACKAGE}.plotting"
#: the layers allowed to import the view layer anywhere
EDGE = (f"{PACKAGE}.cli", VIEW)


def modules(root: Path) -> dict[str, Path]:
    """Dotted module name -> file, for every module of the package below ``root`` (the package folder)."""
    found = {}
    for path in root.rglob("*.py"):
        parts = list(path.relative_to(root.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        found[".".join(parts)] = path
    return found


def _resolve(module: str, is_package: bool, node: ast.ImportFrom) -> str | None:
    if not node.level:
        return node.module
    base = module.split(".") if is_package else module.split(".")[:-1]
    base = base[:len(base) - (node.level - 1)]
    return ".".join(base) + (f".{node.module}" if node.module else "")


def _within(name: str, package: str) -> bool:
    return name == package or name.startswith(package + ".")


def _plot_methods(tree: ast.AST) -> set[int]:
    """ids of the nodes inside a method named ``plot`` of a class."""
    return {id(n) for c in ast.walk(tree) if isinstance(c, ast.ClassDef) for f in c.body
            if isinstance(f, (ast.FunctionDef, ast.AsyncFunctionDef)) and f.name == "plot" for n in ast.walk(f)}


def import_graph(root: Path) -> tuple[dict[str, set[str]], dict[str, set[str]], list[str]]:
    """(every internal import arrow, the arrows made inside functions, the imports of the view layer from below the
    command line other than in a ``.plot()`` method) between modules of the package."""
    mods = modules(root)
    edges: dict[str, set[str]] = defaultdict(set)
    inside: dict[str, set[str]] = defaultdict(set)
    misplaced: list[str] = []
    for name, path in mods.items():
        tree = ast.parse(path.read_text(encoding="utf-8"))
        in_function = {id(n) for f in ast.walk(tree) if isinstance(f, (ast.FunctionDef, ast.AsyncFunctionDef))
                       for n in ast.walk(f)}
        in_plot = _plot_methods(tree)
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom):
                target = _resolve(name, path.name == "__init__.py", node)
                if not target or not _within(target, PACKAGE):
                    continue
                targets = [f"{target}.{a.name}" if f"{target}.{a.name}" in mods else target for a in node.names]
            elif isinstance(node, ast.Import):
                targets = [a.name for a in node.names if _within(a.name, PACKAGE)]
            else:
                continue
            for target in targets:
                while target not in mods and "." in target:
                    target = target.rsplit(".", 1)[0]
                if target == name:
                    continue
                if id(node) in in_function:
                    inside[name].add(target)
                if (_within(target, VIEW) and not any(_within(name, edge) for edge in EDGE)
                        and id(node) not in in_plot):
                    misplaced.append(f"{name} -> {target} (line {node.lineno})")
                edges[name].add(target)
                # the packages that hold the target run first, unless they hold the importer too
                package = target.rsplit(".", 1)[0] if "." in target else ""
                while package and package in mods:
                    if not _within(name, package):
                        edges[name].add(package)
                    package = package.rsplit(".", 1)[0] if "." in package else ""
    return edges, inside, sorted(set(misplaced))


def _package(module: str, mods: dict[str, Path]) -> str:
    """The innermost package that holds ``module`` (a package holds itself)."""
    return module if mods[module].name == "__init__.py" else module.rsplit(".", 1)[0]


def _defined(tree: ast.Module) -> dict[str, ast.AST]:
    """Public functions and classes a module defines at its top level, by name."""
    return {node.name: node for node in tree.body
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef))
            and not node.name.startswith("_")}


def _annotated(node: ast.AST) -> set[str]:
    """Names in the annotations of a function's signature or of a class's bases, fields and methods' signatures: the
    types a caller receives from it."""
    found: set[str] = set()
    functions = [node] if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) else []
    if isinstance(node, ast.ClassDef):
        found |= {n.id for base in node.bases for n in ast.walk(base) if isinstance(n, ast.Name)}
        for item in node.body:
            if isinstance(item, ast.AnnAssign):
                found |= {n.id for n in ast.walk(item.annotation) if isinstance(n, ast.Name)}
                found |= {n.value for n in ast.walk(item.annotation) if isinstance(n, ast.Constant)
                          and isinstance(n.value, str)}
            elif isinstance(item, (ast.FunctionDef, ast.AsyncFunctionDef)) and not item.name.startswith("_"):
                functions.append(item)
    for f in functions:
        for annotation in [f.returns, *(a.annotation for a in f.args.args + f.args.kwonlyargs)]:
            if annotation is not None:
                found |= {n.id for n in ast.walk(annotation) if isinstance(n, ast.Name)}
                found |= {n.value for n in ast.walk(annotation) if isinstance(n, ast.Constant)
                          and isinstance(n.value, str)}
    return found


def _all(tree: ast.Module) -> set[str]:
    """The names a module's ``__all__`` lists (a literal list or tuple of strings)."""
    for node in tree.body:
        if (isinstance(node, ast.Assign) and any(isinstance(t, ast.Name) and t.id == "__all__" for t in node.targets)
                and isinstance(node.value, (ast.List, ast.Tuple))):
            return {e.value for e in node.value.elts if isinstance(e, ast.Constant) and isinstance(e.value, str)}
    return set()


def inner_names(root: Path, packages: list[str]) -> list[str]:
    """``module.name (line n)`` of every public name defined in a module of one of ``packages`` (dotted, below the
    package: ``identify.model_fit``) that no module outside that package imports or reads as an attribute."""
    mods = modules(root)
    wanted = [f"{PACKAGE}.{p}" if p else PACKAGE for p in packages]
    for package in wanted:
        if package not in mods or mods[package].name != "__init__.py":
            raise SystemExit(f"--inner: {package} is not a package below {root}")
    used: dict[str, set[str]] = defaultdict(set)  # module -> names read from it by modules outside its package
    trees = {name: ast.parse(path.read_text(encoding="utf-8")) for name, path in mods.items()}
    for name, tree in trees.items():
        aliases: dict[str, str] = {}
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom):
                target = _resolve(name, mods[name].name == "__init__.py", node)
                if not target or target not in mods:
                    continue
                for a in node.names:
                    if f"{target}.{a.name}" in mods:
                        aliases[a.asname or a.name] = f"{target}.{a.name}"
                    elif not _within(name, _package(target, mods)):
                        used[target].add(a.name)
            elif isinstance(node, ast.Import):
                aliases.update({a.asname: a.name for a in node.names if a.asname and a.name in mods})
        for node in ast.walk(tree):
            if (isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id in aliases
                    and not _within(name, _package(aliases[node.value.id], mods))):
                used[aliases[node.value.id]].add(node.attr)
    found = []
    for package in wanted:
        # what the ``__all__`` of a module of the package or of a package above it lists is offered to its users (a
        # package's re-exports, a module of examples); a name re-exported by a package's __init__ is read from there
        offered = set().union(*(_all(tree) for m, tree in trees.items() if _within(m, package) or _within(package, m)))
        outside = offered.union(*(names for module, names in used.items() if _within(module, package)))
        defined = {(module, name): node for module in sorted(m for m in mods if _package(m, mods) == package)
                   for name, node in _defined(trees[module]).items()}
        grown = True
        while grown:  # a type that a used name hands out (its fields, arguments, returns) is used with it
            before = len(outside)
            outside |= set().union(*(_annotated(node) for (_, name), node in defined.items() if name in outside))
            grown = len(outside) > before
        found += [f"{module}.{name} (line {node.lineno})" for (module, name), node in defined.items()
                  if name not in outside]
    return found


def cycles(edges: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected groups of more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []
    sys.setrecursionlimit(10_000)

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in edges.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            group = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                group.append(w)
                if w == v:
                    break
            if len(group) > 1:
                found.append(sorted(group))

    for v in list(edges):
        if v not in index:
            visit(v)
    return found


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-v", "--verbose", action="store_true", help="list the function-level imports")
    parser.add_argument("--inner", nargs="+", metavar="PACKAGE",
                        help="list the public names of these subpackages (e.g. identify.model_fit) used only inside "
                             "them, instead of the import graph")
    parser.add_argument("--root", type=Path, default=Path(__file__).resolve().parents[1] / "src" / PACKAGE)
    args = parser.parse_args()
    if args.inner:
        inner = inner_names(args.root, args.inner)
        for line in inner:
            print("public name used only inside its package:", line)
        print(f"{len(inner)} public name(s) used only inside their package")
        return 1 if inner else 0
    edges, inside, misplaced = import_graph(args.root)
    groups = cycles(edges)
    for group in groups:
        print("cycle:", " <-> ".join(group))
    for line in misplaced:
        print("view imported below the command line, outside a .plot() method:", line)
    print(f"{len(groups)} import cycle(s); {len(misplaced)} import(s) of the view layer from below the command line "
          f"outside a .plot() method; {sum(len(v) for v in inside.values())} internal imports inside functions")
    if args.verbose:
        for name in sorted(inside):
            print(f"  {name} -> {', '.join(sorted(inside[name]))}")
    return 1 if groups or misplaced else 0


if __name__ == "__main__":
    raise SystemExit(main())
