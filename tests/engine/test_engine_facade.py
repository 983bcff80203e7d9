"""Engine is the engine's facade: nothing outside engine/ in the package reaches
through it into its ControlLoop (`engine.loop...`), so the loop's insides can change
without the session, the use cases or the commands changing with them.  Read from
the source with `ast`."""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).parents[2] / "quadtank_tui"


def reach_throughs(path: Path) -> list[int]:
    """Lines of `path` that read `.loop` of something named engine (engine.loop,
    self.engine.loop, run.engine.loop, self._engine.loop)."""
    lines = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Attribute) and node.attr == "loop":
            owner = node.value
            name = owner.id if isinstance(owner, ast.Name) else owner.attr if isinstance(owner, ast.Attribute) else ""
            if name.lstrip("_") == "engine":
                lines.append(node.lineno)
    return lines


def test_the_scan_finds_a_reach_through(tmp_path: Path) -> None:
    src = tmp_path / "m.py"
    src.write_text("def f(run, loop):\n    run.engine.loop.h\n    loop.h\n    self_engine = 1\n")
    assert reach_throughs(src) == [2]


def test_nothing_outside_engine_reaches_into_the_loop() -> None:
    engine = PACKAGE / "engine"
    found = [f"{p.relative_to(PACKAGE)}:{n}" for p in sorted(PACKAGE.rglob("*.py"))
             if engine not in p.parents for n in reach_throughs(p)]
    assert found == []
