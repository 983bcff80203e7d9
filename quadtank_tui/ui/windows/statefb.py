"""The State feedback window: the STATE FEEDBACK settings (Desautel, chapters 3-4).

Set sends them; the engine redesigns between two samples (bumpless) or refuses with
the key and the reason, which the window shows next to the field.  The gains, the
placed poles and delta are in the Controller box.
"""

from __future__ import annotations

from textual.app import ComposeResult
from textual.widgets import Input, Label

from quadtank_tui.core.parameters import STATEFB_SECTION
from quadtank_tui.ui.windows.base import Field, WholeControllerWindow

S = STATEFB_SECTION
FIELDS = (
    Field(f"{S}.Ts", "Ts", "s settling time"),
    Field(f"{S}.Poles", "Poles", "zeros | none | rad/s", text=True),
    Field(f"{S}.L3", "L3", "x L2^-1 anti-windup"),
    Field(f"{S}.Smart", "Smart int.", flag=True),
    Field(f"{S}.LevelMargin", "Margin", "cm below a top"),
    Field(f"{S}.Level1", "At h1", "cm (linearized)"),
    Field(f"{S}.Level2", "At h2", "cm (linearized)"),
)


class StateFeedbackWindow(WholeControllerWindow):
    """Settling time, chosen poles, anti-windup and the operating point; Reset clears
    the integrators."""

    controller_title = "Controller - State feedback"
    controller_fields = FIELDS

    def compose_body(self) -> ComposeResult:
        yield from super().compose_body()
        if self.params.process is not None:
            yield Label(f"A {self.params.process.kind} plant is linearized at its operating levels "
                        "(Setup); At h1, At h2 are the quadruple tank's.", classes="hint")

    def on_mount(self) -> None:
        super().on_mount()
        if self.params.process is not None:  # another plant: its PLANT levels are the point
            for i, f in enumerate(FIELDS):
                if f.key.endswith((".Level1", ".Level2")):
                    self.query_one(f"#row-{i}").set_class(True, "-unused")
                    self.query_one(f"#f-{i}", Input).disabled = True
