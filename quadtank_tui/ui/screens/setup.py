"""The Setup screen (thesis 5.4; S1-S7): the settings a user changes rarely.

Sampling time, the reference waves, the controller elements with the PID extras,
the simulated process with the consequence of its setting (time constants, zeros,
phase), parameter files, and the Default actions.  Opening it changes nothing:
the engine keeps running in its own thread, and every Set here is a command
exactly like one sent from Main, applied at the next sample.

Like Main, this screen is the only part of its UI that talks to the engine: it
hands snapshots down to its widgets on a timer and sends the windows' commands.
"""

from __future__ import annotations

import dataclasses
import functools

from textual import events
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical
from textual.widgets import Static

from quadtank_tui.core.parameters import PLANT_SETTINGS, TSAMP, Parameters, keys_of
from quadtank_tui.core.plants.common import FULL_SCALE_V, PlantError
from quadtank_tui.core.plants.johansson import steady_state_inputs
from quadtank_tui.core.plants.spec import KIND_KEY
from quadtank_tui.core.plants.spec import PREFIX as PLANT_PREFIX
from quadtank_tui.core.setup_relations import TANKS
from quadtank_tui.engine.commands import LoadPar, SavePar, SetDefaults, SetParams
from quadtank_tui.engine.handle import EngineHandle
from quadtank_tui.engine.snapshot import Snapshot
from quadtank_tui.ui.messages import ActionRequested
from quadtank_tui.ui.screens.sending import CommandSender
from quadtank_tui.ui.values import fmt
from quadtank_tui.ui.widgets.analysis_panel import AnalysisPanel
from quadtank_tui.ui.widgets.key_footer import KeyFooter
from quadtank_tui.ui.widgets.process_image import ProcessImage
from quadtank_tui.ui.widgets.setup_tables import ControllerTable, ParamTable, ProcessTable, ReferenceTable
from quadtank_tui.ui.windows.base import Commands, ConfirmWindow
from quadtank_tui.ui.labels import type_modified
from quadtank_tui.ui.windows.calibration import CalibrationWindow
from quadtank_tui.ui.windows.controller_windows import ControllerTypeWindow, GeneralWindow
from quadtank_tui.ui.windows.mpc import MPCWindow
from quadtank_tui.ui.windows.statefb import StateFeedbackWindow
from quadtank_tui.ui.windows.par_files import ParFileWindow
from quadtank_tui.ui.windows.pid_extras import PIDExtrasWindow
from quadtank_tui.ui.windows.plant_setup import PlantSetupWindow
from quadtank_tui.ui.windows.sampling import SamplingTimeWindow
from quadtank_tui.ui.windows.tank_setup import TankSetupWindow
from quadtank_tui.ui.windows.wave import WaveWindow

SIMULATION_KEYS = tuple(k.name for k in keys_of("SIMULATION"))

LEGEND = (
    "[i]Dim italic[/i]: the value differs from its default (default.par).\n"
    "Tab: next table · arrows: choose a row · Enter or click: open it.\n"
    "d: process defaults · D: reread default.par · f: .par files.\n"
    "Every Set acts on the running process at once."
)


def operating_point_view(snap: Snapshot) -> Snapshot:
    """What Setup's process image draws (thesis 5.4): the water at the configured
    operating point, the pumps at the inputs that hold it (the live inputs if no
    input can, e.g. at gamma1 + gamma2 = 1), the tubes as paths, not flows."""
    p = snap.params
    if p.process is not None:  # another plant: its levels and the pumps that hold them
        plant, levels = p.process_plant(), p.process_levels()
        ys = [v / FULL_SCALE_V for v in plant.output(levels)] + [0.0] * 4
        u: tuple[float, float] = snap.u
        try:
            v = plant.steady_inputs([x if i in plant.controlled else None for i, x in enumerate(levels)]).u
            us = [x / s.full_scale for x, s in zip(v, plant.inputs)] + [0.0] * 2
            u = (us[0], us[1])
        except PlantError:
            pass
        return dataclasses.replace(snap, y=(ys[0], ys[1], ys[2], ys[3]), u=u, state="Pause", operation="Simul")
    y = p.simulation.op_points
    try:
        h = p.operating_levels()
        v = steady_state_inputs(h[0], h[1], p.quadtank_constants()).u
        u = (v[0] / FULL_SCALE_V, v[1] / FULL_SCALE_V)
    except PlantError:
        u = snap.u
    return dataclasses.replace(snap, y=y, u=u, state="Pause", operation="Simul")


class SamplingLine(Static):
    """The sampling time as a line of text (the original's top-left text box); a
    click opens its window, like the `s` key."""

    def show(self, p: Parameters, defaults: Parameters) -> None:
        value = fmt(p.tsamp_ms)
        if p.is_modified(TSAMP, defaults):
            value = f"[i dim]{value}[/]"
        self.update(f"[b]Sampling time[/] {value} ms   [dim]· s to change[/]")

    def on_click(self, event: events.Click) -> None:
        event.stop()
        self.post_message(ActionRequested("sampling"))


