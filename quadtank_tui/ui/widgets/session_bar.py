"""The session line of a lab session's client (Main, above the footer): whose
session this is and who drives it, in the longest form the width holds.

The session's own line ("session root-1 of root: root (pid 25996) controls session
root-1; you operate it") was cut at 80x24 ("...you operate"): what the client may
do came last and was the part lost.  Shorter forms drop what repeats or what a
student needs least first (the session named twice, the pid), never the role.
"""

from __future__ import annotations

import re
from typing import Any

from rich.text import Text
from textual.widgets import Static

#: Shorter forms, each applied over the one before.
_SHORTER = ((re.compile(r" controls session [^;\s]+"), " controls it"),
            (re.compile(r" \(pid \d+\)"), ""),
            (re.compile(r"^session (\S+) of (\S+): "), r"\1 of \2: "),
            (re.compile(r"read-only: you observe it$"), "read-only"))


def fit_banner(banner: str, width: int) -> str:
    """The longest form of `banner` that fits `width` columns; if none does, the
    shortest (the bar then wraps it: a session gone says why in full)."""
    form = banner
    for pattern, short in _SHORTER:
        if len(form) <= width:
            return form
        form = pattern.sub(short, form)
    return form


class SessionBar(Static):
    """The session banner, in the form that fits the width."""

    def __init__(self, banner: str, **kwargs: Any) -> None:
        super().__init__(markup=False, **kwargs)
        self.banner = banner

    def update(self, content: Any = "", *, layout: bool = True) -> None:
        self.banner = str(content)
        self.refresh(layout=layout)

    def render(self) -> Text:
        return Text(fit_banner(self.banner, self.content_size.width or 78))
