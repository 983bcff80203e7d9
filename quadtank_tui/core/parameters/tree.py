"""Changing values deep inside the frozen model: several changes are applied at
once and validated together (a pair of values valid only together, such as a
sampling time and a period, can be set in one step).

Only the objects on the changed paths are rebuilt (and so validated again); every
other object is shared with the model before, which was valid.  A dataclass's
checks read its own fields only, and every object holding a changed one is on a
changed path, so this validates what a rebuild of the whole model would, at a
small part of its cost (a Setup edit, a command's parameters: every SetParams)."""

from __future__ import annotations

import dataclasses
from typing import Any, Mapping, Sequence, TypeVar

from quadtank_tui.core.parameters.keys import SECTION_OF_PATH
from quadtank_tui.core.ranges import ParameterError

T = TypeVar("T")


def walk(obj: Any, path: Sequence[str | int]) -> Any:
    """The value at `path` (attribute names and tuple indices) inside `obj`."""
    for step in path:
        obj = obj[step] if isinstance(step, int) else getattr(obj, step)
    return obj


class _Leaf:
    """A new value in a change tree (so a value is never taken for a branch)."""

    __slots__ = ("value",)

    def __init__(self, value: Any) -> None:
        self.value = value


def replaced(obj: T, changes: Mapping[tuple[str | int, ...], Any]) -> T:
    """A copy of `obj` with the value at each path of `changes` replaced, every
    object on those paths rebuilt (validated); a nested object's ParameterError is
    renamed to the full "SECTION.Key".  A later path equal to an earlier one wins."""
    tree: dict[str | int, Any] = {}
    for path, value in changes.items():
        node = tree
        for step in path[:-1]:
            node = node.setdefault(step, {})
        node[path[-1]] = _Leaf(value)
    rebuilt: T = _rebuild(obj, tree, ())
    return rebuilt


def _rebuild(obj: Any, tree: dict[str | int, Any], path: tuple[str | int, ...]) -> Any:
    new = {step: sub.value if isinstance(sub, _Leaf) else _rebuild(walk(obj, (step,)), sub, (*path, step))
           for step, sub in tree.items()}
    if isinstance(obj, tuple):
        return tuple(new.get(i, x) for i, x in enumerate(obj))
    kwargs = {f.name: new[f.name] if f.name in new else getattr(obj, f.name) for f in dataclasses.fields(obj)}
    try:
        return type(obj)(**kwargs)
    except ParameterError as exc:
        if "." in exc.field or path not in SECTION_OF_PATH:
            raise
        raise ParameterError(f"{SECTION_OF_PATH[path]}.{exc.field}", exc.reason) from None
