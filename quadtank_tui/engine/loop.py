"""The sampled control loop and its mode state machine (Nunes 1998, 5.3 and 5.5).

:class:`ControlLoop` is pure and synchronous: it owns the generators, the controller
matrix, the process backends and the logger, and does exactly one sample per
:meth:`ControlLoop.step`.  It knows nothing of threads or wall time; the one driver
(engine/driver.py) calls it at the times a clock gives, and the tests call it
directly.  Everything the outside may change goes through
:meth:`ControlLoop.apply` (or :meth:`ControlLoop.begin`), which validates first and
changes nothing if it refuses; a driver's own needs (its timing, its crash, the
end of the run) have methods too: no other module assigns to a
ControlLoop's attributes (tests/engine/test_loop_encapsulation.py).

The loop never touches the disk itself: log rows, LogOn/Save/Discard and `.par`
saves go to its :class:`FileWorker`, inline until :meth:`ControlLoop.use_file_thread`
(a real-time driver calls it), then on a writer thread, so a slow disk delays no
sample.  A write that fails there faults the loop at its next step.

One sample (Run)::

    y  = read levels                         (backend)
    w  = generator values                    (w1, w2)
    Automatic: r = w,  u = sat(C(r, y)),  C.update(r, y, u)
    Manual:    u = sat(w), r = y,         C.track(r, y, u)    (bumpless later)
    write u; log a row; history; snapshot; let h seconds of process time pass

C is the PID/General matrix on y1, y2, or the state feedback (core.controllers.statefb) on every
level of the plant; while the state feedback runs, the matrix tracks u so that switching
back to its family is bumpless too.  Making and changing C is engine/controllers.py's;
the calibration on the rig, which replaces the sample while it holds the pumps, is
engine/calibration_step.py's.

Pause: a simulation freezes (no time passes, nothing is logged); a real process gets
its pumps at 0.  Any exception in a sample puts the pumps at 0, pauses and shows why.
A zeroing the rig did not confirm (the backend's safe_state_error) is the fault shown
and is tried again at each tick, with nothing read from the rig meanwhile: a read
would feed its watchdog and beat its guard, which must stop the pumps if we cannot.
A real process does not wait for a late loop: the sampling slots the runner's clock
skipped pass (t moves on over them) and a log notes the late row (`% late: ...`),
so its TSamp never silently stands for samples that were further apart.
"""

from __future__ import annotations

import math
from dataclasses import replace
from datetime import datetime
from pathlib import Path
from concurrent.futures import Future
from typing import TYPE_CHECKING, Any, Callable, Mapping

from quadtank_tui.core.faults import Fault
from quadtank_tui.core.controllers.matrix import ControllerMatrix, Family, saturate
from quadtank_tui.core.parameters import TSAMP, ControlMode, Parameters
from quadtank_tui.core.plants.common import PlantError
from quadtank_tui.core.plants.spec import PREFIX as PLANT_PREFIX
from quadtank_tui.core.controllers.signals import Generator
from quadtank_tui.core.ranges import ParameterError
from quadtank_tui.engine.backend import (
    BackendError, Pair, ProcessBackend, arm, identity_refused, plant_refused, unconfirmed_stop,
)
from quadtank_tui.engine.calibration_step import RigCalibration
from quadtank_tui.engine.commands import (
    AddWater, CalibrationHeights, CancelCalibration, Command, CommandResult, InstallPar, LoadPar, LogDiscard, LogOff,
    LogOn, LogSave, NudgeMean, ResetControllers, SavePar, SetControlMode, SetDefaults, SetDisturbance, SetFault,
    SetOperation, SetParams, SetSpeed, SetState, StartCalibration,
)
from quadtank_tui.engine.controllers import Controllers
from quadtank_tui.engine.filework import FileWorker
from quadtank_tui.engine.history import DEFAULT_CAPACITY, History
from quadtank_tui.engine.jitter import LoopTiming
from quadtank_tui.engine.logsession import LogSession
from quadtank_tui.engine.outcome import refusal, resolved, then
from quadtank_tui.engine.parload import prepare_load
from quadtank_tui.engine.safety import InterlockRecord
from quadtank_tui.engine.sim import SimBackend
from quadtank_tui.engine.snapshot import LoopStats, Snapshot
from quadtank_tui.files.names import check_names
from quadtank_tui.files.par import RESERVED, ParStore

if TYPE_CHECKING:
    from quadtank_tui.engine.controllers import AnyStateFeedback


