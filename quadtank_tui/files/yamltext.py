"""Reading the project's YAML files (experiment scripts, DAQ configurations) with
errors that name the file and line, whatever went wrong: missing file, not a
regular file, bad bytes, YAML that does not parse, or YAML built to hurt (nested
hundreds of levels deep, or aliases that expand to millions of values: a
"billion laughs").  Both readers also need the composed node tree, whose marks
give the line of every key for their own validation messages.

The limits are checked on the event stream, before anything is composed or
built, so a hostile file costs a bounded time and memory.  Numbers: `1e3` is
read as a number (YAML 1.1 wants `1.0e+3`); a UTF-8 byte-order mark is skipped.
"""

from __future__ import annotations

import functools
import re
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable

from quadtank_tui.files.regular import read_regular

if TYPE_CHECKING:  # loaded when a file is parsed: the TUI's first frame needs none
    import yaml

#: Builds the reader's own error from (file name, message, line or None).
ErrorFactory = Callable[[str, str, "int | None"], Exception]

#: A script or a DAQ configuration is a few kB.
MAX_BYTES = 1_000_000
#: Collections inside collections: a configuration needs 4, a script 3.
MAX_DEPTH = 32
#: Values once every alias is expanded (a long script has a few thousand).
MAX_NODES = 200_000


@functools.cache
def _loader() -> type[yaml.SafeLoader]:
    """SafeLoader that also reads `1e3`, `-2.5E-4` as floats."""
    import yaml

    class Loader(yaml.SafeLoader):
        pass

    Loader.add_implicit_resolver(
        "tag:yaml.org,2002:float",
        re.compile(r"^[-+]?(?:[0-9][0-9_]*(?:\.[0-9_]*)?|\.[0-9_]+)[eE][-+]?[0-9]+$"),
        list("-+0123456789."),
    )
    return Loader


def read_text(path: Path | str, error: ErrorFactory) -> str:
    """The file's text, or `error(path, reason, None)` raised."""
    try:
        data = read_regular(path, MAX_BYTES)
    except FileNotFoundError:
        raise error(str(path), "no such file", None) from None
    except OSError as exc:
        raise error(str(path), f"cannot read: {exc.strerror or exc}", None) from None
    if len(data) > MAX_BYTES:
        raise error(str(path), f"larger than {MAX_BYTES} bytes: not a script or configuration", None)
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = data[: exc.start].count(b"\n") + 1
        raise error(str(path), f"not UTF-8 text (undecodable byte {data[exc.start]:#04x})", line) from None


def parse_yaml(text: str, name: str, error: ErrorFactory) -> tuple[Any, Any]:
    """(node tree, data) of `text`; invalid or hostile YAML raises `error` with
    the line."""
    import yaml

    text = text.removeprefix("\ufeff")
    try:
        _check_size(text, name, error)
        loader = _loader()(text)
        try:
            node = loader.get_single_node()
            data = None if node is None else loader.construct_document(node)
        finally:
            loader.dispose()
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        problem = getattr(exc, "problem", None) or getattr(exc, "reason", None) or str(exc)
        problem = " ".join(str(problem).split())
        raise error(name, f"not valid YAML: {problem}", None if mark is None else mark.line + 1) from None
    return node, data


def _check_size(text: str, name: str, error: ErrorFactory) -> None:
    """Refuse, from the events alone, a document nested deeper than MAX_DEPTH or
    larger than MAX_NODES values with its aliases expanded."""
    import yaml

    total = 0
    open_: list[tuple[str | None, int]] = []  # (anchor, total at its start)
    sizes: dict[str, int] = {}  # anchor -> values it expands to
    for event in yaml.parse(text, Loader=_loader()):
        if isinstance(event, yaml.AliasEvent):
            total += sizes.get(event.anchor, 1)
        elif isinstance(event, yaml.ScalarEvent):
            total += 1
            if event.anchor is not None:
                sizes[event.anchor] = 1
        elif isinstance(event, (yaml.SequenceStartEvent, yaml.MappingStartEvent)):
            total += 1
            open_.append((event.anchor, total - 1))
            if len(open_) > MAX_DEPTH:
                raise error(name, f"nested deeper than {MAX_DEPTH} levels", event.start_mark.line + 1)
        elif isinstance(event, (yaml.SequenceEndEvent, yaml.MappingEndEvent)):
            anchor, start = open_.pop()
            if anchor is not None:
                sizes[anchor] = total - start
        if total > MAX_NODES:
            raise error(name, f"more than {MAX_NODES} values once its aliases (*name) are expanded",
                        event.start_mark.line + 1)


def key_lines(node: yaml.Node | None, prefix: str = "") -> dict[str, int]:
    """Dotted key (`a.b`, `list.0.c`) -> 1-based line of that key in the file (the
    node tree's marks), for messages that name the line of a bad value."""
    import yaml

    out: dict[str, int] = {}
    if isinstance(node, yaml.MappingNode):
        for k, val in node.value:
            key = f"{prefix}{k.value}" if isinstance(k, yaml.ScalarNode) else prefix.rstrip(".")
            out[key] = k.start_mark.line + 1
            out.update(key_lines(val, key + "."))
    elif isinstance(node, yaml.SequenceNode):
        for i, item in enumerate(node.value):
            key = f"{prefix}{i}"
            out[key] = item.start_mark.line + 1
            out.update(key_lines(item, key + "."))
    return out
