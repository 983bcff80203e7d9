"""The names a parameter set holds for files and screens: the log's file name, the
columns a `.log` may have, the plot types of the two trends.

They are about files and screens, not about the process, so they live here rather
than in the core: the core's model keeps them as plain text, and every
way in (a `.par` file, a script, the engine's SetParams, the windows) checks them
with :func:`check_names`, which refuses with the full "SECTION.Key" so a file
reader can name the line.  The UI imports the lists from here (files is below it).

>>> check_names({"PLOTS.Upper": "Y1  y2 ref1 REF2", "LOGGING.Variables": "t y1"})
{'PLOTS.Upper': 'y1 y2 ref1 ref2', 'LOGGING.Variables': ('t', 'y1')}
"""

from __future__ import annotations

import re
from typing import Any, Mapping, Sequence

from quadtank_tui.core.ranges import ParameterError

#: Columns a `.log` may hold, in the order the Logging window lists them.
LOG_VARIABLES = ("t", "y1", "y2", "y3", "y4", "u1", "u2", "r1", "r2")
#: Plot types of the two trends (thesis Figure 35).
PLOT_TYPES = ("u1", "u2", "u1 u2", "y1 ref1", "y2 ref2", "y1 y2 ref1 ref2", "y1 y2 y3 y4")

_FILE_NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.\-]{0,99}")

LOG_FILE_KEY = "LOGGING.LogFile"
VARIABLES_KEY = "LOGGING.Variables"
PLOT_KEYS = ("PLOTS.Upper", "PLOTS.Lower")


def check_file_name(name: Any, key: str = "LogFile") -> str:
    """A file name (log or parameter file) is a name, not a path: letters, digits,
    `_`, `-`, `.`; it may not start with a dot or contain `..`, so it cannot leave
    its folder (`logs/`, `params/`) whatever the user types."""
    if not isinstance(name, str) or not _FILE_NAME.fullmatch(name) or ".." in name:
        raise ParameterError(
            key, f"must be a plain file name (letters, digits, _ - .; no folders), got {name!r}"
        )
    return name


def check_variables(key: str, names: Sequence[str] | str) -> tuple[str, ...]:
    """Log columns: a non-empty, repeat-free choice from :data:`LOG_VARIABLES`
    (a list, or one string of names separated by spaces)."""
    names = tuple(names.split()) if isinstance(names, str) else tuple(names)
    bad = [n for n in names if n not in LOG_VARIABLES]
    if not names or bad or len(set(names)) != len(names):
        why = f"unknown {' '.join(map(str, bad))}" if bad else ("none given" if not names else "a name is repeated")
        raise ParameterError(key, f"must be distinct names from {' '.join(LOG_VARIABLES)} ({why})")
    return names


def check_plot_type(key: str, value: Any) -> str:
    """One of :data:`PLOT_TYPES`, whatever its case and spacing."""
    text = " ".join(value.split()).lower() if isinstance(value, str) else None
    for choice in PLOT_TYPES:
        if text == choice:
            return choice
    raise ParameterError(key, f"must be one of {', '.join(PLOT_TYPES)}; got {value!r}")


def check_names(changes: Mapping[str, Any]) -> dict[str, Any]:
    """`changes` ("SECTION.Key" -> value) with its file and screen names checked and
    in their canonical form; other keys pass unchanged.  ParameterError names the key."""
    out = dict(changes)
    if LOG_FILE_KEY in out:
        out[LOG_FILE_KEY] = check_file_name(out[LOG_FILE_KEY], LOG_FILE_KEY)
    if VARIABLES_KEY in out:
        value = out[VARIABLES_KEY]
        if not isinstance(value, (str, list, tuple)):
            raise ParameterError(VARIABLES_KEY, f"must be a list of names, got {value!r}")
        out[VARIABLES_KEY] = check_variables(VARIABLES_KEY, value)
    for key in PLOT_KEYS:
        if key in out:
            out[key] = check_plot_type(key, out[key])
    return out
