"""The package's modules import one another without a circle.

Read from the source with `ast`: every import, at module level, inside a function or
under TYPE_CHECKING, so an import put late to dodge a circle at run time still
counts (two modules in a circle are one module in two files: neither can be read,
tested or loaded without the other).  A module importing its own package's
`__init__` (a parent) is not a circle of modules.
"""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).parents[1]
PACKAGE = ROOT / "quadtank_tui"

#: Circles still in the tree, each to be broken by the room that owns it; the test
#: fails when one is gone too, so that this list only shrinks.
KNOWN: set[frozenset[str]] = {
    frozenset({"quadtank_tui.session.lab", "quadtank_tui.session.roles"}),
}


def module_name(path: Path) -> str:
    parts = path.relative_to(ROOT).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imports_of(path: Path, name: str, modules: set[str]) -> set[str]:
    """The package's modules that `path` (module `name`) imports."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), filename=str(path))):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                module = ".".join([*base, node.module] if node.module else base)
            else:
                module = node.module or ""
            found.add(module)
            found.update(f"{module}.{alias.name}" for alias in node.names)  # `from pkg import mod`
    return {m for m in found if m in modules and m != name and not name.startswith(m + ".")}


def import_graph() -> dict[str, set[str]]:
    paths = {module_name(p): p for p in PACKAGE.rglob("*.py")}
    modules = set(paths)
    return {name: imports_of(path, name, modules) for name, path in paths.items()}


def circles(graph: dict[str, set[str]]) -> list[frozenset[str]]:
    """The strongly connected sets of more than one module (Tarjan's algorithm)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[frozenset[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = set()
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.add(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(frozenset(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def test_the_scan_finds_a_circle_and_its_members() -> None:
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}, "e": set()}
    assert circles(graph) == [frozenset({"a", "b", "c"})]


def test_the_scan_reads_every_kind_of_import(tmp_path: Path) -> None:
    src = tmp_path / "m.py"
    src.write_text("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from p.x import y\n"
                   "def f():\n    from . import z\n    import p.w\n")
    assert imports_of(src, "p.m", {"p.x", "p.x.y", "p.z", "p.w", "p"}) == {"p.x", "p.x.y", "p.z", "p.w"}


def test_the_package_imports_form_no_circle() -> None:
    graph = import_graph()
    assert len(graph) > 200  # the whole package was read
    found = set(circles(graph))
    new = sorted(" <-> ".join(sorted(c)) for c in found - KNOWN)
    gone = sorted(" <-> ".join(sorted(c)) for c in KNOWN - found)
    assert not new, f"import circles: {new}"
    assert not gone, f"no longer circles, take them out of KNOWN: {gone}"


def ui_part_graph() -> dict[str, set[str]]:
    """The UI's parts (a subpackage of ui/ such as widgets or windows, or a module
    directly in it such as app or labels) -> the other parts they import."""
    prefix = "quadtank_tui.ui."
    graph: dict[str, set[str]] = {}
    for name, imported in import_graph().items():
        if not name.startswith(prefix):
            continue
        src = name[len(prefix):].split(".")[0]
        graph.setdefault(src, set())
        for module in imported:
            if module.startswith(prefix) and (dst := module[len(prefix):].split(".")[0]) != src:
                graph.setdefault(src, set()).add(dst)
    return graph


def test_the_ui_parts_import_one_another_in_one_direction() -> None:
    """Screens use windows and widgets, windows use widgets, nothing below imports
    what is built on it: a circle between two parts (widgets <-> windows once, for a
    few shared labels) loads every module of both whenever one loads, and hides
    which is the lower layer; shared labels live in ui/labels.py."""
    graph = ui_part_graph()
    assert {"windows", "widgets"} <= graph["screens"] and "widgets" in graph["windows"]  # the known edges
    assert circles(graph) == [], {k: sorted(v) for k, v in sorted(graph.items())}
