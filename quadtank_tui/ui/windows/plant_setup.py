"""The Setup screen's plant window: the constants and operating levels of a plant
other than the quadruple tank (a `.par` file's PLANT section).

One field per value, in the file's order: the operating levels the pumps hold
(Level1.. in the plant's unit), then every physical constant with its unit.  The
levels that follow from the chosen ones (the cascade's x2, the upper tanks of
Desautel's quadruple tank) are recomputed at steady state when a constant changes,
as the tank window recomputes its linked values.  The analysis below follows every
keystroke.  Set sends the changed values as "PLANT.<key>" (all or none: a refused
one is named next to its field and nothing reaches the engine); Default puts the
published values back into the fields (the shipped preset's).
"""

from __future__ import annotations

import dataclasses

from textual import on
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import VerticalScroll
from textual.widgets import Input, Static

from quadtank_tui.core.parameters import PLANT_SETTINGS, Parameters
from quadtank_tui.core.plants.spec import PREFIX, PlantSpec, level_key
from quadtank_tui.core.ranges import ParameterError
from quadtank_tui.engine.commands import SetParams
from quadtank_tui.ui.values import fmt, parse_number
from quadtank_tui.ui.widgets.analysis_panel import AnalysisPanel
from quadtank_tui.ui.windows.base import Commands, Window, field_row, set_default_cancel


class PlantSetupWindow(Window[Commands]):
    """Edit the plant in use: its operating levels and constants."""

    BINDINGS = [Binding("enter", "set", "Set"), Binding("ctrl+r", "default", "Default")]

    def __init__(self, params: Parameters, *, opener: str | None = None) -> None:
        spec = params.process
        if spec is None:
            raise ValueError("the quadruple tank is edited in its Tank windows")
        plant = spec.plant()
        super().__init__(f"Plant: {plant.title}", opener=opener)
        self.params = params
        self.spec: PlantSpec = spec
        shipped = PLANT_SETTINGS.get(spec.kind)
        #: Default puts these back: the published values of the shipped preset.
        self.published = shipped.process if shipped is not None and shipped.process is not None else spec
        levels = [(level_key(i), f"{s.name} op.", s.unit) for i, s in enumerate(plant.states)]
        consts = [(name, name, plant.units.get(name, "")) for name, _ in spec.values]
        #: (key without "PLANT.", label, unit) of each field, in file order
        self.rows: tuple[tuple[str, str, str], ...] = tuple(levels + consts)
        #: The text put into a following level's field by the window (not typed)
        self.followed: dict[int, str] = {}

    # --- layout -------------------------------------------------------------------------

    def compose_body(self) -> ComposeResult:
        with VerticalScroll(id="plant-fields"):
            for i, (key, label, unit) in enumerate(self.rows):
                field = Input(fmt(self.spec.get(key)), id=f"f-{i}", compact=True, select_on_focus=True)
                yield from field_row(f"row-{i}", label, field, unit, f"e-{i}")
        yield AnalysisPanel(id="plant-analysis")

    def compose_buttons(self) -> ComposeResult:
        yield from set_default_cancel()

    def on_mount(self) -> None:
        self._edited()

    # --- values ---------------------------------------------------------------------------

    def _field(self, i: int) -> Input:
        return self.query_one(f"#f-{i}", Input)

    def typed(self) -> dict[str, float] | None:
        """The fields that differ from the values in force, by key; None (each bad
        field marked) when one is not a number."""
        out: dict[str, float] = {}
        bad = False
        for i, (key, _, _) in enumerate(self.rows):
            text = self._field(i).value
            if text == fmt(self.spec.get(key)) or text == self.followed.get(i):
                continue  # shown as it is (rounded), or recomputed by the window: not typed
            try:
                value = parse_number(PREFIX + key, text)
            except ParameterError as exc:
                self.query_one(f"#e-{i}", Static).update(exc.reason)
                bad = True
                continue
            if value != self.spec.get(key):
                out[key] = value
        return None if bad else out

    def checked(self) -> tuple[dict[str, float], PlantSpec] | None:
        """The changes and the plant they give, validated together; None after
        naming what is refused next to its field (or for the window)."""
        changes = self.typed()
        if changes is None:
            return None
        try:
            return changes, self.spec.with_values(changes)
        except ParameterError as exc:
            self._error(exc.field.removeprefix(PREFIX), exc.reason)
            return None

    def _error(self, key: str, reason: str) -> None:
        keys = [k for k, _, _ in self.rows]
        if key in keys:
            self.query_one(f"#e-{keys.index(key)}", Static).update(reason)
        else:
            self.show_message(f"{key}: {reason}")

    def _edited(self) -> None:
        """Marks, the following levels and the analysis of the fields as typed."""
        for i, (key, _, _) in enumerate(self.rows):
            self.query_one(f"#e-{i}", Static).update("")
            self.query_one(f"#row-{i}").set_class(self._field(i).value != fmt(self.published.get(key)), "-modified")
        self.show_message("")
        panel = self.query_one(AnalysisPanel)
        result = self.checked()
        if result is None:
            panel.refuse("a value is refused (see the marked field)")
            return
        spec = result[1]
        for i in range(self.spec.free_levels, len(spec.levels)):  # the levels that follow
            field = self._field(i)
            if level_key(i) not in result[0] and field.value != fmt(spec.levels[i]):
                self.followed[i] = fmt(spec.levels[i])
                with field.prevent(Input.Changed):
                    field.value = self.followed[i]
        panel.params = dataclasses.replace(self.params, process=spec)

    @on(Input.Changed)
    def _changed(self) -> None:
        self._edited()

    # --- actions ---------------------------------------------------------------------------

    def action_set(self) -> None:
        result = self.checked()
        if result is None:
            self.show_message("Correct the marked value first (Esc cancels).")
            return
        changes, _ = result
        self.dismiss((SetParams({PREFIX + k: v for k, v in changes.items()}),) if changes else ())

    def action_default(self) -> None:
        self.followed.clear()
        for i, (key, _, _) in enumerate(self.rows):
            with self._field(i).prevent(Input.Changed):
                self._field(i).value = fmt(self.published.get(key))
        self._edited()

    @on(Input.Submitted)
    def _submitted(self) -> None:
        self.action_set()
