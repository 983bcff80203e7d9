"""The Main screen (thesis 5.3; M1-M9): modes, controller box, input signals,
process image, two trends; every window opens from here.

It is the only part of the UI that talks to the engine: on its timer it reads the
latest snapshot and, when a new sample arrived, the ring buffers, and hands them
down to the widgets; the widgets' intents come up as actions; commands go to the
engine through `send`, and a refusal comes back as a notification.  No control
logic lives here.
"""

from __future__ import annotations

import time
from typing import Callable

from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical
from textual.css.query import NoMatches
from textual.widgets import Footer

from quadtank_tui.core.parameters import REFERENCE_SECTIONS
from quadtank_tui.core.plant import FULL_SCALE_V
from quadtank_tui.engine.commands import (
    LogDiscard, LogSave, NudgeMean, ResetControllers, SetControlMode,
    SetOperation, SetParams, SetSpeed, SetState,
)
from quadtank_tui.engine.handle import EngineHandle
from quadtank_tui.engine.snapshot import Snapshot
from quadtank_tui.ui.screens.sending import CommandSender
from quadtank_tui.ui.screens.setup import SetupScreen
from quadtank_tui.ui.widgets.controller_box import ControllerBox, element_used
from quadtank_tui.ui.widgets.input_signals import ChannelPanel
from quadtank_tui.ui.widgets.process_image import ProcessImage
from quadtank_tui.ui.widgets.status_line import StatusLine
from quadtank_tui.ui.widgets.trends import WINDOWS, Trend
from quadtank_tui.ui.windows.base import Choice, ChoiceWindow, ConfirmWindow, free_log_name
from quadtank_tui.ui.windows.controller import ControllerTypeWindow, GeneralWindow, PIDWindow
from quadtank_tui.ui.windows.logging import LoggingWindow
from quadtank_tui.ui.windows.process import PumpWindow, TankWindow
from quadtank_tui.ui.windows.signals import InputSignalWindow, PlotTypeWindow

#: How close to the brim (normalized level) counts as overflowing.
SPILL_MARGIN = 1e-6
#: Least wall time between two trend drawings on the timer, s (see _trends_due).
TREND_MIN_INTERVAL = 0.2
NO_DAQ = "Active needs a DAQ backend: start with quadtank --daq ..."


