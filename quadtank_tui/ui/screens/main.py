"""The Main screen (thesis 5.3; M1-M9): modes, controller box, input signals,
process image, two trends; every window opens from here.

It is the only part of the UI that talks to the engine: on its timer it reads the
latest snapshot and, when a new sample arrived, the ring buffers, and hands them
down to the widgets; the widgets' intents come up as actions; commands go to the
engine through `send`, and a refusal comes back as a notification.  No control
logic lives here.
"""

from __future__ import annotations

import dataclasses
import math
import time
from functools import partial
from typing import Callable

from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical
from textual.css.query import NoMatches

from quadtank_tui.core.parameters import REFERENCE_SECTIONS, SimulationSettings
from quadtank_tui.core.plants.common import FULL_SCALE_V
from quadtank_tui.engine.commands import (
    LogDiscard, LogSave, NudgeMean, ResetControllers, SetControlMode,
    SetOperation, SetParams, SetSpeed, SetState,
)
from quadtank_tui.engine.clock import next_speed
from quadtank_tui.engine.handle import EngineHandle, LabSession, lab_session_of
from quadtank_tui.engine.snapshot import LoopStats, Snapshot
from quadtank_tui.ui.asked_speed import AskedSpeed
from quadtank_tui.ui.screens.sending import CommandSender
from quadtank_tui.ui.widgets.analysis_panel import analysis_ready, warm_up
from quadtank_tui.ui.widgets.controller_box import ControllerBox, element_used
from quadtank_tui.ui.widgets.input_signals import ChannelPanel
from quadtank_tui.ui.widgets.key_footer import KeyFooter
from quadtank_tui.ui.widgets.process_image import ProcessImage
from quadtank_tui.ui.widgets.session_bar import SessionBar
from quadtank_tui.ui.widgets.status_line import StatusLine
from quadtank_tui.ui.widgets.trend_clock import ClockMap
from quadtank_tui.ui.plot_axes import scroll_step
from quadtank_tui.ui.widgets.trends import WINDOWS, Scale, Trend, TrendView, physical_scales
from quadtank_tui.ui.ghost import GhostControl
from quadtank_tui.ui.windows.base import Choice, ChoiceWindow, ConfirmWindow, LiveWindow, free_log_name
from quadtank_tui.ui.windows.controller_windows import ControllerTypeWindow, GeneralWindow, PIDWindow
from quadtank_tui.ui.windows.faults import FaultWindow
from quadtank_tui.ui.windows.mpc import MPCWindow
from quadtank_tui.ui.windows.statefb import StateFeedbackWindow
from quadtank_tui.ui.windows.logging import LoggingWindow
from quadtank_tui.ui.windows.process import PumpWindow, TankWindow
from quadtank_tui.ui.windows.signals import InputSignalWindow, PlotTypeWindow

_NO_STATS = LoopStats()
#: How close to the brim (normalized level) counts as overflowing.
SPILL_MARGIN = 1e-6
#: The screen's refresh interval while the loop is paused, s (see MainScreen._pace).
PAUSED_INTERVAL = 0.25
#: The name the Setup screen is installed under in the app (kept between visits).
SETUP_SCREEN = "setup"
#: Least wall time between two trend drawings on the timer, s (see _trends_due).
TREND_MIN_INTERVAL = 0.2
NO_DAQ = ("Active runs the real rig, and this session has no DAQ: it runs the simulator "
          "only. Start with quadtank --daq CONFIG (see params/daq-*.yaml) to offer Active.")


def _untimed(snap: Snapshot) -> Snapshot:
    """The snapshot without the loop's timing, which no window shows."""
    return dataclasses.replace(snap, stats=_NO_STATS)


def _warm_up(sim: SimulationSettings) -> None:
    """After the first frame, in a thread: what the Setup screen needs, so it opens
    at once with its analysis of `sim` (scipy takes a second to import on a loaded
    machine), without delaying the first frame."""
    import quadtank_tui.ui.screens.setup  # noqa: F401

    if not analysis_ready():
        warm_up(sim)