MODE_KEY = "CONTROL.Mode"
MEAN_KEYS = ("REFERENCE ONE.Mean", "REFERENCE TWO.Mean")
_FAMILY_KEYS = ("CONTROL.Type", "CONTROL.Structure")
# An enum member is looked up through a descriptor in Python 3.11 (60 ns): the
# sample compares with this name instead.
_AUTOMATIC = ControlMode.AUTOMATIC


class ControlLoop:
    """One sampled loop over a simulator and, optionally, a DAQ backend.

    params : the parameters to start with (the control mode starts Manual, M2)
    defaults : what counts as default (S6) and what SetDefaults restores
    store : the parameter folder (LoadPar / SavePar)
    logs_dir : where LogSave writes `<name>.log` (and the partial file lives)
    daq : a real process (Active), if one is configured
    now : wall-clock stamp for the logs' "Created on:" (injected: virtual runs pass
        a deterministic one)
    """

    def __init__(
        self,
        params: Parameters,
        *,
        defaults: Parameters | None = None,
        store: ParStore | None = None,
        logs_dir: Path | str = Path("logs"),
        daq: ProcessBackend | None = None,
        history_capacity: int = DEFAULT_CAPACITY,
        now: Callable[[], datetime] = datetime.now,
    ) -> None:
        params = params.with_value(MODE_KEY, ControlMode.MANUAL.value)
        self.params = params
        self.defaults = defaults if defaults is not None else params
        self.store = store if store is not None else ParStore(Path("params"))
        self.logs_dir = Path(logs_dir)
        self.sim = SimBackend.for_plant(params.process_plant(), params.process_levels())
        refused = plant_refused(daq, params.process_plant())
        if refused is not None:
            raise ValueError(refused)
        self.daq = daq
        self.backend: ProcessBackend = self.sim
        self.history = History(history_capacity)
        self._gens = (Generator(params.references[0], params.tsamp),
                      Generator(params.references[1], params.tsamp))
        sf_refused = None
        try:
            self.controllers = Controllers(params)
        except ParameterError as exc:  # a file asked for a state feedback there is no design for
            sf_refused = f"{params.control.family.value}: {exc}; the PID controllers are in force"
            params = self.params = params.with_value("CONTROL.Type", Family.PID.value)
            self.controllers = Controllers(params)
        self.running = False
        #: The calibration procedure on the rig (StartCalibration), and where its result goes.
        self.calibration = RigCalibration()
        #: Process time at which Automatic began (None in Manual): the window the
        #: headless summary measures the loops over.
        self.automatic_since: float | None = None
        #: What the rig's interlock held at 0 over the run (the headless summary says it).
        self.interlock = InterlockRecord()
        self.k = 0
        self.t = 0.0
        self._fixed_h = True  # t = k h until the sampling time changes (no drift in t)
        self.fault: str | None = sf_refused
        #: The rig's pumps not confirmed at 0 ("" when they are, or no rig): shown
        #: before `fault` and retried each tick until confirmed (see _retry_safe).
        self._unsafe = ""
        self._y = self.sim.read_levels()
        self._u = (0.0, 0.0)
        self._w = (self._gens[0].value(), self._gens[1].value())
        self._r = (self._y[0], self._y[1])
        #: Where the disk work goes (inline until use_file_thread()).
        self.files = FileWorker()
        self.log = LogSession(self.logs_dir, now, self.files)
        # Timing, filled in by the runner (the loop itself has no clock).
        #: Told each new sampling time as the parameters take it: the parameters own
        #: the sampling time (h), and the engine's clock follows them through this.
        self.on_sampling_time: Callable[[float], None] | None = None
        self.realtime = False
        self.speed = math.inf
        self._timing = LoopTiming()
        self._stats: LoopStats | None = None  # built from _timing when asked (stats)
        self._missed = 0  # sampling slots missed before the sample about to be done
        self._sampled_last = False  # the last step was a sample (not an idle tick, not a fault)
        self._snapshot: Snapshot | None = None  # built when asked (snapshot)

    # --- reading -----------------------------------------------------------------------

    @property
    def h(self) -> float:
        """Sampling time, s."""
        return self.params.tsamp

    @property
    def control(self) -> ControlMode:
        return self.params.control.mode

    @property
    def state(self) -> str:
        return "Run" if self.running else "Pause"

    @property
    def matrix(self) -> ControllerMatrix:
        return self.controllers.matrix

    @property
    def statefb(self) -> AnyStateFeedback | None:
        """The state-feedback controller while it is the type in force."""
        return self.controllers.statefb

    def snapshot(self) -> Snapshot:
        """The state after the last sample or command.  Built here, when asked, not at
        every sample: at x1000 a client reads one in a thousand (the session publishes
        every PUBLISH_INTERVAL) and a headless run none, and building one cost a fifth
        of a sample.  Every change of the loop's state marks it stale (:meth:`_stale`)."""
        snap = self._snapshot
        if snap is None:
            snap = self._snapshot = self._make_snapshot()
        return snap

    @property
    def stats(self) -> LoopStats:
        """The timing of the loop so far (built when asked, as the snapshot is)."""
        stats = self._stats
        if stats is None:
            stats = self._stats = self._timing.stats()
        return stats

    # --- one sample ---------------------------------------------------------------------

    def step(self) -> Snapshot:
        """Do one sample (Run) or one idle tick (Pause); never raises.  Its snapshot."""
        self.sample()
        return self.snapshot()

    def sample(self) -> None:
        """:meth:`step` without building the snapshot (the driver's call: nobody may
        read this sample's)."""
        # Slots missed after a sample are late samples; after an idle tick, only Pause.
        missed = self._missed if self._sampled_last and self.backend is not self.sim else 0
        self._sampled_last = False
        try:
            self.log.check()  # a write the file worker failed (disk full): fault now
            if self._unsafe:
                self._retry_safe()
            if self.calibration.active:
                self._calibration_tick()
            elif self.running:
                self._sample(missed)
                self._sampled_last = True
            elif not self._unsafe or self.backend is not self.daq:
                self._y = self.backend.read_levels()  # a paused rig still shows its levels
        except Exception as exc:  # noqa: BLE001 - any fault: pumps safe, Pause, say why
            self._fail(exc)
            self.calibration.fail(f"stopped: {self.fault}")
        if self._unsafe:
            self._unsafe = unconfirmed_stop(self.daq)  # a write of the pumps that went through clears it
        self._snapshot = None

    def _retry_safe(self) -> None:
        """The rig's pumps not confirmed at 0: try again, unless the loop drives them
        now (Run, or a calibration holding them, whose writes settle it)."""
        if self.backend is not self.daq or not (self.running or self.calibration.active):
            self._safe(self.daq)

    def _calibration_tick(self) -> None:
        """One sample of the calibration (engine/calibration_step.py): the pumps held,
        the raw sensors read while settling; pumps at 0 when it stops holding them."""
        self._u, self._y, holding = self.calibration.tick(self.backend, self.params.process_plant())
        if not holding:
            self._safe(self.backend)  # timed out: pumps at 0
            self._u = (0.0, 0.0)

    def _sample(self, missed: int = 0) -> None:
        """One sample; `missed` sampling slots of a real process went by since the last.

        Every sample of a run comes here (x1000 at 50 ms leaves 50 us for all of it):
        what it reads more than once is read once, into locals."""
        if missed:
            self._skip(missed)
        backend, gens, log, t = self.backend, self._gens, self.log, self.t
        h = self.params.tsamp
        y = self._y = backend.read_levels()
        y12 = (y[0], y[1])
        w = (gens[0].value(), gens[1].value())
        controllers = self.controllers
        m, sf = controllers.matrix, controllers.whole  # sf: state feedback or MPC
        if self.params.control.mode is _AUTOMATIC:
            r = w
            if (mpc := controllers.mpc) is not None and mpc.wants_preview:
                mpc.preview(gens)  # the references over its horizon (waves are known ahead)
            u = self._write(saturate(sf.compute(r, y) if sf is not None else m.compute(r, y12)))
            if sf is not None:
                sf.update(r, y, u)
                m.track(r, y12, u)
            else:
                m.update(r, y12, u)
        else:
            r = y12
            u = self._write(saturate(w))
            m.track(r, y12, u)
            if sf is not None:
                sf.track(y, u)
        self._u, self._w, self._r = u, w, r
        if log.running:
            if missed:
                log.late((missed + 1) * h, h)
            log.row(t, y, u, r)
        self.history.append((t, y[0], y[1], y[2], y[3], u[0], u[1], r[0], r[1]))
        backend.elapse(h)
        gens[0].advance()
        gens[1].advance()
        self.k = k = self.k + 1
        self.t = k * h if self._fixed_h else t + h

    def _write(self, u: Pair) -> Pair:
        """Write `u` to the pumps; the inputs really written, which the log, the
        trends and the controllers see (an interlock may have held some at 0: the
        record counts it and the log says when a trip begins and ends)."""
        backend = self.backend
        backend.write_pumps(u)
        written = backend.written(u)
        began, released = self.interlock.note(self.t, backend.interlock_holds())
        for hold in began:
            self.log.comment(self.t, hold.alarm)
        for tank in released:
            self.log.comment(self.t, f"interlock: tank {tank} released, its pumps follow the controller again")
        return written

    def _skip(self, missed: int) -> None:
        """A real process does not wait for a late loop: the `missed` sampling slots
        went by, so process time and the generators move on over them (t stays true,
        and the log notes the late row), rather than the samples closing up."""
        self.k += missed
        self.t = self.k * self.h if self._fixed_h else self.t + missed * self.h
        for _ in range(missed):
            self._gens[0].advance()
            self._gens[1].advance()

    def _fail(self, exc: BaseException) -> None:
        reason = str(exc) if isinstance(exc, BackendError) else f"{type(exc).__name__}: {exc}"
        self.fault = f"{self.backend.description or self.backend.kind}: {reason}"
        was_running, self.running = self.running, False
        self._safe(self.backend)
        if was_running and self.log.running:  # the log says why its rows stop here
            self.log.comment(self.t, f"paused, pumps at 0: {self.fault}")

    def _safe(self, backend: ProcessBackend | None) -> None:
        """Pumps to 0; whether the rig confirmed it is noted (`_unsafe`)."""
        if backend is None:
            return
        try:
            backend.safe_state()
        except Exception:  # noqa: BLE001 - safe_state must not raise; if it does, go on
            pass
        self._unsafe = unconfirmed_stop(self.daq)

    @property
    def pumps_unconfirmed(self) -> str:
        """"pumps NOT confirmed at 0 (...): why" while the rig's last zeroing was not
        confirmed (after shut_down: its last), else ""."""
        return self._unsafe

    def _make_snapshot(self) -> Snapshot:
        return Snapshot(
            t=self.t, k=self.k, y=self._y, u=self._u, w=self._w, r=self._r,
            operation=self.backend.kind, state=self.state, control=self.control.value,
            params=self.params, speed=self.speed, realtime=self.realtime,
            active_available=self.daq is not None,
            backend=self.backend.description or self.backend.kind,
            log=self.log.status(self.params.logging),
            stats=self.stats, fault=self._fault_shown(),
            statefb=sf.info if (sf := self.controllers.statefb) is not None else None,
            mpc=mpc.info if (mpc := self.controllers.mpc) is not None else None,
            calibration=self.calibration.status(),
            alarms=tuple(getattr(self.backend, "alarms", ()) or ()),
            faults=self.sim.faults.labels() if self.backend is self.sim else "",
            disturbances=self._disturbances(),
            automatic_since=self.automatic_since,
        )

    def _disturbances(self) -> tuple[float, float] | None:
        """The disturbance pumps' duties of the process in use (None: it has none)."""
        if self.backend is self.sim and self.sim.plant.kind != "quadtank":
            return None
        duties = getattr(self.backend, "disturbances", None)
        return None if duties is None else (float(duties[0]), float(duties[1]))

    def _fault_shown(self) -> str | None:
        """The fault, and the rig's pumps not confirmed at 0 after it (or alone: a Pause's zeroing)."""
        if not self._unsafe:
            return self.fault
        if self.fault:
            return f"{self.fault}; {self._unsafe}"
        return f"{self.daq.description or self.daq.kind}: {self._unsafe}" if self.daq is not None else self._unsafe

    def publish(self) -> Snapshot:
        """Publish a fresh snapshot of the current state (after a stop, say)."""
        self._snapshot = None
        return self.snapshot()

    def _stale(self) -> None:
        """The state changed: the next :meth:`snapshot` is built afresh."""
        self._snapshot = None

    @property
    def missed(self) -> int:
        """Sampling slots the driver's clock skipped before the last sample (it came
        late); a real process's loop time passes over them (Engine.run_for)."""
        return self._missed

    def record_timing(self, jitter: float, missed: int, wall: float) -> None:
        """The runner's measurement of the sample about to be done (LoopStats); the
        sample's snapshot carries it."""
        self._missed = missed
        self._timing.add(jitter, missed, wall)
        self._stats = None
        self._snapshot = None

    def timed_sample(self, jitter: float, missed: int, wall: float) -> None:
        """:meth:`record_timing` then :meth:`sample`: the driver's every sample, in one call."""
        self.record_timing(jitter, missed, wall)
        self.sample()

    def follow_sampling_time(self, listener: Callable[[float], None]) -> None:
        """`listener(h)` is told each new sampling time as the parameters take it
        (the engine's clock: the parameters own the sampling time, the clock follows)."""
        self.on_sampling_time = listener

    def set_clock_info(self, realtime: bool, speed: float) -> None:
        self.realtime, self.speed = realtime, speed
        self._snapshot = None

    # --- the driver's hooks: the only ways the outside changes the loop but commands ---------

    def halt(self, reason: str) -> None:
        """The driver itself failed: Pause, pumps safe, and `reason` shown as the fault."""
        self.fault = reason
        self.running = False
        self._safe(self.backend)
        self.publish()

    def shut_down(self) -> None:
        """The end of the run: Pause, both processes' pumps at 0, logging stopped (an
        unsaved log stays as the partial file), a last snapshot, backends closed."""
        self.running = False
        backends = [b for b in (self.sim, self.daq) if b is not None]
        for backend in backends:
            self._safe(backend)
        self.close_log()
        self.files.close()  # the rows still queued reach the file first
        self.publish()
        for backend in backends:
            try:
                backend.close()
            except Exception:  # noqa: BLE001 - closing a dead link must not hide the stop
                pass

    # --- commands -----------------------------------------------------------------------

    def apply(self, command: Command | InstallPar) -> CommandResult:
        """Apply one command between samples; a refusal changes nothing.  Waits for
        the command's file operations (see :meth:`begin`)."""
        return self.begin(command).result()

    def begin(self, command: Command | InstallPar) -> Future[CommandResult]:
        """Apply one command between samples, as :meth:`apply`, but leave its file
        operations (LogOn, LogSave, SavePar, ...) to the file worker: the loop's
        state changes now, the Future resolves when the disk is done.  With the
        file thread on (:meth:`use_file_thread`) a slow disk never delays a sample."""
        handler = _HANDLERS.get(type(command))
        if handler is None:
            return resolved(CommandResult.refused(f"unknown command {type(command).__name__}"))
        try:
            result = handler(self, command)
        except Exception as exc:
            refused = refusal(exc)
            if refused is None:
                raise
            return resolved(refused)
        self._stale()
        return result if isinstance(result, Future) else resolved(result)

    def use_file_thread(self) -> None:
        """Run the file operations (log rows, saves) on a writer thread from now on,
        off the sampling path: what a real-time driver calls before sampling."""
        self.files.start_thread()

    def finish_writes(self, timeout: float | None = None) -> None:
        """Wait for the file operations handed out so far; one that failed (disk full)
        faults the run now, as the next sample would have."""
        self.files.drain(timeout)
        try:
            self.log.check()
        except Exception as exc:  # noqa: BLE001 - the same path as a sample's fault
            self._fail(exc)
            self.publish()

    def _set_params(self, cmd: SetParams) -> CommandResult:
        values = check_names(cmd.values)  # file and screen names are the files layer's to check
        mode = values.pop(MODE_KEY, None)
        plant_values = {k: values.pop(k) for k in list(values) if k.startswith(PLANT_PREFIX)}
        new = self.params.with_values(values)
        if plant_values:  # "PLANT.alpha1": the plant in use (core.plants.spec), all or none too
            if new.process is None:
                key = next(iter(plant_values))
                raise ParameterError(key, "the quadruple tank's values are set in SIMULATION (its Tank windows)")
            new = replace(new, process=new.process.with_values(plant_values))
        if mode is not None:
            target = self.params.with_value(MODE_KEY, mode).control.mode  # validates
        self._install(new)
        if mode is not None:
            self._switch_mode(target, adjust_means=not any(k in values for k in MEAN_KEYS))
        return CommandResult(True)

    def _install(self, new: Parameters) -> None:
        """Make `new` the parameters in force, all or nothing.

        Everything that can still refuse (a General pole at 2/h, a plant the
        physics rejects, a sampling time change while logging) is checked before
        anything moves.
        """
        old = self.params
        new = new.with_value(MODE_KEY, old.control.mode.value)
        h = new.tsamp
        if h != old.tsamp and self.log.running:
            raise ParameterError(TSAMP, "stop logging (LogOff) before changing the sampling time: "
                                 "the log's TSamp would no longer be true")
        self.controllers.check(new)
        changed = new.simulation != old.simulation or new.process != old.process
        plant = new.process_plant() if changed else None
        refused = plant_refused(self.daq, plant) if plant is not None else None
        if refused is not None:
            raise ParameterError("PLANT.Kind", refused)
        change = self.controllers.prepare(new, old)
        # --- nothing below refuses ---
        if h != old.tsamp:
            self._fixed_h = False
        for g, a, b in zip(self._gens, old.references, new.references):
            # Each step must be valid on its own: the period is checked against the
            # sampling time in force, so a longer h takes the new period first.
            if h >= old.tsamp and a != b:
                g.set_params(b)
            if h != old.tsamp:
                g.set_sampling_time(h)
            if h < old.tsamp and a != b:
                g.set_params(b)
        self.controllers.install(new, old, change, self._y, self._u, self.control is ControlMode.AUTOMATIC)
        if plant is not None:
            self.sim.set_plant(plant, new.process_levels())
        self.params = new
        if h != old.tsamp:
            if self.on_sampling_time is not None:
                self.on_sampling_time(h)  # the clock's schedule
            if self.backend is not self.sim:
                arm(self.backend, h)  # the rig's watchdog timeout follows the sampling time

    def _switch_mode(self, mode: ControlMode, *, adjust_means: bool = True) -> None:
        """Manual <-> Automatic, bumpless (M3): Manual -> Automatic sets the reference
        means to the measured y1, y2; Automatic -> Manual sets the input means to the
        applied u1, u2.  The controllers have tracked u in Manual, so nothing jumps."""
        if mode is self.control:
            return
        if adjust_means:
            src = (self._y[0], self._y[1]) if mode is ControlMode.AUTOMATIC else self._u
            for g, m in zip(self._gens, src):
                g.set_mean(m)
            self.params = self.params.with_values({MEAN_KEYS[0]: self._gens[0].mean,
                                                   MEAN_KEYS[1]: self._gens[1].mean})
        self.params = self.params.with_value(MODE_KEY, mode.value)
        self.automatic_since = self.t if mode is ControlMode.AUTOMATIC else None

    def _set_control_mode(self, cmd: SetControlMode) -> CommandResult:
        return self._set_params(SetParams({MODE_KEY: cmd.mode}))

    def _set_defaults(self, cmd: SetDefaults) -> CommandResult:
        keys = tuple(k for k in cmd.keys if k != MODE_KEY)
        return self._set_params(SetParams({k: self.defaults.get(k) for k in keys}))

    def _set_state(self, cmd: SetState) -> CommandResult:
        if self.calibration.active and cmd.state == "Run":
            return CommandResult.refused("a calibration is holding the pumps: finish or cancel it first")
        if cmd.state == "Run":
            self.running = True
            self.fault = None
        elif cmd.state == "Pause":
            self.running = False
            if self.backend is not self.sim:
                self._safe(self.backend)  # a real process: pumps to 0
        elif cmd.state == "Reset":
            self.reset()
        else:
            return CommandResult.refused(f"state must be Run, Pause or Reset, got {cmd.state!r}")
        return CommandResult(True)

    def reset(self) -> None:
        """Reset (M2): every state cleared, the simulation at its operating point,
        then Pause.  A log being taken stops (its rows are kept until Save)."""
        self.running = False
        self._cancel_calibration(CancelCalibration())
        self._safe(self.backend)
        self.controllers.reset()
        for g in self._gens:
            g.reset()
        self.sim.reset()
        self.log.stop()
        self.history.clear()
        self.k, self.t, self._fixed_h = 0, 0.0, True
        if self.automatic_since is not None:
            self.automatic_since = 0.0
        self.fault = None
        self._y = self.backend.read_levels() if self.backend is self.sim else self._y
        self._u = (0.0, 0.0)
        self._w = (self._gens[0].value(), self._gens[1].value())
        self._r = (self._y[0], self._y[1])

    def _set_operation(self, cmd: SetOperation) -> CommandResult:
        if cmd.operation == "Simul":
            target: ProcessBackend = self.sim
        elif cmd.operation == "Active":
            if self.daq is None:
                return CommandResult.refused("Active needs a DAQ backend; none is configured")
            target = self.daq
            if target is not self.backend:
                why = identity_refused(target)  # a rig that is not this DAQ file's: never drive it
                if why:
                    return CommandResult.refused(why)
        else:
            return CommandResult.refused(f"operation must be Simul or Active, got {cmd.operation!r}")
        if target is not self.backend:
            self.calibration.forget()  # a calibration belongs to the rig it ran on
            self._safe(self.backend)
            self.running = False
            self.backend = target
            self.fault = None
            if target is not self.sim:
                arm(target, self.h)
        return CommandResult(True)

    def _nudge(self, cmd: NudgeMean) -> CommandResult:
        if cmd.channel not in (1, 2):
            return CommandResult.refused(f"channel must be 1 or 2, got {cmd.channel!r}")
        g = self._gens[cmd.channel - 1]
        g.nudge(cmd.delta)
        self.params = self.params.with_value(MEAN_KEYS[cmd.channel - 1], g.target)
        return CommandResult(True)

    def _add_water(self, cmd: AddWater) -> CommandResult:
        if self.backend is not self.sim:
            return CommandResult.refused("water can be added to the simulation only (Simul)")
        if cmd.tank not in (1, 2, 3, 4):
            return CommandResult.refused(f"tank must be 1..4, got {cmd.tank!r}")
        if not isinstance(cmd.amount, (int, float)) or not math.isfinite(cmd.amount):
            return CommandResult.refused(f"amount must be a number, got {cmd.amount!r}")
        self.sim.add_water(cmd.tank, float(cmd.amount))
        if not self.running:
            self._y = self.sim.read_levels()
        return CommandResult(True)

    def _set_fault(self, cmd: SetFault) -> CommandResult:
        """A fault on or off in the simulation (core.faults); the log gets a `%` line."""
        if self.backend is not self.sim:
            return CommandResult.refused("faults act on the simulation only (Simul)")
        if cmd.on:
            try:
                began = self.sim.set_fault(Fault(cmd.kind, cmd.target, cmd.value))
            except PlantError as exc:
                return CommandResult.refused(str(exc))
            text = f"fault on: {began.label()}"
        else:
            if not self.sim.clear_fault(cmd.kind, cmd.target):
                return CommandResult.refused(f"no {cmd.kind} fault on {cmd.target} to switch off")
            text = f"fault off: {cmd.kind.replace('_', ' ')} {cmd.target}"
        self.log.comment(self.t, text)
        if not self.running:
            self._y = self.sim.read_levels()
        return CommandResult(True)

    def _set_disturbance(self, cmd: SetDisturbance) -> CommandResult:
        """The disturbance pumps of the process in use (an IST rig's in Active, the
        simulated inflow in Simul); the log gets a `%` line.  Refused by a process
        without them (a Modbus rig, a plant other than the quadruple tank)."""
        drive = getattr(self.backend, "set_disturbances", None)
        if drive is None:
            return CommandResult.refused(f"{self.backend.description or self.backend.kind} has no disturbance "
                                         "pumps (an IST rig has two; in Simul, the quadruple tank)")
        drive(cmd.d1, cmd.d2)  # ValueError: refused, nothing changed
        d = self.backend.disturbances  # type: ignore[attr-defined]  # every backend with the setter has them
        self.log.comment(self.t, f"disturbance: d1 {100 * d[0]:.1f} %, d2 {100 * d[1]:.1f} % of full PWM")
        return CommandResult(True)

    def _reset_controllers(self, cmd: ResetControllers) -> CommandResult:
        self.controllers.reset(cmd.element)
        return CommandResult(True)

    # --- logging --------------------------------------------------------------------------

    def _log_on(self, cmd: LogOn) -> Future[CommandResult]:
        return then(self.log.on(self.params.logging, self.h, self.t, cmd.points),
                     lambda warnings: CommandResult(True, warnings=warnings))

    def _log_off(self, cmd: LogOff) -> Future[CommandResult]:
        return then(self.log.off(), lambda _: CommandResult(True))

    def _log_save(self, cmd: LogSave) -> Future[CommandResult]:
        return then(self.log.save_later(cmd.name or self.params.logging.log_file, cmd.overwrite),
                     lambda saved: CommandResult(True, f"saved {saved}"))

    def _log_discard(self, cmd: LogDiscard) -> Future[CommandResult]:
        return then(self.log.discard(), lambda _: CommandResult(True))

    def close_log(self) -> None:
        """Exit: stop logging; an unsaved log stays on disk as the partial file
        (one without rows is removed)."""
        self.log.close()

    # --- parameter files --------------------------------------------------------------------

    def _load_par(self, cmd: LoadPar) -> CommandResult:
        """The file read here, on the loop's thread: only where nothing samples
        meanwhile (a manual or headless engine); a running engine or a session reads
        it on a thread of its own (engine/parload.py) and hands over InstallPar."""
        prepared = prepare_load(self.store, cmd)
        return prepared if isinstance(prepared, CommandResult) else self._install_par(prepared)

    def _install_par(self, cmd: InstallPar) -> CommandResult:
        """Every setting of the file, except what would make the loop jump: in
        Automatic the references keep the means in force (bumpless, as M3's switches
        are).  A file's means are the inputs of its setting when it was saved in
        Manual (nonminphase.par: 0.315), never levels to steer to: taken as
        references they drained tanks at 0.63 to 0.38 within seconds.  The loop
        stays in its mode (the file's Mode is not applied either: _install)."""
        new, note = cmd.params, ""
        if self.control is ControlMode.AUTOMATIC:
            kept = tuple(self.params.get(k) for k in MEAN_KEYS)
            filed = tuple(new.get(k) for k in MEAN_KEYS)
            new = new.with_values(dict(zip(MEAN_KEYS, kept)))
            note = f"; Automatic: references kept at {kept[0]:.3f}, {kept[1]:.3f}" + (
                f" (the file's means {filed[0]:.3f}, {filed[1]:.3f} not applied)" if filed != kept else "")
        self._install(new)
        return CommandResult(True, f"loaded {cmd.name}{note}", warnings=cmd.warnings)

    def _save_par(self, cmd: SavePar) -> Future[CommandResult]:
        """The parameters in force now, written by the file worker."""
        store, params = self.store, self.params

        def save() -> CommandResult:
            if cmd.defaults:
                return CommandResult(True, f"saved {store.save_default(params)}")
            # A reserved name skips the "exists" question: store.save refuses it with the reason.
            if store.exists(cmd.name) and not cmd.overwrite and cmd.name.lower() not in RESERVED:
                return CommandResult.refused(f"{store.path_of(cmd.name)} exists (save again to overwrite)")
            return CommandResult(True, f"saved {store.save(cmd.name, params)}")

        return then(self.files.submit(save), lambda result: result)

    # --- calibration on the rig (Desautel 2.3) ---------------------------------------------

    def _start_calibration(self, cmd: StartCalibration) -> CommandResult:
        """Pause the control loop and start holding the pumps (refused in Simul: the
        simulation's sensors need no calibration, and a rig without raw reads)."""
        if self.backend is self.sim:
            return CommandResult.refused("calibration runs on the rig: switch to Active first "
                                         "(the simulation's sensors are exact)")
        result = self.calibration.start(self.backend, cmd, self.params.process_plant(), self.h, self.store.folder)
        if result.ok:
            self.running = False
        return result

    def _calibration_heights(self, cmd: CalibrationHeights) -> CommandResult:
        result = self.calibration.heights(cmd)
        if result.ok and not self.calibration.active:  # done: pumps at 0
            self._safe(self.backend)
            self._u = (0.0, 0.0)
        return result

    def _cancel_calibration(self, cmd: CancelCalibration) -> CommandResult:
        """Pumps at 0 while it runs; afterwards, forget it (the window closed)."""
        if self.calibration.cancel():
            self._safe(self.backend)
            self._u = (0.0, 0.0)
        return CommandResult(True)

    def _set_speed(self, cmd: SetSpeed) -> CommandResult:
        return CommandResult.refused("the speed belongs to the engine's clock, not the loop")

    def set_initial_mode(self, mode: ControlMode) -> None:
        """Start in `mode` with the references as the parameters give them (a headless
        run of a `.par` saved in Automatic), not the bumpless adjustment."""
        self._switch_mode(mode, adjust_means=False)

    def place_at_steady_state(self, levels_cm: Any) -> None:
        """Put the simulated water at `levels_cm` (a steady state to start from)."""
        self.sim.set_levels(levels_cm)
        self._y = self.sim.read_levels()
        self._r = (self._y[0], self._y[1])
        self._stale()


_HANDLERS: Mapping[type, Callable[[ControlLoop, Any], CommandResult | Future[CommandResult]]] = {
    SetParams: ControlLoop._set_params, SetDefaults: ControlLoop._set_defaults,
    SetOperation: ControlLoop._set_operation, SetState: ControlLoop._set_state,
    SetControlMode: ControlLoop._set_control_mode, NudgeMean: ControlLoop._nudge,
    AddWater: ControlLoop._add_water, SetFault: ControlLoop._set_fault,
    SetDisturbance: ControlLoop._set_disturbance,
    ResetControllers: ControlLoop._reset_controllers,
    LogOn: ControlLoop._log_on, LogOff: ControlLoop._log_off, LogSave: ControlLoop._log_save,
    LogDiscard: ControlLoop._log_discard, LoadPar: ControlLoop._load_par, InstallPar: ControlLoop._install_par,
    SavePar: ControlLoop._save_par, SetSpeed: ControlLoop._set_speed,
    StartCalibration: ControlLoop._start_calibration, CalibrationHeights: ControlLoop._calibration_heights,
    CancelCalibration: ControlLoop._cancel_calibration,
}
