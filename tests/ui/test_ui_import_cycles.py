"""The UI's parts import one another in one direction only (issue 18): screens use
windows and widgets, windows use widgets, and nothing below imports what is built
on it.  A cycle between two subpackages (widgets <-> windows once did it, for a few
shared labels) makes every module of both load whenever one does, and hides which
is the lower layer; shared labels live in ui/labels.py.

Read from the source with `ast` (every import, at module level or inside a
function), so an import done late to dodge the cycle at run time still counts."""

from __future__ import annotations

import ast
from pathlib import Path

UI = Path(__file__).parents[2] / "quadtank_tui" / "ui"
PREFIX = "quadtank_tui.ui."


def part_of(module: str) -> str | None:
    """The ui part a module belongs to: its subpackage (widgets, windows, ...) or,
    for a module directly in ui/, the module itself (app, labels, values, ...)."""
    if not module.startswith(PREFIX):
        return None
    return module[len(PREFIX):].split(".")[0]


def imports_of(path: Path) -> set[str]:
    """Every module `path` imports, absolute."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    out: set[str] = set()
    package = ".".join(("quadtank_tui", "ui", *path.relative_to(UI).parent.parts))
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                module = ".".join([*base, node.module] if node.module else base)
            else:
                module = node.module or ""
            out.add(module)
            out.update(f"{module}.{alias.name}" for alias in node.names)  # `from pkg import mod`
    return out


def part_graph() -> dict[str, set[str]]:
    """part -> the other parts it imports."""
    graph: dict[str, set[str]] = {}
    for path in UI.rglob("*.py"):
        rel = path.relative_to(UI)
        src = rel.parts[0].removesuffix(".py") if len(rel.parts) == 1 else rel.parts[0]
        if src == "__init__":
            continue
        for module in imports_of(path):
            dst = part_of(module)
            if dst is not None and dst != src and ((UI / dst).is_dir() or (UI / f"{dst}.py").exists()):
                graph.setdefault(src, set()).add(dst)
    return graph


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components with more than one part (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def test_the_cycle_finder_finds_a_cycle() -> None:
    assert cycles({"widgets": {"windows"}, "windows": {"widgets"}, "screens": {"windows"}}) == [
        ["widgets", "windows"]]
    assert cycles({"screens": {"windows", "widgets"}, "windows": {"widgets"}}) == []


def test_the_graph_sees_the_known_edges() -> None:
    graph = part_graph()
    assert {"windows", "widgets"} <= graph["screens"]
    assert "widgets" in graph["windows"]


def test_no_import_cycle_between_ui_parts() -> None:
    graph = part_graph()
    assert cycles(graph) == [], {k: sorted(v) for k, v in sorted(graph.items())}