class MainScreen(CommandSender):
    """Operate the process."""

    # Nothing focused at start, so the footer shows the screen's keys; Tab
    # reaches the input panels (up/down nudge the mean there).
    AUTO_FOCUS = ""

    # The tooltip is the longer description the help screen (`?`) and the command
    # palette show next to the key.  The footer shows only the keys the status
    # line does not (its mode words carry theirs), so it fits 80 columns.
    BINDINGS = [
        Binding("r", "run", "Run", show=False, tooltip="Run: sample, control and log"),
        Binding("p", "pause", "Pause", show=False, tooltip="Pause: the pumps hold, nothing is sampled"),
        Binding("R", "reset", "Reset", show=False, tooltip="All states back, the simulation to its operating point, Pause"),
        Binding("m", "manual", "Manual", show=False, tooltip="Manual: the generators drive u1, u2 (bumpless)"),
        Binding("a", "automatic", "Auto", show=False, tooltip="Automatic: the generators drive ref1, ref2 (bumpless)"),
        Binding("s", "simul", "Simul", show=False, tooltip="Simul: the simulated process"),
        Binding("A", "active", "Active", show=False, tooltip="Active: the real rig (needs quadtank --daq CONFIG)"),
        Binding("S", "setup", "Setup", tooltip="The Setup screen: sampling time, waves, PID extras, tanks, .par files"),
        Binding("d", "design", "Design", show=False, tooltip="The Design screen: PI/PID from a model, evaluated, then Apply"),
        Binding("y", "identify", "Identify", show=False, tooltip="The Identify screen: models from a logged experiment"),
        Binding("F", "faults", "Faults", show=False, tooltip="Simul only: break the simulated process (leaks, clogs, sensors)"),
        Binding("t", "controller_type", "Type", tooltip="Controller type: PID or General (decentralized or full), state feedback or MPC"),
        Binding("1", "element(0)", "Element 11", show=False, tooltip="Controller element 11 (error 1 to input 1)"),
        Binding("2", "element(1)", "Element 12", show=False, tooltip="Controller element 12 (full matrix only)"),
        Binding("3", "element(2)", "Element 21", show=False, tooltip="Controller element 21 (full matrix only)"),
        Binding("4", "element(3)", "Element 22", show=False, tooltip="Controller element 22 (error 2 to input 2)"),
        Binding("C", "reset_controllers", "Reset controllers", show=False, tooltip="Reset the controllers' states"),
        Binding("i", "input(1)", "Input 1", tooltip="Input signal 1: wave, mean (a typed mean is a step), amplitude, period"),
        Binding("I", "input(2)", "Input 2", show=False, tooltip="Input signal 2"),
        Binding("o", "toggle_wave(1)", "Wave 1 on/off", show=False, tooltip="Wave of input 1 on or off"),
        Binding("O", "toggle_wave(2)", "Wave 2 on/off", show=False, tooltip="Wave of input 2 on or off"),
        Binding("right_square_bracket", "nudge(1, 0.01)", "Mean 1 +", show=False, tooltip="Mean of input 1 up by 0.01"),
        Binding("left_square_bracket", "nudge(1, -0.01)", "Mean 1 -", show=False, tooltip="Mean of input 1 down by 0.01"),
        Binding("right_curly_bracket", "nudge(2, 0.01)", "Mean 2 +", show=False, tooltip="Mean of input 2 up by 0.01"),
        Binding("left_curly_bracket", "nudge(2, -0.01)", "Mean 2 -", show=False, tooltip="Mean of input 2 down by 0.01"),
        Binding("h", "tank(1)", "Tanks", tooltip="Tank window: op. point, diameter, time constant; in Simul add water"),
        Binding("v", "pump(1)", "Pumps", show=False, tooltip="Pump window: the pumps' inputs and valves"),
        Binding("g", "plot_type('upper')", "Upper plot", show=False, tooltip="What the upper trend shows"),
        Binding("G", "plot_type('lower')", "Lower plot", show=False, tooltip="What the lower trend shows"),
        Binding("z", "time_window", "Time window", show=False, tooltip="Trend time window: 2, 5, 10, 30 min"),
        Binding("Z", "autoscale", "Autoscale", show=False, tooltip="Trends autoscaled or full scale"),
        Binding("u", "units", "Units", show=False, tooltip="Trends normalized or in the plant's units (levels cm, pumps V)"),
        Binding("c", "clock_axis", "Clock", show=False,
                tooltip="Trends' time axis in s before now or at the clock times the samples were taken"),
        Binding("left", "scroll_trends(1)", "Trends back", show=False,
                tooltip="Paused: scroll the trends back through the history (half a window)"),
        Binding("right", "scroll_trends(-1)", "Trends forward", show=False, tooltip="Paused: scroll the trends forward"),
        Binding("end", "scroll_trends(0)", "Trends live", show=False, tooltip="Trends back to the newest samples"),
        Binding("b", "ghost", "Ghost", show=False,
                tooltip="Draw a saved .log dimmed behind the trends (the last one by default)"),
        Binding("B", "clear_ghost", "Clear ghost", show=False, tooltip="Remove the ghost run from the trends"),
        Binding("E", "export_figure", "Export figure", show=False,
                tooltip="The trends in view as a PNG figure in the logs folder (the name is shown)"),
        Binding("plus", "speed(1)", "Faster", show=False,
                tooltip="Simul: next speed of 1, 2, 5 ... 1000 x real time"),
        Binding("minus", "speed(-1)", "Slower", show=False, tooltip="Simul: previous speed step"),
        Binding("l", "logging", "Log", show=False, tooltip="Logging window: points, file, variables, LogOn, LogOff, Save"),
        Binding("k", "bookings", "Bookings", show=False, tooltip="The rig's bookings: book or cancel a slot"),
        Binding("x", "exercise", "Exercise", show=False,
                tooltip="Exercise window: its text, the requirements live, the time left"),
        Binding("question_mark", "app.help", "Help", tooltip="Every key of every screen and window"),
        Binding("f1", "app.help", "Help", show=False, tooltip="Every key of every screen and window"),
        Binding("q", "exit", "Exit", show=False, tooltip="Exit: asks first, and says so if a log would be thrown away"),
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
        #: The live window last given a snapshot, and that snapshot without its timing.
        self._live: object = None
        self._live_snap: Snapshot = _untimed(self.snap)
        self.window_index = 1  # 5 min
        self._banner: str | None = None
        self.autoscale = True
        #: Trends in the plant's units (else normalized); how far back they show, s.
        self.physical = False
        self.trend_offset = 0.0
        self._asked_speed = AskedSpeed()  # + and - step from the last press, not the snapshot
        #: The trends' time axis in clock time (else s before now); the clock of each
        #: sample as it arrived, and where the wall clock comes from (epoch s).
        self.clock_axis = False
        self.clock_map = ClockMap()
        self.epoch_clock: Callable[[], float] = time.time
        self._clock_k = -1  # the sample count at the last look (-1: none yet)
        self._scales: tuple[object, tuple[tuple[str, Scale], ...]] = (None, ())
        self.ghost = GhostControl(self)

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
        banner = self._session_banner()
        if banner is not None:  # a client of a lab session: whose it is, who drives it
            yield SessionBar(banner, id="session-bar")
        yield KeyFooter()

    def _session_banner(self) -> str | None:
        session = lab_session_of(self.engine)
        return session.session_banner() if session is not None else None

    def on_mount(self) -> None:
        # The widgets the timer feeds, found once: a DOM query costs milliseconds,
        # at 20 ticks a second most of an idle screen's CPU.
        self._status = self.query_one(StatusLine)
        self._controller = self.query_one(ControllerBox)
        self._image = self.query_one(ProcessImage)
        self._panels = tuple(self.query(ChannelPanel))
        self._upper, self._lower = self.query_one("#upper", Trend), self.query_one("#lower", Trend)
        self.refresh_view()
        self._interval = self.refresh_interval
        self._timer = self.set_interval(self._interval, self._tick)
        self.ghost.restore()  # the ghost this user showed on this session, on a re-attach
        self._restore_trends()
        self.call_after_refresh(self.run_worker, partial(_warm_up, self.snap.params.simulation), thread=True,
                                group="warm-up", exit_on_error=False)

    # --- attributes down ------------------------------------------------------------

    def on_screen_resume(self) -> None:
        """Back from Setup, Design or Identify (which this screen does not redraw
        under): show the process as it is now, not at the next tick - while paused
        that is up to PAUSED_INTERVAL away, and an Apply made there would not show."""
        if hasattr(self, "_controller"):  # mounted: the widgets are found
            self.refresh_view()

    def _tick(self) -> None:
        # While the Setup screen (the other CommandSender) covers this one nothing
        # here is seen: skip the work.
        if any(isinstance(screen, CommandSender) and screen is not self for screen in self.app.screen_stack):
            pass
        elif self.redraw_due():
            self.refresh_view(timer=True)
        else:  # dimmed behind a window (screens/behind.py): the live window follows each sample
            self._feed_live(self.engine.snapshot())
        self._pace()

    def _pace(self) -> None:
        """Tick at the refresh interval while the loop runs, at most 4 times a second
        while it is paused: a paused screen changes only on a command (which redraws
        at once) or a fault, and each tick costs a wake-up (issue 17: under 2 % of
        a core when paused)."""
        interval = self.refresh_interval if self.snap.state == "Run" else max(self.refresh_interval, PAUSED_INTERVAL)
        if interval != self._interval:
            self._timer.stop()
            self._interval = interval
            self._timer = self.set_interval(interval, self._tick)

    def refresh_view(self, *, timer: bool = False) -> None:
        """Show the latest snapshot (status, controller box, image, inputs), and the
        trends when that shows something (see `_trends_due`)."""
        snap = self.engine.snapshot()
        status = self._status
        status.age = max(0.0, self.wall_clock() - snap.stats.last_sample_wall)
        window = WINDOWS[self.window_index]
        changed = snap != self.snap or status.snapshot is None
        if changed:
            previous, self.snap = self.snap, snap
            status.snapshot = snap
            # Each widget repaints only if what it shows changed.
            self._controller.statefb = snap.statefb
            self._controller.mpc = snap.mpc
            self._controller.params = snap.params
            self._image.snapshot = snap
            self._spill_alarm(snap)
            for panel in self._panels:
                panel.snapshot = snap
            if snap.params.control != previous.params.control:
                self.refresh_bindings()
        banner = self._session_banner()
        if banner is not None and banner != self._banner:
            self._banner = banner
            try:
                self.query_one("#session-bar", SessionBar).update(banner)
            except NoMatches:
                pass
        if snap.state == "Run":
            self.trend_offset = 0.0  # scrolling back is for a paused trend
        self.ghost.follow(snap)
        self._note_clock(snap, status.age)
        view = (window, self.autoscale, self.size, snap.params.plots, snap.state, snap.control,
                self.physical, self.trend_offset, self.ghost.run, self.ghost.start, self.clock_axis)
        if self._trends_due(snap, view, timer):
            self._drawn_view, self._drawn_t, self._drawn_k = view, snap.t, snap.k
            self._drawn_at = time.monotonic()
            # Beyond the window: the time axis may show a little more (x_axis).
            history = self.engine.history(1.5 * window + self.trend_offset)
            scales = self._trend_scales(snap) if self.physical else ()
            for trend, plot_type in ((self._upper, snap.params.plots.upper),
                                     (self._lower, snap.params.plots.lower)):
                trend.show(history, TrendView(plot_type, window, self.autoscale, self.trend_offset,
                                              scales, self.ghost.run, self.ghost.start,
                                              self.clock_map if self.clock_axis else None))
        self._feed_live(snap)

    def _note_clock(self, snap: Snapshot, age: float) -> None:
        """The wall clock of the newest sample (the one before snap.t, which is the
        next sample's time), `age` seconds ago, for the clock axis.  Seen from the
        first sample on (k was 0 at the last look), the run's start is known too: the
        samples in between went at the speed of the snapshot."""
        watched_start, self._clock_k = self._clock_k == 0, snap.k
        if snap.k <= 0:
            return
        t = max(0.0, snap.t - snap.params.tsamp)
        wall = self.epoch_clock() - (age if age < 60 else 0.0)  # minutes: a stalled loop, or clocks apart
        if watched_start and t > 0:  # (after a Reset: the map starts again)
            self.clock_map.note(0.0, wall - (t / snap.speed if 0 < snap.speed < math.inf else 0.0))
        if snap.state == "Run":
            self.clock_map.note(t, wall)
        else:  # paused: a simulation takes no samples, the newest one stands (a rig's go on)
            self.clock_map.stand(t, wall)

    def _feed_live(self, snap: Snapshot) -> None:
        """Hand the snapshot to the live window in front (Tank, Pump, Logging,
        Exercise); an exercise followed hears the loop's mode even with its window closed."""
        exercise = getattr(self.app, "exercise", None)
        if exercise is not None:
            exercise.note(snap.automatic_since)
        live = self.app.screen
        # A live window gets the snapshot only when more than the loop's timing
        # changed (a paused loop's idle ticks).
        fed = isinstance(live, (TankWindow, PumpWindow, LoggingWindow)) or (
            isinstance(live, LiveWindow) and getattr(live, "follows_loop", False))
        if fed and live.is_mounted:
            assert isinstance(live, LiveWindow)
            untimed = _untimed(snap)
            if live is not self._live or untimed != self._live_snap:
                self._live, self._live_snap = live, untimed
                try:
                    live.snapshot = snap
                except NoMatches:  # the window is being taken down
                    pass

    def _spill_alarm(self, snap: Snapshot) -> None:
        """Mark the tanks that overflow on the image, and say so once when a
        tank starts to (the simulator spills silently otherwise)."""
        spilling = spilling_tanks(snap)
        image = self._image
        started = spilling - image.spilling
        image.spilling = spilling
        if started:
            names = " and ".join(str(n) for n in sorted(started))
            which = f"Tanks {names} overflow" if len(started) > 1 else f"Tank {names} overflows"
            self.notify(f"{which}: water spills out of the process.",
                        title="Alarm", severity="warning", timeout=8)

    def _trends_due(self, snap: Snapshot, view: tuple[object, ...], timer: bool) -> bool:
        """Whether to redraw the trends now.

        Drawing a trend costs milliseconds (every sample in view joined: about 3 ms
        for 4 signals over 5 min, 13 ms over 30 min), so on the timer they are drawn only when the curves moved by at least one braille dot of the time
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
        dot = WINDOWS[self.window_index] / max(1, 2 * self._upper.size.width)
        return (abs(snap.t - self._drawn_t) >= dot
                and time.monotonic() - self._drawn_at >= TREND_MIN_INTERVAL)

    # --- messages up ----------------------------------------------------------------

    def check_action(self, action: str, parameters: tuple[object, ...]) -> bool | None:
        """Keys that cannot act now are shown disabled (and do nothing)."""
        snap = self.snap
        if action == "speed" and (snap.operation != "Simul" or snap.realtime or snap.speed == float("inf")):
            return None
        if action == "element" and parameters:
            n = parameters[0]  # Textual types action arguments as objects: element(n) has an int
            if isinstance(n, int) and not element_used(snap.params, n):
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

    def action_speed(self, direction: int) -> None:
        """Simul with a virtual clock: the next step of SPEED_STEPS up or down."""
        base = self._asked_speed.base(self.current().speed)
        speed = next_speed(base, direction)
        if speed == base:
            return  # at an end
        self._asked_speed.asked(speed)

        def refused(message: str) -> None:
            self._asked_speed.answered(False)
            self.notify(message, title="SetSpeed", severity="error", timeout=6, markup=False)

        self.send(SetSpeed(speed), on_refused=refused, on_done=lambda: self._asked_speed.answered(True))

    # --- controller box (M5) ------------------------------------------------------------

    def action_controller_type(self) -> None:
        snap = self.current()
        self.app.push_screen(ControllerTypeWindow(snap.params, self.defaults, opener="t"), self.send_all)

    def action_element(self, index: int) -> None:
        snap = self.current()
        p = snap.params
        if not element_used(p, index):
            return
        window = {"PID": PIDWindow, "State feedback": StateFeedbackWindow,
                  "MPC": MPCWindow}.get(p.control.family.value, GeneralWindow)
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

    def action_faults(self) -> None:
        self.app.push_screen(FaultWindow(self.current(), opener="F"), self.send_all)

    # --- trends (M7) ------------------------------------------------------------------

    def action_plot_type(self, which: str) -> None:
        snap = self.current()
        window = PlotTypeWindow(which, snap.params, self.defaults, opener="g" if which == "upper" else "G")
        self.app.push_screen(window, self.send_all)

    def action_time_window(self) -> None:
        self.window_index = (self.window_index + 1) % len(WINDOWS)
        self._trends_changed()

    def action_autoscale(self) -> None:
        self.autoscale = not self.autoscale
        self._trends_changed()

    def action_units(self) -> None:
        self.physical = not self.physical
        self._trends_changed()

    def action_clock_axis(self) -> None:
        self.clock_axis = not self.clock_axis
        self._trends_changed()

    def _trends_changed(self) -> None:
        """Redraw, and remember the trends' settings for this session (a re-attach
        shows them again: files/trend_memory.py)."""
        self.refresh_view()
        session = self.ghost.session()
        if session is not None:
            from quadtank_tui.files.trend_memory import TrendSettings, remember

            remember(session, TrendSettings(self.window_index, self.autoscale, self.physical, self.clock_axis))

    def _restore_trends(self) -> None:
        """The trends as this user last set them on this session (a re-attach)."""
        session = self.ghost.session()
        if session is None:
            return
        from quadtank_tui.files.trend_memory import recall

        settings = recall(session)
        if settings is not None and 0 <= settings.window_index < len(WINDOWS):
            self.window_index, self.autoscale = settings.window_index, settings.autoscale
            self.physical, self.clock_axis = settings.physical, settings.clock_axis
            self.refresh_view()

    def _trend_scales(self, snap: Snapshot) -> tuple[tuple[str, Scale], ...]:
        """The plant's units per signal, worked out again only when the
        parameters change."""
        if self._scales[0] != snap.params:
            self._scales = (snap.params, tuple(physical_scales(snap.params).items()))
        return self._scales[1]

    def action_scroll_trends(self, direction: int) -> None:
        """Left/right: half a window back/forward through the history kept (paused
        only: running, the trends follow the newest sample); End: live again."""
        if direction and self.current().state == "Run":
            self.notify("Pause first (p): a running trend follows the newest sample.", timeout=4)
            return
        window = WINDOWS[self.window_index]
        step = scroll_step(window, self._upper.columns)
        kept = self.engine.history()["t"]
        most = float(kept[-1] - kept[0]) if len(kept) else 0.0
        offset = 0.0 if not direction else self.trend_offset + direction * step
        # Not so far back that nothing is left in view.
        self.trend_offset = min(max(0.0, offset), max(0.0, step * math.floor(most / step - 1e-6)))
        self.refresh_view()

    def action_ghost(self) -> None:
        self.ghost.choose()

    def action_clear_ghost(self) -> None:
        self.ghost.clear()

    def action_export_figure(self) -> None:
        """The trends in view, as shown (window, scroll, units), drawn in a worker."""
        from pathlib import Path

        from quadtank_tui.ui.figure_export import export, trends_builder

        snap, window = self.snap, WINDOWS[self.window_index]
        build = trends_builder(self.engine.history(window + self.trend_offset), (snap.params.plots.upper,
                               snap.params.plots.lower), window, self.trend_offset, snap.params, self.physical)
        export(self, Path(self.engine.logs_dir), "trends", build)

    # --- logging (M8) and exit (M9) ---------------------------------------------------

    def action_exercise(self) -> None:
        """The exercise window, when the TUI follows an exercise (quadtank exercise FILE)."""
        tracker = getattr(self.app, "exercise", None)
        if tracker is None:
            self.notify("No exercise: open one with quadtank exercise FILE (docs/exercises.md)")
            return
        from quadtank_tui.ui.windows.exercise import ExerciseWindow

        self.app.push_screen(ExerciseWindow(self.current(), tracker, self.engine, opener="x",
                                            wall_clock=getattr(self.app, "exercise_clock", time.time)))

    def action_bookings(self) -> None:
        """The Bookings window of the session's rig (session/bookings.py)."""
        from quadtank_tui.ui.windows.booking_slots import BookingsWindow

        info = getattr(self.engine, "info", None)
        self.app.push_screen(BookingsWindow(str(getattr(info, "daq", "") or ""), opener="k"))

    def action_logging(self) -> None:
        snap = self.current()
        window = LoggingWindow(snap, self.defaults, submit=self.send,
                               log_exists=self.engine.log_exists, opener="l")
        self.app.push_screen(window, self.send_all)

    def action_setup(self) -> None:
        """The Setup screen (M1's third operation mode): the process runs on as it
        was; Esc there comes back here."""
        # Built on the first visit and kept (installed): composing it again cost
        # 230-390 ms of CPU at each S; it shows what changed while away when it
        # comes back (SetupScreen.on_screen_resume).
        # Setup shows only the process time live: a quarter second is plenty, and
        # a slower refresh asked for a slow link is kept.
        from quadtank_tui.ui.screens.setup import SetupScreen  # loaded by _warm_up, not at start

        if not self.app.is_screen_installed(SETUP_SCREEN):
            self.app.install_screen(SetupScreen(self.engine, refresh_interval=max(0.25, self.refresh_interval)),
                                    name=SETUP_SCREEN)
        self.app.push_screen(SETUP_SCREEN)

    def action_design(self) -> None:
        """The Design screen (B3): PI/PID from a model; the process runs on, and
        nothing is applied until its Apply key."""
        from quadtank_tui.ui.screens.design import DesignScreen

        self.app.push_screen(DesignScreen(self.engine))

    def action_identify(self) -> None:
        """The Identify screen: models from logs while the process runs on; Esc
        comes back here."""
        from quadtank_tui.ui.screens.identify import IdentifyScreen

        # The engine's logs folder (a session's, wherever this terminal started), as
        # the ghost window lists.
        logs = self.engine.logs_dir
        self.app.push_screen(IdentifyScreen(logs, last_log=self.current().log.saved_path, engine=self.engine))

    def action_exit(self) -> None:
        """Exit, asking first; an unsaved log is saved by default (Enter), never
        thrown away without a second choice.  On a lab session: detach (it keeps
        running, as its policy says) or stop it."""
        session = lab_session_of(self.engine)
        if session is not None:
            self._exit_session(session)
            return
        self._exit_stopping(confirm=True)

    def _exit_session(self, engine: LabSession) -> None:
        sid = engine.session_id
        if engine.gone and engine.dropped is not None:  # this screen was dropped: the session runs on
            self.app.push_screen(ConfirmWindow("Exit", f"Session {sid} dropped this screen ({engine.dropped}); "
                                               f"it runs on: quadtank attach {sid} comes back to it.\nExit?",
                                               yes="Exit"),
                                 lambda yes: self.app.exit() if yes else None)
            return
        if engine.gone:  # it ended (or died): nothing of it to stop, and its id is no one else's to offer
            why = engine.ended or "its process is gone"
            self.app.push_screen(ConfirmWindow("Exit", f"Session {sid} has ended: {why}.\nExit?", yes="Exit"),
                                 lambda yes: self.app.exit() if yes else None)
            return
        if not engine.operating:
            self.app.push_screen(ConfirmWindow("Exit", f"Stop watching session {sid} and exit?\n"
                                               "It keeps running.", yes="Exit"),
                                 lambda yes: self.app.exit() if yes else None)
            return
        policy = engine.policy  # the lab's unattended policy, one sentence
        question = (f"Session {sid} can run on without this screen.\n"
                    f"Detach: it runs on; quadtank attach {sid} comes back to it. {policy}\n"
                    "Stop: the pumps at 0, logging stopped (its rows kept), the session ended.")
        choices = (Choice("detach", "Detach", "success"), Choice("stop", "Stop the session", "error"),
                   Choice("cancel", "Cancel"))

        def answered(answer: str | None) -> None:
            if answer == "detach":
                self.app.exit()
            elif answer == "stop":
                self._exit_stopping(confirm=False, leave=stop_and_exit)

        def stop_and_exit() -> None:
            engine.stop_on_exit()  # the CLI stops it once the app is down
            self.app.exit()

        self.app.push_screen(ChoiceWindow("Exit", question, choices), answered)

    def _exit_stopping(self, *, confirm: bool, leave: Callable[[], None] | None = None) -> None:
        """Exit stopping the loop: asks about an unsaved log (and, if `confirm`,
        whether to stop at all); `leave` exits (default: the app's exit)."""
        leave = leave or self.app.exit
        log = self.current().log
        if not log.unsaved:
            if not confirm:
                leave()
                return
            self.app.push_screen(ConfirmWindow("Exit", "Stop the loop and exit?", yes="Exit"),
                                 lambda yes: leave() if yes else None)
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
                self.send(LogSave(name), on_done=leave)
            elif answer == "discard":
                self.send(LogDiscard(), on_done=leave)

        self.app.push_screen(ChoiceWindow("Exit", question, choices), answered)


def spilling_tanks(snap: Snapshot) -> frozenset[int]:
    """The simulated tanks at the brim while the process runs: water keeps coming
    in (else the level would fall) and spills over."""
    if snap.operation != "Simul" or snap.state != "Run":
        return frozenset()
    sensors = snap.params.process_plant().outputs  # the plant in use: its sensors' full range
    return frozenset(n for n, (level, s) in enumerate(zip(snap.y, sensors), start=1)
                     if level >= s.hi / FULL_SCALE_V - SPILL_MARGIN)
