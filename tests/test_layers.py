"""The layers of python/genplan, read with ``ast`` (nothing is imported).

library (everything but the three below)  <-  genplan.cli.args  <-  genplan.experiments  <-  genplan.cli

The library never imports the experiments or the command line, the experiments never import the
command line but its argument types (``genplan.cli.args``, which imports the library only), only
the library imports ``genplan._core`` (the experiments use the public API), and there is no import
cycle but the known ones. Imports are every ``import`` / ``from ... import`` anywhere in a module
(inside functions and ``TYPE_CHECKING`` blocks too, not in an ``if __name__ == "__main__":`` block,
which runs only when the module is run as a program) and ``importlib.import_module("...")``; a
module that imports by a computed name (a lazy ``__getattr__``, the CLI's command table) imports
every genplan module its string literals name.

Two more rules keep one definition per concept: a command line (argparse, ``add_arguments``) lives
in ``genplan.cli`` (or, for the benchmarks, ``genplan.experiments``), never in the library; and a
registry of names (an upper-case tuple, list or set of names at module or class level) is not
repeated by another one holding the same names, which would drift apart from it: derive the second
from the first. The names the native settings take are the core's tables too: the stub's
``Literal`` types of them (``python/genplan/_core.pyi``) hold the same names as the tables
``genplan._core`` exposes (the one test here that imports the module).
"""

from __future__ import annotations

import ast
import itertools
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1] / "python"
EXPERIMENTS = "genplan.experiments"
FRONT_END = "genplan.cli"
#: the command-line argument types, shared by the commands and the benchmarks
ARGUMENTS = "genplan.cli.args"
#: import cycles left for later (each the set of its modules)
KNOWN_CYCLES: list[set[str]] = []
#: registries that share names but name different things (pair of registries: why)
DIFFERENT_CONCEPTS = {
    frozenset({"genplan.samplers.gan.GanConfig.MEMBER_INITS", "genplan.samplers.SAMPLERS"}):
        "how a GAN's members are initialised ('uniform': PyTorch's default, 'data': at data points), not samplers",
}


def _name(path: Path) -> str:
    parts = path.relative_to(ROOT).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


FILES = {_name(p): p for p in sorted((ROOT / "genplan").rglob("*.py"))}
MODULES = set(FILES) | {"genplan._core"}


def _within(module: str, package: str) -> bool:
    return module == package or module.startswith(package + ".")


def _layer(module: str) -> str:
    if module == ARGUMENTS:
        return "arguments"
    if _within(module, FRONT_END) or module == "genplan.__main__":
        return "front end"
    return "experiments" if _within(module, EXPERIMENTS) else "library"


def _is_main_block(node: ast.AST) -> bool:
    """``if __name__ == "__main__":``"""
    t = node.test if isinstance(node, ast.If) else None
    return (isinstance(t, ast.Compare) and isinstance(t.left, ast.Name) and t.left.id == "__name__"
            and any(isinstance(c, ast.Constant) and c.value == "__main__" for c in t.comparators))


