"""The Design screen's table of candidate controllers, one row per candidate.

Columns never run together: every column has a fixed width with one blank in
it, and each number is written to fit the rest (`fit`: four significant digits,
fewer, or a short exponent, never cut: `0.006800.01890.38` and `1.87e+1.00` were
numbers cut off by the column next to them).  The units are in the header.  A
candidate without a controller says why across its row (`n/a: Ms 1.2
unreachable`); the full reason is the status line's when the row is highlighted.
The last column is the sampled loop's verdict with the pumps limited (issue 23):
`best` on the suggested row (core.design.table.suggested), and on a row that must
not be suggested a word for why: `sat` (at a pump limit more than a fifth of its
settling time), `chatter` (the pump reverses on most samples), `settle?` (a step
does not settle); the status line says it in full.
"""

from __future__ import annotations

import math
import re
from typing import TYPE_CHECKING, Sequence

from rich.text import Text
from textual.widgets import DataTable

if TYPE_CHECKING:  # the design core loads when the screen first computes (start-up time)
    from quadtank_tui.core.design.table import Candidate

#: (key, header, width with its blank); the candidate column is left-aligned, the rest right.
COLUMNS = (("candidate", "candidate", 12), ("Kc", "Kc", 7), ("Ti", "Ti[s]", 7), ("Td", "Td[s]", 6),
           ("IAE", "IAE", 7), ("Emax", "Emax", 6), ("u_os", "u_os", 5), ("phi", "φm°", 4),
           ("Lm", "Lm[s]", 6), ("Am", "Am", 5), ("Ms", "Ms", 5), ("check", "check", 8))
WIDTH = sum(w for _, _, w in COLUMNS)

#: Short reasons for a candidate without a controller, by what core.design's message says.
_REASONS = (
    ("does not bound the gains", "Ms bounds no gain on this model; use λ"),
    ("right-half-plane", "unstable model (right-half-plane pole)"),
    ("right half-plane", "unstable model (right-half-plane pole)"),
    ("one integrator at most", "more than one integrator"),
    ("undamped oscillating", "undamped oscillating poles"),
    ("static gain", "zero static gain"),
    ("zeros lead its lags", "zeros lead the lags: no first-order fit"),
    ("Ms must be", "Ms must be > 1"),
    ("lambda must be", "λ must be > 0 s"),
)


def _compact_exponent(text: str) -> str:
    """1.87e+04 -> 1.87e4, 5e-05 -> 5e-5."""
    return re.sub(r"e([+-])0*(\d)", lambda m: "e" + ("-" if m[1] == "-" else "") + m[2], text)


def fit(x: float | None, room: int, digits: int = 4) -> str:
    """`x` in at most `room` characters with as many of `digits` significant digits
    as fit; "-" for no value, "∞" for an infinite one."""
    if x is None or math.isnan(x):
        return "-"
    if math.isinf(x):
        return "∞" if x > 0 else "-∞"
    if abs(x) >= 10.0 ** digits:  # 12346 reads better than 1.235e4
        whole = f"{x:.0f}"
        if len(whole) <= room:
            return whole
    for d in range(digits, 0, -1):  # g keeps -0.0008 fixed-point at every precision: -8e-4 then
        for text in (_compact_exponent(f"{x:.{d}g}"), _compact_exponent(f"{x:.{d - 1}e}")):
            if len(text) <= room:
                return text
    return "…"


def fixed(x: float, decimals: int, room: int) -> str:
    """`x` with `decimals` decimals (Ms 1.40, u_os 0.00) when that fits, else as `fit`."""
    text = f"{x:.{decimals}f}"
    return text if len(text) <= room and math.isfinite(x) else fit(x, room, 3)


def label(c: Candidate) -> str:
    """The candidate's name in its column: `λ 15.7 s`, `PI Ms 1.4`, `PID Ms 1.25`."""
    room = COLUMNS[0][2] - 1
    if c.method == "lambda":
        text = f"λ {fit(c.parameter, room - 4, 3)} s" if c.parameter > 0 else "λ"
    elif c.method in ("pi-ms", "pid-ms"):
        text = f"{'PI' if c.method == 'pi-ms' else 'PID'} Ms {c.parameter:.3g}"
    else:
        text = c.label
    return text if len(text) <= room else text[: room - 1] + "…"