class MainScreen(CommandSender):
    """Operate the process."""

    # Nothing focused at start, so the footer shows the screen's keys; Tab
    # reaches the input panels (up/down nudge the mean there).
    AUTO_FOCUS = ""

    BINDINGS = [
        Binding("r", "run", "Run"),
        Binding("p", "pause", "Pause"),
        Binding("R", "reset", "Reset"),
        Binding("m", "manual", "Manual"),
        Binding("a", "automatic", "Auto"),
        Binding("s", "simul", "Simul", show=False),
        Binding("A", "active", "Active", show=False, tooltip=NO_DAQ),
        Binding("S", "setup", "Setup"),
        Binding("t", "controller_type", "Type"),
        Binding("1", "element(0)", "Element 11", show=False),
        Binding("2", "element(1)", "Element 12", show=False),
        Binding("3", "element(2)", "Element 21", show=False),
        Binding("4", "element(3)", "Element 22", show=False),
        Binding("C", "reset_controllers", "Reset controllers", show=False),
        Binding("i", "input(1)", "Input 1"),
        Binding("I", "input(2)", "Input 2", show=False),
        Binding("o", "toggle_wave(1)", "Wave 1 on/off", show=False),
        Binding("O", "toggle_wave(2)", "Wave 2 on/off", show=False),
        Binding("right_square_bracket", "nudge(1, 0.01)", "Mean 1 +", show=False),
        Binding("left_square_bracket", "nudge(1, -0.01)", "Mean 1 -", show=False),
        Binding("right_curly_bracket", "nudge(2, 0.01)", "Mean 2 +", show=False),
        Binding("left_curly_bracket", "nudge(2, -0.01)", "Mean 2 -", show=False),
        Binding("h", "tank(1)", "Tanks"),
        Binding("v", "pump(1)", "Pumps", show=False),
        Binding("g", "plot_type('upper')", "Upper plot", show=False),
        Binding("G", "plot_type('lower')", "Lower plot", show=False),
        Binding("z", "time_window", "Time window", show=False),
        Binding("Z", "autoscale", "Autoscale", show=False),
        Binding("plus", "speed(2.0)", "Faster", show=False, tooltip="Simul with a virtual clock only"),
        Binding("minus", "speed(0.5)", "Slower", show=False, tooltip="Simul with a virtual clock only"),
        Binding("l", "logging", "Log"),
        Binding("q", "exit", "Exit"),
    ]

    def __init__(self, engine: EngineHandle, *, refresh_interval: float = 0.05,
                 wall_clock: Callable[[], float] = time.monotonic) -> None:
        super().__init__()
        self.engine = engine
        self.refresh_interval = refresh_interval
        self.wall_clock = wall_clock
        self.defaults = engine.defaults()
        self.snap: Snapshot = engine.snapshot()
        self._drawn_view: tuple[object, ...] = ()
        self._drawn_t, self._drawn_k, self._drawn_at = 0.0, -1, 0.0
        self.window_index = 1  # 5 min
        self.autoscale = True

    def compose(self) -> ComposeResult:
        yield StatusLine(id="status")
        with Horizontal(id="top"):
            yield ControllerBox(self.defaults, id="controller")
            yield ProcessImage(id="image")
            with Vertical(id="inputs"):
                yield ChannelPanel(1, self.defaults)
                yield ChannelPanel(2, self.defaults)
        with Horizontal(id="trends"):
            yield Trend("upper", id="upper")
            yield Trend("lower", id="lower")
        yield Footer()

    def on_mount(self) -> None:
        self.refresh_view()
        self.set_interval(self.refresh_interval, self._tick)

    # --- attributes down ------------------------------------------------------------

    def _tick(self) -> None:
        # While the Setup screen covers this one nothing here is seen: skip the work.
        if not any(isinstance(screen, SetupScreen) for screen in self.app.screen_stack):
            self.refresh_view(timer=True)

    def refresh_view(self, *, timer: bool = False) -> None:
        """Show the latest snapshot (status, controller box, image, inputs), and the
        trends when that shows something (see `_trends_due`)."""
        snap = self.engine.snapshot()
        status = self.query_one(StatusLine)
        status.age = max(0.0, self.wall_clock() - snap.stats.last_sample_wall)
        window = WINDOWS[self.window_index]
        changed = snap != self.snap or status.snapshot is None
        if changed:
            previous, self.snap = self.snap, snap
            status.snapshot = snap
            self.query_one(ControllerBox).params = snap.params
            self.query_one(ProcessImage).snapshot = snap
            self._spill_alarm(snap)
            for panel in self.query(ChannelPanel):
                panel.snapshot = snap
            if snap.params.control != previous.params.control:
                self.refresh_bindings()
        view = (window, self.autoscale, self.size, snap.params.plots, snap.state, snap.control)
        if self._trends_due(snap, view, timer):
            self._drawn_view, self._drawn_t, self._drawn_k = view, snap.t, snap.k
            self._drawn_at = time.monotonic()
            history = self.engine.history(window)
            for trend, plot_type in ((self.query_one("#upper", Trend), snap.params.plots.upper),
                                     (self.query_one("#lower", Trend), snap.params.plots.lower)):
                trend.plot_type, trend.window, trend.autoscale = plot_type, window, self.autoscale
                trend.show(history)
        live = self.app.screen
        if isinstance(live, (TankWindow, PumpWindow, LoggingWindow)):
            try:
                live.snapshot = snap
            except NoMatches:  # the window is being taken down
                pass

    def _spill_alarm(self, snap: Snapshot) -> None:
        """Mark the tanks that overflow on the image, and say so once when a
        tank starts to (the simulator spills silently otherwise)."""
        spilling = spilling_tanks(snap)
        image = self.query_one(ProcessImage)
        started = spilling - image.spilling
        image.spilling = spilling
        if started:
            names = " and ".join(str(n) for n in sorted(started))
            which = f"Tanks {names} overflow" if len(started) > 1 else f"Tank {names} overflows"
            self.notify(f"{which}: water spills out of the process.",
                        title="Alarm", severity="warning", timeout=8)

    def _trends_due(self, snap: Snapshot, view: tuple[object, ...], timer: bool) -> bool:
        """Whether to redraw the trends now.

        Drawing a trend costs plotext tens of milliseconds, so on the timer they are
        drawn only when the curves moved by at least one braille dot of the time
        axis, and at most every TREND_MIN_INTERVAL of wall time; otherwise the
        redraws would take the CPU the control loop needs (seen in a terminal as
        overruns at speed x8).  A changed view, a stop, or an explicit refresh draws
        at once.
        """
        if not timer or view != self._drawn_view:
            return True
        if snap.k == self._drawn_k:
            return False
        if snap.state != "Run":
            return True
        dot = WINDOWS[self.window_index] / max(1, 2 * self.query_one("#upper", Trend).size.width)
        return (abs(snap.t - self._drawn_t) >= dot
                and time.monotonic() - self._drawn_at >= TREND_MIN_INTERVAL)

    # --- messages up ----------------------------------------------------------------

    def check_action(self, action: str, parameters: tuple[object, ...]) -> bool | None:
        """Keys that cannot act now are shown disabled (and do nothing)."""
        snap = self.snap
        if action == "active" and not snap.active_available:
            return None
        if action == "speed" and (snap.operation != "Simul" or snap.realtime or snap.speed == float("inf")):
            return None
        if action == "element" and parameters and not element_used(snap.params, int(parameters[0])):  # type: ignore[call-overload]
            return None
        return True

    # --- modes (M1-M3) ------------------------------------------------------------------

    def action_run(self) -> None:
        self.send(SetState("Run"))

    def action_pause(self) -> None:
        self.send(SetState("Pause"))

    def action_reset(self) -> None:
        self.send(SetState("Reset"))

    def action_simul(self) -> None:
        self.send(SetOperation("Simul"))

    def action_active(self) -> None:
        if not self.snap.active_available:
            self.notify(NO_DAQ, severity="warning")
            return
        self.send(SetOperation("Active"))

    def action_manual(self) -> None:
        self.send(SetControlMode("Manual"))

    def action_automatic(self) -> None:
        self.send(SetControlMode("Automatic"))

    def action_speed(self, factor: float) -> None:
        """Simul with a virtual clock: process seconds per wall second, 1..1000."""
        speed = min(1000.0, max(1.0, self.current().speed * factor))
        self.send(SetSpeed(speed))

    # --- controller box (M5) ------------------------------------------------------------

    def action_controller_type(self) -> None:
        snap = self.current()
        self.app.push_screen(ControllerTypeWindow(snap.params, self.defaults, opener="t"), self.send_all)

    def action_element(self, index: int) -> None:
        snap = self.current()
        p = snap.params
        if not element_used(p, index):
            return
        window = PIDWindow if p.control.family.value == "PID" else GeneralWindow
        self.app.push_screen(window(index, p, self.defaults, opener=str(index + 1)), self.send_all)

    def action_reset_controllers(self) -> None:
        self.send(ResetControllers())

    # --- input signals (M4) -------------------------------------------------------------

    def action_input(self, channel: int) -> None:
        snap = self.current()
        window = InputSignalWindow(channel, snap.control, snap.params, self.defaults,
                                   opener="i" if channel == 1 else "I")
        self.app.push_screen(window, self.send_all)

    def action_toggle_wave(self, channel: int) -> None:
        snap = self.current()
        key = f"{REFERENCE_SECTIONS[channel - 1]}.On"
        self.send(SetParams({key: not snap.params.get(key)}))

    def action_nudge(self, channel: int, delta: float) -> None:
        self.send(NudgeMean(channel, delta))

    # --- process image (M6) ---------------------------------------------------------------

    def action_tank(self, tank: int = 1) -> None:
        snap = self.current()
        self.app.push_screen(TankWindow(snap, self.defaults, tank, opener="h"), self.send_all)

    def action_pump(self, pump: int = 1) -> None:
        snap = self.current()
        self.app.push_screen(PumpWindow(snap, self.defaults, pump, opener="v"), self.send_all)

    # --- trends (M7) ------------------------------------------------------------------

    def action_plot_type(self, which: str) -> None:
        snap = self.current()
        window = PlotTypeWindow(which, snap.params, self.defaults, opener="g" if which == "upper" else "G")
        self.app.push_screen(window, self.send_all)

    def action_time_window(self) -> None:
        self.window_index = (self.window_index + 1) % len(WINDOWS)
        self.refresh_view()

    def action_autoscale(self) -> None:
        self.autoscale = not self.autoscale
        self.refresh_view()

    # --- logging (M8) and exit (M9) ---------------------------------------------------

    def action_logging(self) -> None:
        snap = self.current()
        window = LoggingWindow(snap, self.defaults, submit=self.send,
                               log_exists=self.engine.log_exists, opener="l")
        self.app.push_screen(window, self.send_all)

    def action_setup(self) -> None:
        """The Setup screen (M1's third operation mode): the process runs on as it
        was; Esc there comes back here."""
        # Setup shows only the process time live: a quarter second is plenty, and
        # a slower refresh asked for a slow link is kept.
        self.app.push_screen(SetupScreen(self.engine, refresh_interval=max(0.25, self.refresh_interval)))

    def action_exit(self) -> None:
        """Exit, asking first; an unsaved log is saved by default (Enter), never
        thrown away without a second choice."""
        log = self.current().log
        if not log.unsaved:
            self.app.push_screen(ConfirmWindow("Exit", "Stop the loop and exit?", yes="Exit"),
                                 lambda yes: self.app.exit() if yes else None)
            return
        earlier = log.started_as or log.file
        name = free_log_name(earlier, self.engine.log_exists)
        question = f"The log ({log.rows} rows) has not been saved.\nSave and exit saves it as logs/{name}.log"
        question += f" (logs/{earlier}.log exists and is kept)." if name != earlier else "."
        choices = (Choice("save", "Save and exit", "success"),
                   Choice("discard", "Discard and exit", "error"),
                   Choice("cancel", "Cancel"))

        def answered(answer: str | None) -> None:
            if answer == "save":
                self.send(LogSave(name), on_done=self.app.exit)
            elif answer == "discard":
                self.send(LogDiscard(), on_done=self.app.exit)

        self.app.push_screen(ChoiceWindow("Exit", question, choices), answered)


def spilling_tanks(snap: Snapshot) -> frozenset[int]:
    """The simulated tanks at the brim while the process runs: water keeps coming
    in (else the level would fall) and spills over."""
    if snap.operation != "Simul" or snap.state != "Run":
        return frozenset()
    plant = snap.params.plant()
    brim = plant.kc * plant.hmax / FULL_SCALE_V - SPILL_MARGIN
    return frozenset(n for n, level in enumerate(snap.y, start=1) if level >= brim)
