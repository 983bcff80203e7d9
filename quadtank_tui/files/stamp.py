"""The `Created on:` stamp of the original's files: `%b %d %H:%M:%S %Y`
("Jun 20 00:30:50 1997").

English month names are spelled out here rather than taken from `strftime("%b")`,
which follows the locale: a Swedish locale would write "maj", which the original's
users' scripts (and our reader) do not expect.  Note the day is zero-padded as in
the thesis's samples ("Aug 05"), unlike C's ctime ("Aug  5").
"""

from __future__ import annotations

import re
from datetime import datetime

MONTHS = ("Jan", "Feb", "Mar", "Apr", "May", "Jun", "Jul", "Aug", "Sep", "Oct", "Nov", "Dec")
_STAMP = re.compile(r"([A-Za-z]{3})\s+(\d{1,2})\s+(\d{1,2}):(\d{2}):(\d{2})\s+(\d{4})")


def format_stamp(when: datetime) -> str:
    """`when` as the original wrote it, e.g. "Jun 20 00:30:50 1997"."""
    return f"{MONTHS[when.month - 1]} {when.day:02d} {when:%H:%M:%S} {when.year:04d}"


def parse_stamp(text: str) -> datetime | None:
    """The inverse of :func:`format_stamp`; also accepts ctime's space-padded day.
    None if `text` is not such a stamp (a reader then keeps the raw text)."""
    m = _STAMP.fullmatch(text.strip())
    if not m or m.group(1).title() not in MONTHS:
        return None
    mon, day, hh, mm, ss, year = m.groups()
    try:
        return datetime(int(year), MONTHS.index(mon.title()) + 1, int(day), int(hh), int(mm), int(ss))
    except ValueError:
        return None
