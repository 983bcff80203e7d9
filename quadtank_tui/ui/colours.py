"""The one palette of every terminal plot (issue 28): named hues, each an RGB
for a dark and for a light background.

A title or legend that names a colour takes the name from here, and the curve
takes the RGB from the same entry, so "y (blue)" cannot be drawn purple again
(plotext turned the name "blue" into one ANSI code and Rich into another).
Every colour keeps a contrast of at least 3:1 (WCAG's figure for graphics)
against Textual's dark and light plot backgrounds (tests/ui/test_trend_view.py).
"""

from __future__ import annotations

from dataclasses import dataclass

RGB = tuple[int, int, int]


@dataclass(frozen=True)
class Hue:
    """A colour by the name titles use, and its RGB on each background."""

    name: str
    dark: RGB
    light: RGB

    def rgb(self, dark: bool) -> RGB:
        return self.dark if dark else self.light


BLUE = Hue("blue", (90, 160, 255), (0, 85, 200))
RED = Hue("red", (255, 110, 110), (200, 30, 30))
GREEN = Hue("green", (110, 220, 110), (30, 120, 40))
ORANGE = Hue("orange", (255, 185, 80), (170, 85, 0))
CYAN = Hue("cyan", (80, 225, 225), (0, 125, 135))
MAGENTA = Hue("magenta", (235, 130, 235), (145, 35, 165))
GREY = Hue("grey", (150, 150, 150), (110, 110, 110))

#: The hue of each process signal, in every plot that draws it.  Loop 1's input
#: and level share a hue, loop 2's too (a plot never mixes levels and inputs).
SIGNALS: dict[str, Hue] = {
    "y1": BLUE, "y2": RED, "y3": GREEN, "y4": ORANGE,
    "u1": BLUE, "u2": RED,
    "ref1": CYAN, "ref2": MAGENTA,
}
