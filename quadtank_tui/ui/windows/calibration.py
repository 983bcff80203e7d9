"""The Calibration window of Setup (Desautel 2.3; B9): the steady-state procedure on
the rig, in Active mode.

The engine runs the procedure (StartCalibration: the control loop pauses, both
pumps are held at each voltage until the sensors settle); this window only shows
its status from the snapshots, asks for the heights read on the tanks' scales
(CalibrationHeights), fits the pairs in a worker when it is done, and writes the
result, after showing what changes and asking, into the DAQ configuration file and
a `.par` of the parameter folder (daq.calibrate.plan_writes / commit, atomic).
Cancel (or Esc) stops the procedure with the pumps at 0.  In Simul the window only
says why it is not available.
"""

from __future__ import annotations

import asyncio
from pathlib import Path
from typing import Any, Callable

from textual import work
from textual.app import ComposeResult
from textual.containers import Horizontal
from textual.reactive import reactive
from textual.widgets import Button, Input, Label, Static

from quadtank_tui.core.calibration.procedure import DONE, HEIGHTS, SETTLING, CalibrationStatus
from quadtank_tui.files.names import check_file_name
from quadtank_tui.core.ranges import ParameterError
from quadtank_tui.engine.commands import CalibrationHeights, CancelCalibration, Command, StartCalibration
from quadtank_tui.engine.snapshot import Snapshot
from quadtank_tui.files.par import RESERVED
from quadtank_tui.ui.widgets.key_button import KeyButton
from quadtank_tui.ui.windows.base import ConfirmWindow, LiveWindow

SIMUL_TEXT = ("Calibration runs on the rig, in Active mode (start with --daq CONFIG, then A on Main): "
              "it holds the pumps, reads the raw sensor voltages and asks for the heights on the "
              "tanks' scales. The simulation's sensors are exact: there is nothing to calibrate.")


def progress_text(s: CalibrationStatus | None) -> str:
    """One or two lines on where the procedure is."""
    if s is None:
        return ("Not started. Start pauses the control loop and holds both pumps at each voltage "
                "until every sensor settles.")
    n = len(s.volts)
    if s.phase in (SETTLING, HEIGHTS):
        head = f"Pumps at {s.volts[s.step]:g} V ({s.step + 1} of {n}): "
        if s.phase == SETTLING:
            spread = "-" if s.reads == 0 else f"{s.spread:.4f} V"
            return head + f"settling, {s.reads}/{s.window} reads, spread {spread}, {s.elapsed:.0f} s"
        volts = " ".join(f"{v:.4f}" for v in s.settled)
        return head + f"settled at {volts} V.\nRead the heights on the scales (cm), then Record."
    if s.phase == DONE:
        return f"Done: {n} settled states, the pumps are at 0."
    return s.message


def pairs_text(s: CalibrationStatus | None) -> str:
    """The settled states so far: pump V, sensor V, scale cm."""
    if s is None or not s.columns:
        return ""
    cols = dict(s.columns)
    rows = []
    for k in range(len(cols["u1"])):
        volts = " ".join(f"{cols[f'volts{i}'][k]:.3f}" for i in range(1, s.tanks + 1))
        levels = " ".join(f"{cols[f'level{i}'][k]:.2f}" for i in range(1, s.tanks + 1))
        rows.append(f"{cols['u1'][k]:g} V: {volts} V  {levels} cm")
    return "\n".join(rows)


def par_name_problem(name: str) -> str:
    """Why the calibration cannot be written into `name`.par ("" when it can): a
    plain name of an existing file in the parameter folder, not a reserved one
    (default.par is the administrators' to save)."""
    if not name:
        return ""
    if name.lower() in RESERVED:
        return f"Into .par: {RESERVED[name.lower()]}"
    try:
        check_file_name(name, "Into .par")
    except ParameterError as exc:
        return f"Into .par: {exc.reason}"
    return ""


