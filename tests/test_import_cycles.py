"""No module of varint imports, directly or through others, a module that
imports it back — counting imports inside functions (the ones that climbed
up a layer: results → plotting → indicators → results), not counting those
a type checker alone reads (``if TYPE_CHECKING:``). Read from the source
with :mod:`ast`, so nothing is imported to check it."""

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parent.parent / "varint"


def _modules():
    out = {}
    for path in PACKAGE.rglob("*.py"):
        parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts.pop()
        out[".".join(parts)] = path
    return out


def _imports(name, source, is_package, modules):
    """The modules of ``modules`` that module ``name`` (its ``source``; a
    package's ``__init__`` where ``is_package``) imports anywhere."""
    tree = ast.parse(source)
    typing_only = {id(node) for branch in ast.walk(tree) if isinstance(branch, ast.If)
                   and "TYPE_CHECKING" in ast.unparse(branch.test)
                   for statement in branch.body for node in ast.walk(statement)}
    package = name.split(".") if is_package else name.split(".")[:-1]
    out = set()
    for node in ast.walk(tree):
        if id(node) in typing_only:
            continue
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = ".".join(package[:len(package) - node.level + 1] if node.level else [])
            base = ".".join(filter(None, [base, node.module]))
            targets = [f"{base}.{alias.name}" for alias in node.names]
        else:
            continue
        for target in targets:
            while target and target not in modules:
                target = target.rpartition(".")[0]
            if target and target != name:
                out.add(target)
    return out


def _cycle(graph):
    """One import cycle of ``graph`` as a list of modules, or None."""
    state = {}

    def visit(node, trail):
        state[node] = "open"
        for dep in sorted(graph[node]):
            if state.get(dep) == "open":
                return trail[trail.index(dep):] + [dep]
            if dep not in state:
                found = visit(dep, trail + [dep])
                if found:
                    return found
        state[node] = "done"
        return None

    for start in sorted(graph):
        if start not in state:
            found = visit(start, [start])
            if found:
                return found
    return None


def test_no_module_imports_one_that_imports_it_back():
    modules = _modules()
    graph = {name: _imports(name, path.read_text(encoding="utf-8"),
                            path.name == "__init__.py", modules)
             for name, path in modules.items()}
    cycle = _cycle(graph)
    assert cycle is None, "import cycle: " + " -> ".join(cycle)


def test_the_check_sees_a_cycle_through_an_import_inside_a_function():
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}
    assert _cycle(graph) == ["a", "b", "c", "a"]
    assert _cycle({"a": {"b"}, "b": set()}) is None
    modules = {"varint.a": None, "varint.b": None, "varint.b.c": None, "varint.t": None}
    source = ("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from . import t\n"
              "def f():\n    from .b import c, g\n    import numpy\n")
    assert _imports("varint.a", source, False, modules) == {"varint.b", "varint.b.c"}
