"""Reading the project's YAML files (experiment scripts, DAQ configurations) with
errors that name the file and line, whatever went wrong: missing file, bad bytes,
or YAML that does not parse.  Both readers also need the composed node tree, whose
marks give the line of every key for their own validation messages."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Callable

import yaml

#: Builds the reader's own error from (file name, message, line or None).
ErrorFactory = Callable[[str, str, "int | None"], Exception]


def read_text(path: Path | str, error: ErrorFactory) -> str:
    """The file's text, or `error(path, reason, None)` raised."""
    try:
        return Path(path).read_text(encoding="utf-8")
    except FileNotFoundError:
        raise error(str(path), "no such file", None) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise error(str(path), f"cannot read: {exc}", None) from None


def parse_yaml(text: str, name: str, error: ErrorFactory) -> tuple[Any, Any]:
    """(node tree, data) of `text`; invalid YAML raises `error` with the line."""
    try:
        node = yaml.compose(text, Loader=yaml.SafeLoader)
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        problem = getattr(exc, "problem", None) or getattr(exc, "reason", None) or str(exc)
        problem = " ".join(str(problem).split())
        raise error(name, f"not valid YAML: {problem}", None if mark is None else mark.line + 1) from None
    return node, data
