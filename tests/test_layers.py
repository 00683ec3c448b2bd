"""The layers of python/genplan, read with ``ast`` (nothing is imported).

library (everything but the two below)  <-  genplan.experiments  <-  genplan.cli (front end)

The library never imports the experiments or the CLI, the experiments never import the CLI, only
the library imports ``genplan._core`` (the experiments use the public API), and there is no
import cycle but the known ones. Imports are every ``import`` / ``from ... import`` anywhere in a module
(inside functions and ``TYPE_CHECKING`` blocks too) and ``importlib.import_module("...")``; a
module that imports by a computed name (a lazy ``__getattr__``, the CLI's command table) imports
every genplan module its string literals name.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1] / "python"
EXPERIMENTS = "genplan.experiments"
FRONT_END = ("genplan.cli", "genplan.__main__")
#: import cycles left for later (each the set of its modules): Environment.queries calls
#: make_queries, which builds Query objects (a lazy import each way)
KNOWN_CYCLES = [{"genplan.planning.environments", "genplan.planning.queries"}]


def _name(path: Path) -> str:
    parts = path.relative_to(ROOT).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


FILES = {_name(p): p for p in sorted((ROOT / "genplan").rglob("*.py"))}
MODULES = set(FILES) | {"genplan._core"}


def _layer(module: str) -> str:
    if module in FRONT_END:
        return "front end"
    return "experiments" if module == EXPERIMENTS or module.startswith(EXPERIMENTS + ".") else "library"


def _is_import_module(call: ast.Call) -> bool:
    f = call.func
    return (f.attr if isinstance(f, ast.Attribute) else getattr(f, "id", None)) == "import_module"


def imports(module: str) -> list[tuple[str, int]]:
    """(imported genplan module, line) of every import in ``module``."""
    path = FILES[module]
    tree = ast.parse(path.read_text(), str(path))
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    found: list[tuple[str, int]] = []
    computed = False
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found += [(a.name, node.lineno) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:  # relative: ``from .x import y`` in package p is ``from p.x import y``
                parts = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join(parts + ([base] if base else []))
            # ``from genplan import projection``: the module genplan.projection; else the package
            found += [(f"{base}.{a.name}" if f"{base}.{a.name}" in MODULES else base, node.lineno) for a in node.names]
        elif isinstance(node, ast.Call) and _is_import_module(node) and node.args:
            arg = node.args[0]
            if isinstance(arg, ast.Constant) and isinstance(arg.value, str):
                found.append((arg.value, node.lineno))
            else:
                computed = True
    if computed:
        found += [(n.value, n.lineno) for n in ast.walk(tree)
                  if isinstance(n, ast.Constant) and isinstance(n.value, str) and n.value in MODULES]
    return sorted({(m, line) for m, line in found if m in MODULES and m != module})


GRAPH = {m: imports(m) for m in FILES}


def _where(module: str, imported: str, line: int) -> str:
    return f"{module} ({FILES[module].relative_to(ROOT.parent)}:{line}) imports {imported}"


def _violations(importers: set[str], forbidden: set[str]) -> list[str]:
    """Every import by a module of the layers ``importers`` of a module of the layers ``forbidden``."""
    return [_where(m, i, line) for m, edges in GRAPH.items() if _layer(m) in importers
            for i, line in edges if _layer(i) in forbidden]


def test_the_graph_is_read() -> None:
    edges = {m: {i for i, _ in e} for m, e in GRAPH.items()}
    assert "genplan.robots" in edges["genplan.planning"]
    assert "genplan.gan.model" in edges["genplan.gan"]  # a lazy re-export, by computed name
    assert "genplan.experiments.benchmarks.plan" in edges["genplan.cli"]  # the command table


def test_the_library_imports_neither_the_experiments_nor_the_cli() -> None:
    bad = _violations({"library"}, {"experiments", "front end"})
    assert not bad, "the library must not import genplan.experiments or genplan.cli:\n" + "\n".join(bad)


def test_the_experiments_do_not_import_the_cli() -> None:
    bad = _violations({"experiments"}, {"front end"})
    assert not bad, "genplan.experiments must not import genplan.cli:\n" + "\n".join(bad)


def test_only_the_library_imports_the_core() -> None:
    bad = [_where(m, i, line) for m, edges in GRAPH.items() if _layer(m) != "library"
           for i, line in edges if i == "genplan._core"]
    assert not bad, "only the library imports genplan._core (use the public API):\n" + "\n".join(bad)


def _cycles() -> list[set[str]]:
    """The strongly connected components of more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    out: list[set[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        for w, _ in GRAPH.get(v, []):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = {stack.pop()}
            while v not in comp:
                comp.add(stack.pop())
            if len(comp) > 1:
                out.append(comp)

    for v in GRAPH:
        if v not in index:
            visit(v)
    return out


@pytest.mark.parametrize("cycle", _cycles() or [set()], ids=lambda c: " <-> ".join(sorted(c)) or "none")
def test_no_new_import_cycles(cycle: set[str]) -> None:
    edges = [_where(m, i, line) for m in sorted(cycle) for i, line in GRAPH[m] if i in cycle]
    assert not cycle or cycle in KNOWN_CYCLES, "an import cycle among genplan's modules:\n" + "\n".join(edges)