class CalibrationWindow(LiveWindow):
    """Start, follow and write the calibration; fed snapshots by Setup."""

    snapshot: reactive[Snapshot | None] = reactive(None, always_update=True)

    def __init__(self, snapshot: Snapshot, *, submit: Callable[[Command], Any], opener: str | None = None) -> None:
        super().__init__("Calibration (Desautel 2.3)", snapshot, opener=opener)
        self.submit = submit
        self.active_mode = snapshot.operation == "Active"
        self.tanks = len(snapshot.params.process_plant().states)
        self.result: Any = None  # daq.calibrate.Result once fitted
        self._fitted: tuple[tuple[str, tuple[float, ...]], ...] | None = None

    # --- layout -----------------------------------------------------------------------

    def compose_body(self) -> ComposeResult:
        if not self.active_mode:
            yield Static(SIMUL_TEXT, id="cal-simul", markup=False)
            return
        with Horizontal(classes="field"):
            yield Label("Pumps", classes="label")
            yield Input("2 2.5 3 3.5", id="cal-volts", compact=True)
            yield Label("V, held on every pump", classes="unit")
        with Horizontal(classes="field"):
            yield Label("Settled", classes="label")
            yield Input("60", id="cal-window", compact=True)
            yield Label("s within", classes="unit")
            yield Input("0.004", id="cal-tol", compact=True)
            yield Label("V", classes="unit")
        yield Static("", id="cal-progress", markup=False)
        with Horizontal(classes="field", id="cal-heights"):
            yield Label("Heights", classes="label")
            for i in range(1, self.tanks + 1):
                yield Input("", id=f"cal-h{i}", compact=True, placeholder=f"h{i} cm")
        yield Static("", id="cal-pairs", markup=False)
        yield Static("", id="cal-result", markup=False)
        with Horizontal(classes="field"):
            yield Label("Into .par", classes="label")
            yield Input("", id="cal-par", compact=True, placeholder="name")
            yield Label("in the parameter folder (empty: none)", classes="unit")

    def compose_buttons(self) -> ComposeResult:
        if self.active_mode:
            yield KeyButton("Start", id="start", variant="primary")
            yield KeyButton("Record", id="record", variant="success")
            yield KeyButton("Write", id="write", variant="warning")
        yield KeyButton("Cancel", id="cancel")

    # --- the live part ------------------------------------------------------------------

    @property
    def status(self) -> CalibrationStatus | None:
        return self.snapshot.calibration if self.snapshot is not None else None

    def show(self, snapshot: Snapshot) -> None:
        if not self.active_mode:  # Simul: the window only says why (no progress to show)
            return
        s = snapshot.calibration
        self.query_one("#cal-progress", Static).update(progress_text(s))
        self.query_one("#cal-pairs", Static).update(pairs_text(s))
        running = s is not None and s.phase in (SETTLING, HEIGHTS)
        self.query_one("#start", Button).disabled = running
        self.query_one("#record", Button).disabled = s is None or s.phase != HEIGHTS
        self.query_one("#cal-heights").display = s is not None and s.phase == HEIGHTS
        done = s is not None and s.phase == DONE
        if not done:
            self.result, self._fitted = None, None
            self.query_one("#cal-result", Static).update("")
        elif s is not None and s.columns != self._fitted:
            self._fitted = s.columns
            self.fit(s)
        self.query_one("#write", Button).disabled = self.result is None

    @work(thread=True, exclusive=True, group="fit")
    def fit(self, s: CalibrationStatus) -> None:
        """Least squares on the pairs (sensors, and the plant's outlets), off the UI."""
        from quadtank_tui.core.calibration.fits import CalibrationError
        from quadtank_tui.daq.calibrate import Pairs, fit_pairs, format_result

        assert self.snapshot is not None
        plant = self.snapshot.params.process_plant()
        try:
            result = fit_pairs(Pairs({k: list(v) for k, v in s.columns}), plant)
            text = format_result(result, plant, config_lines=False)
        except CalibrationError as exc:
            result, text = None, f"no fit: {exc}"
        self.app.call_from_thread(self._fitted_result, result, text)

    def _fitted_result(self, result: Any, text: str) -> None:
        if not self.is_attached:
            return
        self.result = result
        self.query_one("#cal-result", Static).update(text)
        self.query_one("#write", Button).disabled = result is None

    # --- actions --------------------------------------------------------------------------

    def action_start(self) -> None:
        try:
            volts = tuple(float(w) for w in self.query_one("#cal-volts", Input).value.replace(",", " ").split())
            window = float(self.query_one("#cal-window", Input).value)
            tol = float(self.query_one("#cal-tol", Input).value)
        except ValueError:
            self.show_message("Pumps: volts like 2 2.5 3; Settled: seconds and a tolerance in V")
            return
        self.show_message("")
        self.submit(StartCalibration(volts, window=window, tol=tol))

    def action_record(self) -> None:
        try:
            levels = tuple(float(self.query_one(f"#cal-h{i}", Input).value) for i in range(1, self.tanks + 1))
        except ValueError:
            self.show_message(f"Heights: {self.tanks} numbers in cm, as read on the scales")
            return
        self.show_message("")
        for i in range(1, self.tanks + 1):
            self.query_one(f"#cal-h{i}", Input).value = ""
        self.submit(CalibrationHeights(levels))

    @work(exclusive=True, group="write")
    async def action_write(self) -> None:
        """Show what changes in each file, ask, then write them atomically."""
        from quadtank_tui.daq.calibrate import commit, plan_writes

        s = self.status
        if self.result is None or s is None:
            return
        name = self.query_one("#cal-par", Input).value.strip().removesuffix(".par")
        problem = par_name_problem(name)
        if problem:
            self.show_message(problem)
            return
        par = Path(s.par_dir) / f"{name}.par" if name else None
        try:
            planned = await asyncio.to_thread(plan_writes, self.result, s.daq_file or None, par)
        except (ValueError, OSError) as exc:
            self.show_message(str(exc))
            return
        if not planned:
            self.show_message("Nothing to write: " + ("the files already hold this calibration" if
                              s.daq_file or par else "no DAQ configuration file and no .par named"))
            return
        diff = "".join(p.diff() for p in planned)
        names = " and ".join(str(p.path) for p in planned)
        if not await self.app.push_screen_wait(ConfirmWindow("Write the calibration", f"{diff}\nWrite into {names}?",
                                                             yes="Write")):
            return
        try:
            await asyncio.to_thread(commit, planned)
        except OSError as exc:
            self.show_message(f"not written: {exc}")
            return
        self.show_message(f"Written into {names}. The DAQ file's calibration is used from the next start.")

    def action_cancel(self) -> None:
        """Stop the procedure with the pumps at 0, and close."""
        s = self.status
        if s is not None and s.phase in (SETTLING, HEIGHTS):
            self.submit(CancelCalibration())
        self.dismiss(())
