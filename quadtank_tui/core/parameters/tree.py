"""The model as a tree of plain values: several changes are applied to the tree,
then the frozen model is rebuilt and validated once (a pair of values valid only
together, such as a sampling time and a period, can be set in one step)."""

from __future__ import annotations

import dataclasses
from typing import Any, Sequence

from quadtank_tui.core.parameters.keys import SECTION_OF_PATH
from quadtank_tui.core.validation import ParameterError


def walk(obj: Any, path: Sequence[str | int]) -> Any:
    """The value at `path` (attribute names and tuple indices) inside `obj`."""
    for step in path:
        obj = obj[step] if isinstance(step, int) else getattr(obj, step)
    return obj


def to_tree(obj: Any) -> Any:
    """Dataclasses as dicts and tuples as lists, recursively (a mutable copy)."""
    if dataclasses.is_dataclass(obj):
        return {f.name: to_tree(getattr(obj, f.name)) for f in dataclasses.fields(obj)}
    if isinstance(obj, tuple):
        return [to_tree(x) for x in obj]
    return obj


def set_leaf(tree: Any, path: Sequence[str | int], value: Any) -> None:
    """Put `value` at `path` in a tree made by :func:`to_tree`."""
    for step in path[:-1]:
        tree = tree[step]
    tree[path[-1]] = value


def from_tree(template: Any, tree: Any, path: tuple[str | int, ...]) -> Any:
    """Rebuild `template`'s type from `tree`, validating every object; a nested
    object's ParameterError is renamed to the full "SECTION.Key"."""
    if dataclasses.is_dataclass(template):
        kwargs = {
            f.name: from_tree(getattr(template, f.name), tree[f.name], (*path, f.name))
            for f in dataclasses.fields(template)
        }
        cls: type[Any] = type(template)  # an instance's class (is_dataclass also admits classes)
        try:
            return cls(**kwargs)
        except ParameterError as exc:
            if "." in exc.field or path not in SECTION_OF_PATH:
                raise
            raise ParameterError(f"{SECTION_OF_PATH[path]}.{exc.field}", exc.reason) from None
    if isinstance(template, tuple):
        if isinstance(tree, tuple):  # a leaf just set (LOGGING.Variables): any length
            return tree
        return tuple(from_tree(t, x, (*path, i)) for i, (t, x) in enumerate(zip(template, tree)))
    return tree
