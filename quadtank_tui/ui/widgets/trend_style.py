"""How the trends tell their signals apart: one colour per signal, the same in
the legend and in the plot, for a dark and a light theme; marker characters
instead when the user asked for no colour (NO_COLOR).

The colours are given as RGB, not as terminal colour names: plotext turned
"blue" into one ANSI code and Rich markup into another, so y1 was blue in the
title and purple in the plot (issue 17).  Every colour keeps a contrast of at
least 3:1 (WCAG's figure for graphics) against the theme's plot background;
tests/ui/test_trend_view.py checks it on Textual's dark and light themes.
"""

from __future__ import annotations

from dataclasses import dataclass

from quadtank_tui.ui.colours import RGB, SIGNALS

#: Per signal, on a dark background and on a light one (colours.py: the one palette).
DARK: dict[str, RGB] = {name: hue.dark for name, hue in SIGNALS.items()}
LIGHT: dict[str, RGB] = {name: hue.light for name, hue in SIGNALS.items()}
#: Without colour, each trace of a plot draws with its own character (in the
#: order of the plot type: "y1 y2 ref1 ref2" -> * + o x) and a ghost with dots.
MARKERS = ("*", "+", "o", "x")
GHOST_MARKER = "·"
#: A reference's or a model's dots in the small plots and `quadtank log` (Identify, Design).
DOTTED_MARKER = "·"
#: Columns between the dots of a dotted curve (a reference, a model).
DOT_GAP = 2
#: How far a ghost's colour goes towards the background (0 = the trace's own).
GHOST_FADE = 0.6


@dataclass(frozen=True)
class TraceStyle:
    """How one signal is drawn: `color` None means no colour at all."""

    color: RGB | None
    marker: str
    ghost_color: RGB | None
    ghost_marker: str

    @property
    def rich(self) -> str:
        """The Rich style of the legend entry: exactly the plot's colour."""
        return "" if self.color is None else "rgb({},{},{})".format(*self.color)


def blend(a: RGB, b: RGB, f: float) -> RGB:
    """`a` moved the fraction `f` of the way to `b`."""
    r, g, bl = (round(x + (y - x) * f) for x, y in zip(a, b))
    return r, g, bl


def trace_styles(names: list[str], *, dark: bool, no_color: bool, background: RGB) -> dict[str, TraceStyle]:
    """The style of each signal of one plot."""
    if no_color:
        return {n: TraceStyle(None, MARKERS[i % len(MARKERS)], None, GHOST_MARKER) for i, n in enumerate(names)}
    table = DARK if dark else LIGHT
    return {n: TraceStyle(table[n], "braille", blend(table[n], background, GHOST_FADE), "braille")
            for n in names}


def _luminance(c: RGB) -> float:
    def channel(v: int) -> float:
        s = v / 255
        return s / 12.92 if s <= 0.03928 else ((s + 0.055) / 1.055) ** 2.4
    r, g, b = (channel(v) for v in c)
    return 0.2126 * r + 0.7152 * g + 0.0722 * b


def contrast(a: RGB, b: RGB) -> float:
    """WCAG contrast ratio of two colours (1 to 21)."""
    la, lb = sorted((_luminance(a), _luminance(b)), reverse=True)
    return (la + 0.05) / (lb + 0.05)