def short_reason(c: Candidate) -> str:
    """Why `c` has no controller, in a few words."""
    error = c.error or "no controller"
    if "meets Ms" in error:
        return f"Ms {c.parameter:g} unreachable on this model"
    for words, reason in _REASONS:
        if words in error:
            return reason
    return re.split(r"[:;(]", error, maxsplit=1)[0].strip() or error


#: The verdict column's word, by what core.design.sampled_eval's LimitCheck.problem says.
_VERDICTS = (("chatters", "chatter"), ("does not settle", "settle?"), ("pump limit", "sat"))
BEST = "best"


def verdict(c: Candidate) -> str:
    """The check column's word for a designed, stable row: "ok" when it holds, ""
    when it was not checked (h = 0), "2x2 uns" when the pair with the other loop's
    controller is unstable, else a word from _VERDICTS."""
    if c.limits is None or c.limits.problem is None:
        return "2x2 uns" if c.pair is not None else "" if c.limits is None else "ok"
    why = c.limits.problem
    return next((word for words, word in _VERDICTS if words in why), why[: COLUMNS[-1][2] - 2])


def _span(text: str, first: int) -> list[Text]:
    """`text` laid across the columns from `first` on (one blank before it), cut with
    … where it would not fit."""
    widths = [w for _, _, w in COLUMNS[first:]]
    room = sum(widths)
    line = " " + text
    if len(line) > room:
        line = line[: room - 1] + "…"
    line = line.ljust(room)
    cells, at = [], 0
    for w in widths:
        cells.append(Text(line[at:at + w], no_wrap=True))
        at += w
    return cells


def _right(text: str) -> Text:
    return Text(text, justify="right", no_wrap=True)


def cells(c: Candidate, best: bool = False) -> list[Text]:
    """The row of `c`: every cell narrower than its column (one blank at least);
    `best`: the suggested row."""
    room = [w - 1 for _, _, w in COLUMNS]
    first = Text(label(c), no_wrap=True)
    ctrl, e = c.controller, c.evaluation
    if ctrl is None or e is None:
        return [first, *_span(f"n/a: {short_reason(c)}", 1)]
    head = [first, _right(fit(ctrl.Kc, room[1])), _right(fit(ctrl.Ti, room[2])), _right(fit(ctrl.Td, room[3], 3))]
    if not e.stable:
        return head + _span("unstable on this model", 4)
    return head + [
        _right(fit(e.IAE, room[4])), _right(fit(e.Emax, room[5], 3)), _right(fixed(e.u_overshoot, 2, room[6])),
        _right(fixed(e.phase_margin_deg, 0, room[7])), _right(fit(e.delay_margin, room[8], 3)),
        _right(fit(e.gain_margin, room[9], 3)), _right(fixed(e.Ms, 2, room[10])),
        Text(BEST if best else verdict(c), justify="right", no_wrap=True, style="bold" if best else "italic"),
    ]


class CandidatesTable(DataTable[Text]):
    """The candidates of one loop; the row keys are their indexes."""

    def __init__(self, **kwargs: object) -> None:
        super().__init__(cursor_type="row", zebra_stripes=False, cell_padding=0, **kwargs)  # type: ignore[arg-type]

    def on_mount(self) -> None:
        for key, header, width in COLUMNS:
            self.add_column(Text(header, justify="left" if key == "candidate" else "right"), key=key, width=width)

    def show(self, rows: Sequence[Candidate], *, best: int | None = None, to_best: bool = False) -> None:
        """Replace the rows; `best`: the suggested row's index, marked.  The cursor
        goes to it when `to_best` (a new table), else keeps its row where there
        still is one."""
        at = best if to_best and best is not None else self.cursor_row
        self.clear()
        for n, c in enumerate(rows):
            self.add_row(*cells(c, n == best), key=str(n))
        if rows:
            self.move_cursor(row=min(at, len(rows) - 1))
