"""The import graph of the ``app`` package has no cycles.

The rule: an edge A -> B is any ``import`` / ``from ... import`` in A's source that names module B of
``app``, at module level or inside a function or method (a lazy import still makes A depend on B; the
cycle cli <-> export/osl of issue 17 went through lazy imports). Not edges:
- imports under ``if TYPE_CHECKING:``: they never run, and with ``from __future__ import annotations`` the
  names they bring only appear in annotations (viewer/script.py's Viewer, for one);
- imports under ``if __name__ == "__main__":``: they run only when the module is the program, loaded as
  ``__main__`` and not under its own name, so they cannot close a cycle;
- the implicit import of a parent package: a package's ``__init__`` that lazily imports one of its modules
  is not a cycle with that module.
``from pkg import name`` is an edge to ``pkg.name`` when that is a module, else to ``pkg`` (its
``__init__``).
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest
from tests.support.paths import ROOT

APP = ROOT / "app"


def module_name(path: Path, root: Path) -> str:
    parts = list(path.relative_to(root.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _is_type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING")


def _is_main_guard(test: ast.expr) -> bool:
    return (isinstance(test, ast.Compare) and isinstance(test.left, ast.Name) and test.left.id == "__name__"
            and len(test.comparators) == 1 and isinstance(test.comparators[0], ast.Constant)
            and test.comparators[0].value == "__main__")


def _imports(tree: ast.AST):
    """Every import node that can run when the module is imported: all of them except those under
    ``if TYPE_CHECKING:`` and ``if __name__ == "__main__":`` (their ``else`` branches do count)."""
    stack = [tree]
    while stack:
        node = stack.pop()
        if isinstance(node, ast.If) and (_is_type_checking(node.test) or _is_main_guard(node.test)):
            stack.extend(node.orelse)
            continue
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            yield node
        stack.extend(ast.iter_child_nodes(node))


def import_graph(root: Path = APP) -> dict[str, set[str]]:
    """{module: modules of the package it imports}, from the source alone (nothing is imported)."""
    files = {module_name(p, root): p for p in sorted(root.rglob("*.py"))}
    top = root.name
    graph: dict[str, set[str]] = {name: set() for name in files}
    for name, path in files.items():
        is_package = path.name == "__init__.py"
        package = name if is_package else name.rpartition(".")[0]
        for node in _imports(ast.parse(path.read_text(encoding="utf-8"), str(path))):
            if isinstance(node, ast.Import):
                targets = [alias.name for alias in node.names]
            else:
                if node.level:
                    base = package.split(".")
                    base = base[:len(base) - (node.level - 1)]
                    mod = ".".join(base + ([node.module] if node.module else []))
                else:
                    mod = node.module or ""
                targets = [f"{mod}.{alias.name}" if f"{mod}.{alias.name}" in files else mod
                           for alias in node.names]
            for target in targets:
                if target != top and not target.startswith(top + "."):
                    continue
                # ``import app.a.b`` names app.a.b; a name that is no module of ours is an attribute of one
                while target not in files and "." in target:
                    target = target.rpartition(".")[0]
                if target in files and target != name:
                    graph[name].add(target)
    return graph


def find_cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components with more than one module (Tarjan), each as one cycle through it."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    on_stack: set[str] = set()
    stack: list[str] = []
    components: list[list[str]] = []
    counter = 0

    def visit(v: str) -> None:
        nonlocal counter
        index[v] = low[v] = counter
        counter += 1
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                components.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return [_one_cycle(graph, comp) for comp in components]


def _one_cycle(graph: dict[str, set[str]], comp: list[str]) -> list[str]:
    """A shortest cycle through the component's first module, for a message a person can act on."""
    members, start = set(comp), comp[0]
    paths, frontier = {start: [start]}, [start]
    while frontier:
        nxt = []
        for v in frontier:
            for w in sorted(graph[v] & members):
                if w == start:
                    return paths[v] + [start]
                if w not in paths:
                    paths[w] = paths[v] + [w]
                    nxt.append(w)
        frontier = nxt
    return comp


def test_the_app_package_has_no_import_cycles():
    cycles = find_cycles(import_graph())
    assert not cycles, "import cycles in app/ (break them by moving the shared name down a layer):\n" + "\n".join(
        " -> ".join(c) for c in cycles)


def test_the_graph_sees_the_imports_it_must(tmp_path):
    """The checker finds cycles through relative, absolute and lazy imports, and ignores TYPE_CHECKING ones:
    a checker that finds nothing would pass the test above for nothing."""
    pkg = tmp_path / "app"
    (pkg / "sub").mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "sub" / "__init__.py").write_text("def f():\n    from .b import g\n")
    (pkg / "a.py").write_text("from .sub import b\n")                          # relative, names a module
    (pkg / "sub" / "b.py").write_text("def g():\n    import app.c\n")          # absolute, lazy
    (pkg / "c.py").write_text("from app.a import thing\n")                     # absolute, names an attribute
    (pkg / "d.py").write_text("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from .e import E\n")
    (pkg / "e.py").write_text("from . import d\n")
    (pkg / "f.py").write_text("import app.e\nif __name__ == '__main__':\n    from app import a, d, e\n")
    graph = import_graph(pkg)
    assert graph["app.a"] == {"app.sub.b"} and graph["app.sub.b"] == {"app.c"} and graph["app.c"] == {"app.a"}
    assert graph["app.d"] == set() and graph["app.e"] == {"app.d"} and graph["app.f"] == {"app.e"}
    assert graph["app.sub"] == {"app.sub.b"}
    assert find_cycles(graph) == [["app.a", "app.sub.b", "app.c", "app.a"]]


@pytest.mark.parametrize("source,target", [
    ("from .. import reference", "app.reference"),
    ("from ..render.explicit import ExplicitRenderer", "app.render.explicit"),
    ("import app.units as u", "app.units"),
    ("from app.render import budget", "app.render.budget"),
    ("from app.render import Renderer", "app.render"),
    ("from . import state", "app.viewer.state"),
    ("def f():\n    if True:\n        from ..units import human_bytes", "app.units"),
])
def test_each_import_form_is_an_edge(tmp_path, source, target):
    pkg = tmp_path / "app"
    for module in ("__init__", "reference", "units", "render/__init__", "render/explicit", "render/budget",
                   "viewer/__init__", "viewer/state"):
        (pkg / module).parent.mkdir(parents=True, exist_ok=True)
        (pkg / f"{module}.py").write_text("")
    (pkg / "viewer" / "probe.py").write_text(source + "\n")
    assert import_graph(pkg)["app.viewer.probe"] == {target}
