"""The loop's state is changed only through its own methods (issue 16, "the loop
runtime underneath"): no module but engine/loop.py assigns to an attribute of a
ControlLoop.  An AST scan over the package, the tests and the benchmarks."""

from __future__ import annotations

import ast
import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from quadtank_tui.core.parameters import PRESET
from quadtank_tui.engine.commands import SetOperation, SetState
from quadtank_tui.engine.loop import ControlLoop

ROOT = Path(__file__).resolve().parents[2]
LOOP_MODULE = ROOT / "quadtank_tui" / "engine" / "loop.py"
#: A write the scan reports goes through `loop`, `control`, `control_loop` (names or
#: attributes) or a name bound to a ControlLoop: a source without these words has none.
MENTIONS_A_LOOP = re.compile(r"\b(loop|control|control_loop)\b|ControlLoop")


def _loop_names(nodes: list[ast.AST]) -> set[str]:
    """Names that hold a ControlLoop in this module: `loop`, `control`, whatever is
    annotated ControlLoop or assigned ControlLoop(...)."""
    names = {"loop", "control", "control_loop"}
    for node in nodes:
        if isinstance(node, (ast.arg, ast.AnnAssign)):
            ann = node.annotation
            target = node.arg if isinstance(node, ast.arg) else getattr(node.target, "id", None)
            if ann is not None and target and "ControlLoop" in ast.unparse(ann):
                names.add(target)
        if isinstance(node, ast.Assign) and isinstance(node.value, ast.Call):
            if _called(node.value.func) == "ControlLoop":
                names.update(t.id for t in node.targets if isinstance(t, ast.Name))
    return names


def _called(func: ast.expr) -> str:
    """The last name of what a call calls: `setattr` for `setattr(...)` and for
    `monkeypatch.setattr(...)` (what `ast.unparse(func).split(".")[-1]` gives, without
    unparsing every call of the tree)."""
    if isinstance(func, ast.Name):
        return func.id
    return func.attr if isinstance(func, ast.Attribute) else ""


def _is_loop(expr: ast.expr, names: set[str]) -> bool:
    """`loop`, `engine.loop`, `self.loop`, `e.loop`, ... or a name bound to a ControlLoop."""
    if isinstance(expr, ast.Name):
        return expr.id in names
    return isinstance(expr, ast.Attribute) and expr.attr in ("loop", "control_loop")


def outside_writes(source: str, filename: str = "<source>") -> list[str]:
    """Every assignment (=, +=, annotated, del, setattr, monkeypatch.setattr) to an
    attribute of a ControlLoop in `source`, as 'file:line: text'."""
    if not MENTIONS_A_LOOP.search(source):  # no name a write could go through: nothing to parse
        return []
    nodes = list(ast.walk(ast.parse(source, filename)))  # one walk for both passes
    names = _loop_names(nodes)
    found: list[str] = []
    for node in nodes:
        targets: list[ast.expr] = []
        if isinstance(node, ast.Assign):
            targets = list(node.targets)
        elif isinstance(node, (ast.AugAssign, ast.AnnAssign)):
            targets = [node.target]
        elif isinstance(node, ast.Delete):
            targets = list(node.targets)
        elif isinstance(node, ast.Call) and _called(node.func) == "setattr" and node.args:
            if _is_loop(node.args[0], names):
                found.append(f"{filename}:{node.lineno}: {ast.unparse(node)}")
            continue
        flat: list[ast.expr] = []
        for t in targets:
            flat.extend(t.elts if isinstance(t, (ast.Tuple, ast.List)) else [t])
        for t in flat:
            if isinstance(t, ast.Attribute) and _is_loop(t.value, names):
                found.append(f"{filename}:{getattr(node, 'lineno', 0)}: {ast.unparse(t)}")
    return found


def _sources() -> list[Path]:
    files = [p for d in ("quadtank_tui", "tests", "benchmarks") for p in sorted((ROOT / d).rglob("*.py"))]
    return [p for p in files if p != LOOP_MODULE]


def test_no_module_but_the_loop_assigns_to_its_attributes() -> None:
    found = [w for p in _sources() for w in outside_writes(p.read_text(), str(p.relative_to(ROOT)))]
    assert found == []


@pytest.mark.parametrize("line", [
    "engine.loop.fault = 'x'",
    "self.loop.running = False",
    "loop.history = shared.history",
    "loop.k += 1",
    "e.loop.t, x = 0.0, 1",
    "setattr(engine.loop, 'fault', None)",
    "monkeypatch.setattr(loop, 'running', True)",
    "del loop.fault",
    "lp = ControlLoop(PRESET)\nlp.running = True",
    "def f(cl: ControlLoop) -> None:\n    cl.on_publish = print",
])
def test_the_scan_sees_each_way_of_writing(line: str) -> None:
    assert len(outside_writes(line)) == 1


@pytest.mark.parametrize("line", [
    "self.loop = 1",                       # the Design screen's loop number
    "loop.apply(SetState('Run'))",
    "x = engine.loop.fault",
    "aloop.x = 1",
    "engine.loop.sim.plant = None",        # the simulator's own attribute, not the loop's
])
def test_the_scan_leaves_reads_and_other_objects_alone(line: str) -> None:
    assert outside_writes(line) == []


def test_the_drivers_hooks_do_what_the_assignments_did(tmp_path: Path, rig: Any) -> None:
    loop = ControlLoop(PRESET, logs_dir=tmp_path, daq=rig)
    for _ in range(3):
        loop.step()  # paused: nothing in the history
    assert loop.apply(SetState("Run")).ok
    for _ in range(4):
        loop.step()
    np.testing.assert_allclose(loop.history.last()["t"], [0.0, loop.h, 2 * loop.h, 3 * loop.h])
    assert loop.apply(SetOperation("Active")).ok and loop.apply(SetState("Run")).ok
    loop.step()
    loop.halt("engine stopped: RuntimeError: boom")
    snap = loop.snapshot()
    assert (snap.state, snap.fault) == ("Pause", "engine stopped: RuntimeError: boom")
    assert rig.calls[-2:] == ["pumps 0.3 0.3", "safe"]
    assert loop.apply(SetState("Run")).ok and loop.snapshot().fault is None
    loop.shut_down()
    assert loop.snapshot().state == "Pause" and rig.calls[-2:] == ["safe", "close"]
