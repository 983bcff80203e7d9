"""Change a few values of a `.par` file in place, keeping everything else.

A calibration changes two or four numbers of a file the user keeps (its comments,
its unknown entries, its "Created on" line): rewriting it with format_par would
change lines the calibration has nothing to do with.  Here each `Key value` line
of the named section is replaced where it stands; a key the section lacks is added
at the section's end.  The caller checks the result with the file reader before it
writes it (nothing half-valid is ever written).

Example
-------
>>> text = "% TANK PAR-file\\n\\nPLANT\\nKind coupled-cascade\\nalpha1 0.0095\\nLevel1 15\\n"
>>> print(with_par_values(text, {"PLANT.alpha1": "0.0097909"}), end="")
% TANK PAR-file
<BLANKLINE>
PLANT
Kind coupled-cascade
alpha1 0.0097909
Level1 15
"""

from __future__ import annotations

import difflib
import re
from typing import Mapping

from quadtank_tui.files.par import ParFileError

_SECTION_LINE = re.compile(r"^[A-Z][A-Z ]*[A-Z]\s*$")


def with_par_values(text: str, values: Mapping[str, str], name: str = "<par>") -> str:
    """`text` with each "SECTION.Key" of `values` set to its text; ParFileError
    when a section is missing (the file is not the kind of plant the values are for)."""
    lines = text.splitlines(keepends=True)
    newline = "\r\n" if lines and lines[0].endswith("\r\n") else "\n"
    by_section: dict[str, dict[str, str]] = {}
    for full, value in values.items():
        section, _, key = full.partition(".")
        by_section.setdefault(section, {})[key] = value
    for section, entries in by_section.items():
        start = next((i for i, ln in enumerate(lines) if ln.strip() == section), None)
        if start is None:
            raise ParFileError(name, f"has no {section} section to write {', '.join(entries)} into")
        end = next((i for i in range(start + 1, len(lines)) if _SECTION_LINE.match(lines[i])), len(lines))
        todo = dict(entries)
        for i in range(start + 1, end):
            words = lines[i].split(None, 1)
            found = next((k for k in todo if words and words[0].lower() == k.lower()), None)
            if found is not None:
                ending = lines[i][len(lines[i].rstrip("\r\n")):] or newline
                lines[i] = f"{words[0]} {todo.pop(found)}{ending}"
        last = end
        while last > start + 1 and not lines[last - 1].strip():
            last -= 1  # after the section's last entry, before the blank lines
        if last > 0 and not lines[last - 1].endswith(("\n", "\r")):
            lines[last - 1] += newline
        lines[last:last] = [f"{k} {v}{newline}" for k, v in todo.items()]
    return "".join(lines)


def text_diff(old: str, new: str, path: str) -> str:
    """A unified diff of what a write changes ("" when nothing does)."""
    return "".join(difflib.unified_diff(old.splitlines(keepends=True), new.splitlines(keepends=True),
                                        fromfile=path, tofile=f"{path} (calibrated)", n=1))