class SetupScreen(CommandSender):
    """Configure the process, the references, the controllers; load and save."""

    AUTO_FOCUS = ""

    # The tooltip is the longer description the help screen and the palette show.
    BINDINGS = [
        Binding("escape", "main", "Main", tooltip="Back to Main (the process ran on all along)"),
        Binding("s", "sampling", "Sampling", tooltip="Sampling time, 50 ms to 10 s (bumpless)"),
        Binding("i", "reference(1)", "Ref 1", tooltip="Reference 1: wave type, mean, amplitude, period, seed, on/off"),
        Binding("I", "reference(2)", "Ref 2", show=False, tooltip="Reference 2"),
        Binding("h", "tanks", "Tanks", tooltip="Choose a tank in the process table (arrows, Enter opens it)"),
        Binding("f", "par_files", "Files", tooltip="Load or save a .par file"),
        Binding("c", "calibration", "Calibrate", show=False,
                tooltip="Calibrate the level sensors and the outlets on the rig (Active; Desautel 2.3)"),
        Binding("t", "controller_type", "Type", tooltip="Controller type: PID or General (decentralized or full), state feedback or MPC"),
        Binding("1", "element(0)", "Element 11", show=False, tooltip="Element 11 with the PID extras N, Tr, a, b"),
        Binding("2", "element(1)", "Element 12", show=False, tooltip="Element 12 with the PID extras"),
        Binding("3", "element(2)", "Element 21", show=False, tooltip="Element 21 with the PID extras"),
        Binding("4", "element(3)", "Element 22", show=False, tooltip="Element 22 with the PID extras"),
        Binding("d", "process_default", "Process default", tooltip="Every tank and valve back to its default"),
        Binding("D", "default_all", "Default all", tooltip="Every parameter reread from default.par (asks)"),
        Binding("question_mark", "app.help", "Help", show=False, tooltip="Every key of every screen and window"),
        Binding("q", "app.request_exit", "Exit", tooltip="Exit: asks first"),
        Binding("S", "main", "Main", show=False, tooltip="Back to Main"),
    ]

    def __init__(self, engine: EngineHandle, *, refresh_interval: float = 0.25) -> None:
        super().__init__()
        self.engine = engine
        self.refresh_interval = refresh_interval
        self.defaults = engine.defaults()
        self.snap: Snapshot = engine.snapshot()
        #: The name last used in the Parameters window (offered again next time).
        self.par_name = ""
        #: Back on Main (action_main), to come back on the next visit.
        self._away = False

    def compose(self) -> ComposeResult:
        yield Static(id="setup-status")
        with Horizontal(id="setup-body"):
            with Vertical(id="setup-left"):
                yield SamplingLine(id="sampling")
                yield ReferenceTable(self.defaults, id="references")
                yield ControllerTable(self.defaults, id="controllers")
                yield Static(LEGEND, id="legend", classes="hint")
            with Vertical(id="setup-right"):
                yield ProcessImage(caption="P1 P2: the inputs that hold it", id="setup-image")
                yield ProcessTable(self.defaults, id="process")
                yield AnalysisPanel(id="analysis")
        yield KeyFooter()

    def on_mount(self) -> None:
        self.query_one("#references").border_title = "Reference configuration  i I"
        self.query_one("#process").border_title = "Process configuration  h d"
        self.query_one("#setup-image").border_title = "Operating point"
        self.query_one("#analysis").border_title = "At the operating point"
        self.refresh_view(force=True)
        self._timer = self.set_interval(self.refresh_interval, self._tick)

    def on_screen_resume(self) -> None:
        """Back from Main (Main keeps this screen between visits): what changed while
        away (a parameter set on Main, a file loaded) shown at once, the timer again.
        Not on a window's closing: the timer kept the screen up to date under it."""
        if self._away:
            self._away = False
            self.refresh_view()
            self._timer.resume()

    # --- attributes down ----------------------------------------------------------------

    def _tick(self) -> None:
        if self.redraw_due():  # behind a window: once a second (screens/behind.py)
            self.refresh_view()

    def refresh_view(self, force: bool = False) -> None:
        """Show the latest snapshot; the tables only when the parameters changed."""
        snap = self.engine.snapshot()
        previous, self.snap = self.snap, snap
        status = self.status_text(snap)
        if force or status != self.status_text(previous):  # Static.update repaints, even unchanged
            self.query_one("#setup-status", Static).update(status)
        live = self.app.screen
        if isinstance(live, CalibrationWindow) and live.is_mounted and (
                (snap.calibration, snap.u) != (previous.calibration, previous.u) or live.snapshot is None):
            live.snapshot = snap
        p = snap.params
        if force or p != previous.params:
            self.query_one(SamplingLine).show(p, self.defaults)
            self.query_one(ProcessImage).snapshot = operating_point_view(snap)
            for table in self.query(ParamTable):
                table.params = p
            self.query_one(AnalysisPanel).params = p
            c = p.control
            kind = f"{c.family.value}, {c.structure.value}"
            if type_modified(p, self.defaults):
                kind = f"[i]{kind}[/i]"
            self.query_one("#controllers").border_title = f"Controller: {kind}  1-4"

    @staticmethod
    def status_text(snap: Snapshot) -> str:
        return (
            f"[b reverse] SETUP [/]  {snap.operation} · {snap.state} · {snap.control}"
            f"   t = {snap.t:.1f} s  [dim]process keeps running · Esc: Main[/]"
        )

    # --- windows -----------------------------------------------------------------------------

    def action_sampling(self) -> None:
        self.app.push_screen(SamplingTimeWindow(self.current().params, self.defaults, opener="s"), self.send_all)

    def action_reference(self, channel: int) -> None:
        opener = "i" if channel == 1 else "I"
        self.app.push_screen(WaveWindow(channel, self.current().params, self.defaults, opener=opener), self.send_all)

    def action_controller_type(self) -> None:
        self.app.push_screen(ControllerTypeWindow(self.current().params, self.defaults, opener="t"), self.send_all)

    def action_element(self, index: int) -> None:
        """An element's window: PID with the extras, or Main's General window."""
        p = self.current().params
        window = {"PID": PIDExtrasWindow, "State feedback": StateFeedbackWindow,
                  "MPC": MPCWindow}.get(p.control.family.value, GeneralWindow)
        self.app.push_screen(window(index, p, self.defaults, opener=str(index + 1)), self.send_all)

    def action_calibration(self) -> None:
        """The calibration on the rig (in Simul the window says why it is not available)."""
        self.app.push_screen(CalibrationWindow(self.current(), submit=self.send, opener="c"))

    def action_tank(self, tank: int) -> None:
        params = self.current().params
        if params.process is not None:  # another plant: its values in one window
            self.action_plant()
        elif tank in TANKS:
            self.app.push_screen(TankSetupWindow(tank, params, self.defaults), self.send_all)

    def action_plant(self) -> None:
        """The plant window of a plant other than the quadruple tank (its PLANT
        section): operating levels and constants."""
        params = self.current().params
        if params.process is not None:
            self.app.push_screen(PlantSetupWindow(params), self.send_all)

    def action_pump(self, pump: int) -> None:
        """A click on a pump of the operating-point image: its input is Main's."""
        self.notify(f"Pump {pump}'s input is set on Main (input signal {pump}).", timeout=3)

    def action_tanks(self) -> None:
        """Choose a tank in the process table (arrows, Enter opens it)."""
        self.query_one(ProcessTable).focus()

    def action_par_files(self, error: str = "") -> None:
        window = ParFileWindow(self.engine.par_names(), name=self.par_name, error=error, opener="f")
        self.app.push_screen(window, self._par_chosen)

    def _par_chosen(self, commands: Commands | None) -> None:
        for command in commands or ():
            if isinstance(command, (LoadPar, SavePar)):
                self.par_name = command.name
                verb = "Not loaded" if isinstance(command, LoadPar) else "Not saved"
                self.send(command, on_refused=functools.partial(self._par_refused, verb))
            else:
                self.send(command)

    def _par_refused(self, verb: str, why: str) -> None:
        """A refused file: the window again, saying why; the parameters in use are
        unchanged (the engine applies a file all or nothing)."""
        self.action_par_files(f"{verb}: {why}\nThe parameters in use are unchanged.")

    # --- defaults (S6) ------------------------------------------------------------------------

    def action_process_default(self) -> None:
        """The process image's Default: every tank and valve back to the defaults;
        another plant's values back to the published ones (its shipped preset)."""
        process = self.current().params.process
        if process is None:
            self.send(SetDefaults(SIMULATION_KEYS))
            return
        shipped = PLANT_SETTINGS.get(process.kind)
        if shipped is not None and shipped.process is not None:
            self.send(SetParams({PLANT_PREFIX + k: v for k, v in shipped.process.entries() if k != KIND_KEY}))

    def action_default_all(self) -> None:
        """Reread `default.par` for every parameter (asks first: it throws away the
        whole setting in use)."""

        def answered(yes: bool | None) -> None:
            if yes:
                self.send(LoadPar("default"))

        self.app.push_screen(
            ConfirmWindow("Default all", "Reload every parameter from default.par? The setting in use is lost "
                          "unless it was saved.", yes="Reload"),
            answered,
        )

    # --- back to Main ---------------------------------------------------------------------------

    def action_main(self) -> None:
        """Back to Main; the screen is kept for the next visit, idle (no timer), and
        opens again as on the first one, with no table chosen."""
        self._timer.pause()
        self._away = True
        self.set_focus(None)
        self.dismiss(None)


__all__ = ["SetupScreen"]