def _walk(tree: ast.AST) -> list[ast.AST]:
    """Every node of ``tree`` but those inside an ``if __name__ == "__main__":`` block."""
    out, todo = [], [tree]
    while todo:
        node = todo.pop()
        out.append(node)
        todo += [c for c in ast.iter_child_nodes(node) if not _is_main_block(c)]
    return out


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
    for node in _walk(tree):
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
        found += [(n.value, n.lineno) for n in _walk(tree)
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
    assert "genplan.samplers.gan" in edges["genplan.samplers"]  # a lazy re-export, by computed name
    assert "genplan.experiments.benchmarks.plan" in edges["genplan.cli"]  # the command table
    assert "genplan.cli" not in edges["genplan.viewer"]  # `python -m genplan.viewer` runs the CLI: not an import


def test_the_library_imports_neither_the_experiments_nor_the_cli() -> None:
    bad = _violations({"library"}, {"experiments", "front end", "arguments"})
    assert not bad, "the library must not import genplan.experiments or genplan.cli:\n" + "\n".join(bad)


def test_the_experiments_do_not_import_the_cli() -> None:
    bad = _violations({"experiments", "arguments"}, {"front end"}) + _violations({"arguments"}, {"experiments"})
    assert not bad, ("genplan.experiments and genplan.cli.args must not import the rest of genplan.cli "
                     "(genplan.cli.args imports the library only):\n" + "\n".join(bad))


def test_only_the_library_imports_the_core() -> None:
    bad = [_where(m, i, line) for m, edges in GRAPH.items() if _layer(m) != "library"
           for i, line in edges if i == "genplan._core"]
    assert not bad, "only the library imports genplan._core (use the public API):\n" + "\n".join(bad)


def _command_lines(module: str) -> list[str]:
    """Where ``module`` defines a command line: an argparse import or an ``add_arguments``."""
    tree = ast.parse(FILES[module].read_text())
    where = f"{module} ({FILES[module].relative_to(ROOT.parent)}"
    found = [f"{where}:{n.lineno}) imports argparse" for n in _walk(tree)
             if (isinstance(n, ast.Import) and any(a.name == "argparse" for a in n.names))
             or (isinstance(n, ast.ImportFrom) and n.module == "argparse")]
    found += [f"{where}:{n.lineno}) defines add_arguments" for n in tree.body
              if isinstance(n, ast.FunctionDef) and n.name == "add_arguments"]
    return found


def test_command_lines_live_in_the_cli() -> None:
    bad = [line for m in GRAPH if _layer(m) == "library" for line in _command_lines(m)]
    assert not bad, ("a command line belongs in genplan.cli (one module per command: add_arguments, main), "
                     "which calls the library:\n" + "\n".join(bad))


def _names(node: ast.AST) -> set[str] | None:
    """The names a registry literal holds (a tuple, list or set of at least two strings, possibly
    with other registries spread into it: only its own strings), else None."""
    if isinstance(node, ast.Call) and getattr(node.func, "id", None) in ("frozenset", "set", "tuple") and node.args:
        node = node.args[0]
    if not isinstance(node, (ast.Tuple, ast.List, ast.Set)):
        return None
    own = [e.value for e in node.elts if isinstance(e, ast.Constant) and isinstance(e.value, str)]
    if len(own) + sum(isinstance(e, ast.Starred) for e in node.elts) != len(node.elts) or len(own) < 2:
        return None
    return set(own)


def registries() -> dict[str, tuple[int, set[str]]]:
    """Every registry of names in the library: ``module.NAME`` (or ``module.Class.NAME``) ->
    (line, names)."""
    out = {}
    for module in GRAPH:
        if _layer(module) != "library":
            continue
        tree = ast.parse(FILES[module].read_text())
        scopes = [(tree.body, module)] + [(c.body, f"{module}.{c.name}") for c in tree.body if isinstance(c, ast.ClassDef)]
        for body, owner in scopes:
            for n in body:
                target = n.targets[0] if isinstance(n, ast.Assign) and len(n.targets) == 1 else getattr(n, "target", None)
                if (isinstance(n, (ast.Assign, ast.AnnAssign)) and isinstance(target, ast.Name)
                        and target.id.lstrip("_").isupper() and n.value is not None):
                    names = _names(n.value)
                    if names is not None:
                        out[f"{owner}.{target.id}"] = (n.lineno, names)
    return out


def test_the_registries_are_read() -> None:
    found = registries()
    assert found["genplan.samplers.SAMPLERS"][1] == {"uniform", "gan", "data"}  # its own, MIXTURES spread in
    assert "genplan.samplers.WARM_STARTS" not in found  # derived, not a literal


def test_no_registry_repeats_another() -> None:
    """A registry whose names all stand in another registry (both at least two) repeats it."""
    found = registries()
    bad = []
    for (a, (la, na)), (b, (lb, nb)) in itertools.combinations(sorted(found.items()), 2):
        if (na <= nb or nb <= na) and frozenset({a, b}) not in DIFFERENT_CONCEPTS:
            bad.append(f"{a} (line {la}) and {b} (line {lb}) both list {sorted(na & nb)}")
    assert not bad, ("a second registry of the same names: derive one from the other (or, if they name "
                     "different things, say so in DIFFERENT_CONCEPTS):\n" + "\n".join(bad))


#: the stub's Literal types of names -> the core's table (a tuple of ``genplan._core``) they spell
LITERALS = {"_Algorithm": "ALGORITHMS", "_EdgeCheck": "EDGE_CHECKS", "_Sampling": "SAMPLINGS", "_ControlSpace": "CONTROL_SPACES",
            "_LimitPolicy": "LIMIT_POLICIES"}
#: the settings of the stub typed by them: (class, field) -> Literal type
TYPED_SETTINGS = {("PlannerSettings", "algorithm"): "_Algorithm", ("PlannerSettings", "edge_check"): "_EdgeCheck",
                  ("PlannerSettings", "sampling"): "_Sampling",
                  ("ControllerSettings", "space"): "_ControlSpace", ("JointLimits", "policy"): "_LimitPolicy"}


def _stub_literals(tree: ast.Module) -> dict[str, tuple[object, ...]]:
    """The module-level ``Name: TypeAlias = Literal[...]`` of a stub: name -> its values."""
    out = {}
    for n in tree.body:
        if (isinstance(n, ast.AnnAssign) and isinstance(n.target, ast.Name) and isinstance(n.value, ast.Subscript)
                and getattr(n.value.value, "id", None) == "Literal"):
            s = n.value.slice
            out[n.target.id] = tuple(e.value for e in (s.elts if isinstance(s, ast.Tuple) else [s])
                                     if isinstance(e, ast.Constant))
    return out


def test_the_stub_literals_are_the_core_tables() -> None:
    from genplan import _core, planning

    tree = ast.parse((ROOT / "genplan" / "_core.pyi").read_text())
    literals = _stub_literals(tree)
    assert set(literals) == set(LITERALS), "a Literal type of the stub without its table in LITERALS (or gone)"
    for alias, table in LITERALS.items():
        assert literals[alias] == getattr(_core, table), f"{alias} of _core.pyi is not _core.{table}"
    # each setting is typed by its Literal, in the constructor and the attribute
    classes = {c.name: c for c in tree.body if isinstance(c, ast.ClassDef)}
    for (cls, field), alias in TYPED_SETTINGS.items():
        seen = []
        for f in classes[cls].body:
            if isinstance(f, ast.FunctionDef):
                seen += [ast.unparse(a.annotation) for a in f.args.args + f.args.kwonlyargs
                         if a.arg == field and a.annotation is not None]
                if f.name == field and f.returns is not None:
                    seen.append(ast.unparse(f.returns))
        assert seen == [alias, alias], f"{cls}.{field}: typed {seen}, not {alias} (constructor and attribute)"
    # the library's own lists of the planner's names hold the tables' names
    assert (planning.ALGORITHMS, planning.EDGE_CHECKS) == (_core.ALGORITHMS, _core.EDGE_CHECKS)


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
