"""The Setup screen's sampling time window (thesis 5.4; S1).

50 ms to 10 s, in the `.par` file's unit (ms).  The value is validated together
with the references: a Square or Sine period shorter than twice the new sampling
time is refused with the shortest allowed, rather than turned into a constant.  The
engine re-discretizes the controllers and generators bumplessly; the trends keep
their own refresh clock.
"""

from __future__ import annotations

from textual.app import ComposeResult
from textual.widgets import Label

from quadtank_tui.core.parameters import TSAMP, TSAMP_MAX_MS, TSAMP_MIN_MS, Parameters
from quadtank_tui.ui.windows.base import Field, ParamWindow


class SamplingTimeWindow(ParamWindow):
    """One field: the sampling time of controllers and simulation, ms."""

    def __init__(self, params: Parameters, defaults: Parameters, *, opener: str | None = None) -> None:
        unit = f"ms ({TSAMP_MIN_MS:g}..{TSAMP_MAX_MS:g})"
        super().__init__("Sampling time", params, defaults, (Field(TSAMP, "Sampling", unit),), opener=opener)

    def compose_body(self) -> ComposeResult:
        yield from super().compose_body()
        yield Label("Takes effect at the next sample, without a bump; the trends keep their own refresh.",
                    classes="hint")
