"""The engine: a ControlLoop, its clock, and the one door commands come in by.

Nothing here paces: the one driver (engine/driver.py) waits for each deadline and
calls :meth:`Engine.sample`.  A session's host drives the engine on its asyncio
event loop and applies the clients' commands between samples
(:meth:`Engine.submit`, applied at once on the driver's thread); the runs without
clients drive it inline (:meth:`Engine.run_for`, :meth:`Engine.step`).  The engine
has no thread of its own.
"""

from __future__ import annotations

import os
import threading
import time
from concurrent.futures import Future
from dataclasses import dataclass
from datetime import datetime, timedelta, timezone
from pathlib import Path
from typing import TYPE_CHECKING, Callable, Literal, Mapping

import numpy as np

from quadtank_tui.core.parameters import Parameters, REFERENCE_SECTIONS
from quadtank_tui.engine.backend import ProcessBackend
from quadtank_tui.engine.clock import Clock, ManualClock, RealTimeClock, VirtualClock
from quadtank_tui.engine.commands import Command, CommandResult, InstallPar, SetParams, SetSpeed
from quadtank_tui.engine.controllers import preload_designs
from quadtank_tui.engine.design_ahead import needs_mpc_design
from quadtank_tui.engine.driver import Driver, LoopTime
from quadtank_tui.engine.history import DEFAULT_CAPACITY, check_capacity
from quadtank_tui.engine.loop import ControlLoop
from quadtank_tui.engine.snapshot import Snapshot
from quadtank_tui.files.log_writer import log_path
from quadtank_tui.files.par import ParRead, ParStore, read_par

if TYPE_CHECKING:
    from quadtank_tui.engine.mpc_control import LoopMPC

ClockKind = Literal["realtime", "virtual", "manual"]

class Engine:
    """Implements :class:`quadtank_tui.engine.handle.EngineHandle`."""

    def __init__(
        self,
        loop: ControlLoop,
        clock: Clock,
        *,
        sleep: Callable[[float], None] = time.sleep,
        warnings: tuple[str, ...] = (),
    ) -> None:
        self.loop = loop
        self.clock = clock
        self.warnings = warnings
        #: How the driver waits for a deadline of an injected time source (a
        #: ManualClock's sleep moves that time on).
        self.sleep = sleep
        self._lock = threading.Lock()  # one sample or one command at a time
        self._stopped = False
        loop.set_clock_info(clock.realtime, clock.speed)
        loop.follow_sampling_time(clock.set_period)  # the parameters own the sampling time; the clock follows
        if clock.realtime:  # a rig's time, stepped by hand or not: no sample waits for the disk
            loop.use_file_thread()

    # --- the EngineHandle read side -------------------------------------------------------

    def snapshot(self) -> Snapshot:
        return self.loop.snapshot()

    def history(self, seconds: float | None = None) -> Mapping[str, np.ndarray]:
        return self.loop.history.last(seconds)

    def defaults(self) -> Parameters:
        return self.loop.defaults

    def par_names(self) -> list[str]:
        return self.loop.store.names()

    def log_exists(self, name: str) -> bool:
        return log_path(self.loop.logs_dir, name).exists()

    @property
    def logs_dir(self) -> Path:
        """The folder logs are saved in (the ghost run's window lists it)."""
        return Path(self.loop.logs_dir)

    @property
    def missed(self) -> int:
        """Sampling slots the clock skipped before the last sample (the loop's own
        count, :attr:`ControlLoop.missed`)."""
        return self.loop.missed

    @property
    def params(self) -> Parameters:
        """The parameters in force."""
        return self.loop.params

    @property
    def par_store(self) -> ParStore:
        """The folder of `.par` files a LoadPar names one of."""
        return self.loop.store

    @property
    def history_capacity(self) -> int:
        """Rows the trend history keeps."""
        return self.loop.history.capacity

    def history_since(self, index: int) -> tuple[np.ndarray, int, int]:
        """(rows with absolute index >= `index` still kept, rows ever written, clear
        generation): what a session sends its clients after each publication (the
        driver's thread only)."""
        return self.loop.history.since(index)

    @property
    def pumps_unconfirmed(self) -> str:
        """Why the rig's pumps are NOT confirmed at 0 since its last zeroing, else ""."""
        return self.loop.pumps_unconfirmed

    @property
    def interlock_acted(self) -> bool:
        """The rig's interlock held a pump at 0 at some time of the run."""
        return self.loop.interlock.acted

    @property
    def automatic_since(self) -> float | None:
        """Loop time the last switch to Automatic took effect (None: not in Automatic)."""
        return self.loop.automatic_since

    @property
    def log_failed(self) -> str | None:
        """Why the log stopped taking rows (a full disk, a lost folder), else None."""
        return self.loop.log.failed

    @property
    def log_started_at(self) -> float:
        """Loop time of the last LogOn: the log's `t` column counts from it."""
        return self.loop.log.started_at

    def mpc_design_needed(self, command: SetParams) -> Parameters | None:
        """The parameters `command` makes when they need an MPC the loop has not
        designed yet (it is designed off the loop's thread, :meth:`offer_mpc`), else None."""
        return needs_mpc_design(self.loop, command)

    def offer_mpc(self, inputs: tuple[object, ...], mpc: LoopMPC) -> None:
        """An MPC designed off the loop's thread for the design inputs `inputs`: the
        next command that needs it takes it instead of designing it again."""
        self.loop.controllers.offer(inputs, mpc)

    @property
    def wall_paced(self) -> bool:
        """The clock's deadlines are on the wall's monotonic clock (not an injected
        time source): the driver waits for them for real."""
        return self.sleep is time.sleep and self.clock.now is time.monotonic

    # --- the one write door ------------------------------------------------------------

    def submit(self, command: Command | InstallPar) -> Future[CommandResult]:
        """Apply `command` now, between two samples (a session's host calls this on
        its driver's thread); the Future resolves when its file operations are done."""
        if self._stopped:
            fut: Future[CommandResult] = Future()
            fut.set_result(CommandResult.refused("the engine has stopped"))
            return fut
        with self._lock:
            return self._begin(command)

    def _begin(self, command: Command | InstallPar) -> Future[CommandResult]:
        """Apply `command` to the loop (its file operations may still run: the
        Future resolves when they are done)."""
        if isinstance(command, SetSpeed):
            done: Future[CommandResult] = Future()
            done.set_result(self._set_speed(command.factor))
            return done
        return self.loop.begin(command)

    def _set_speed(self, factor: float) -> CommandResult:
        if not isinstance(self.clock, VirtualClock):
            return CommandResult.refused("the speed can be changed only with a virtual clock (Simul)")
        try:
            self.clock.set_speed(factor)
        except ValueError as exc:
            return CommandResult.refused(str(exc))
        self.loop.set_clock_info(self.clock.realtime, self.clock.speed)
        return CommandResult(True)

    # --- samples ------------------------------------------------------------------------------

    def sample(self) -> int:
        """Take one sample now (the driver calls this at its deadline); returns the
        sampling slots it stands for: 1, and on a real process the ones the clock
        skipped before it (a simulator's time waits for the loop)."""
        with self._lock:
            scheduled, actual, missed = self.clock.tick_values()
            loop = self.loop
            loop.timed_sample(actual - scheduled, missed, actual)
            return 1 + loop.missed if loop.backend is not loop.sim else 1

    @property
    def sampling_time(self) -> float:
        """The sampling time in force, s."""
        return self.loop.h

    def hold_files(self, hold: bool) -> None:
        """Hold the log rows for batches (True) or let them go (engine/filework.py)."""
        self.loop.files.hold(hold)

    def use_file_thread(self) -> None:
        """The log rows go to a file thread from now on: no sample waits for the disk."""
        self.loop.use_file_thread()

    def flush_files(self) -> None:
        """The log rows held for the file thread go to it now (the driver calls this
        before it waits: a row is never held while nothing samples)."""
        with self._lock:
            self.loop.files.flush()

    def step(self, n: int = 1) -> Snapshot:
        """Do `n` samples, each at its deadline (the driver, inline)."""
        Driver(self, samples=n).run()
        return self.loop.snapshot()

    def run_for(self, seconds: float, before: Callable[[LoopTime], None] | None = None) -> int:
        """Sample for `seconds` of loop time (sum of the sampling periods, paused or
        not); returns the number of samples.  `before(elapsed)` runs ahead of each
        sample (a script applies its due events there).  On a real process the
        periods the loop missed count too (engine/driver.py)."""
        return Driver(self, duration=seconds, before=before).run()

    def stop(self) -> None:
        """Stop the loop, pumps to 0, logging stopped (rows kept), backends closed.
        Idempotent; the driver must be over (a session's host stops it first)."""
        if self._stopped:
            return
        self._stopped = True
        with self._lock:
            self.loop.shut_down()

    def __enter__(self) -> Engine:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()


# --- the factory the CLI, the TUI and the tests use -----------------------------------------

#: "Created on:" origin of virtual-clock headless runs, so a run's `.log` is the same
#: bytes every time; SOURCE_DATE_EPOCH (reproducible-builds convention) overrides it.
VIRTUAL_EPOCH = datetime(2000, 1, 1, 0, 0, 0)


def virtual_epoch() -> datetime:
    value = os.environ.get("SOURCE_DATE_EPOCH")
    if value and value.isdigit():
        return datetime.fromtimestamp(int(value), tz=timezone.utc).replace(tzinfo=None)
    return VIRTUAL_EPOCH


def load_parameters(par: str | Path | None, store: ParStore,
                    defaults: ParRead | None = None) -> tuple[Parameters, tuple[str, ...]]:
    """The defaults file, or `par`: a path to a `.par` file, else a name in the store.

    Missing values of a file take the defaults (`defaults`: the store's, already
    read).  Errors are ParFileError naming file, line and key."""
    if defaults is None:
        defaults = store.defaults()
    if par is None:
        return defaults.params, tuple(defaults.warnings)
    path = Path(par)
    if path.suffix.lower() == ".par" or path.exists() or len(path.parts) > 1:
        read = read_par(path, base=defaults.params)
        return read.params, tuple(defaults.warnings) + tuple(read.warnings)
    read = store.load(str(par), defaults)  # its warnings already hold the defaults'
    return read.params, tuple(read.warnings)


def with_seed(params: Parameters, seed: int) -> Parameters:
    """Both PRBS generators seeded from one number (channel 2 gets seed + 1)."""
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise ValueError(f"seed must be a whole number >= 0, got {seed!r}")
    return params.with_values({f"{sec}.Seed": (seed + i) % 2**31 for i, sec in enumerate(REFERENCE_SECTIONS)})


@dataclass(frozen=True)
class EngineSpec:
    """What an engine is built from, as plain values: files already read and checked.

    A session process builds its engine from the copy its launcher sends, so a bad
    file is refused in the program the user started, with the same message.
    """

    params: Parameters
    defaults: Parameters
    warnings: tuple[str, ...]
    params_dir: Path
    logs_dir: Path
    clock: ClockKind = "realtime"
    speed: float | None = 1.0
    history_capacity: int = DEFAULT_CAPACITY
    epoch: datetime | None = None


def engine_spec(
    par: str | Path | None = None,
    *,
    clock: ClockKind = "realtime",
    speed: float | None = 1.0,
    seed: int | None = None,
    params_dir: Path | str = Path("params"),
    logs_dir: Path | str = Path("logs"),
    history_capacity: int = DEFAULT_CAPACITY,
    epoch: datetime | None = None,
) -> EngineSpec:
    """Read and check the parameter files (ParFileError names file, line and key)."""
    if clock not in ("realtime", "virtual", "manual"):
        raise ValueError(f"clock must be realtime, virtual or manual, got {clock!r}")
    check_capacity(history_capacity)
    store = ParStore(params_dir)
    defaults = store.defaults()
    params, warnings = load_parameters(par, store, defaults)
    if seed is not None:
        params = with_seed(params, seed)
    return EngineSpec(params, defaults.params, warnings, Path(params_dir), Path(logs_dir),
                      clock, speed, history_capacity, epoch)


def assemble(
    spec: EngineSpec,
    *,
    daq: ProcessBackend | None = None,
    now: Callable[[], float] | None = None,
    sleep: Callable[[float], None] | None = None,
) -> Engine:
    """The engine `spec` describes, in the start-up state (Simul, Pause, Manual)."""
    if spec.clock == "manual" and now is None and sleep is None:
        fake = ManualClock()
        now, sleep = fake.now, fake.sleep
    now = now or time.monotonic
    sleep = sleep or time.sleep
    h = spec.params.tsamp
    # "Created on:" is the wall clock at LogOn (a TUI run, at any speed), unless an
    # epoch is given: then epoch + process time, so a headless run is reproducible.
    stamp: Callable[[], datetime] = lambda: datetime.now().replace(microsecond=0)  # noqa: E731
    if spec.clock == "realtime":
        clk: Clock = RealTimeClock(h, now)
    else:
        clk = VirtualClock(h, None if spec.clock == "manual" else spec.speed, now)
        if spec.epoch is not None:
            origin = spec.epoch
            stamp = lambda: origin + timedelta(seconds=round(control.t, 6))  # noqa: E731
    if daq is not None:  # on a rig, a first design must not stall the samples (controllers.py)
        preload_designs()
    control = ControlLoop(spec.params, defaults=spec.defaults, store=ParStore(spec.params_dir),
                          logs_dir=spec.logs_dir, daq=daq, history_capacity=spec.history_capacity,
                          now=lambda: stamp())
    return Engine(control, clk, sleep=sleep, warnings=spec.warnings)


def build_engine(
    par: str | Path | None = None,
    *,
    daq: ProcessBackend | None = None,
    clock: ClockKind = "realtime",
    speed: float | None = 1.0,
    seed: int | None = None,
    params_dir: Path | str = Path("params"),
    logs_dir: Path | str = Path("logs"),
    history_capacity: int = DEFAULT_CAPACITY,
    epoch: datetime | None = None,
    now: Callable[[], float] | None = None,
    sleep: Callable[[float], None] | None = None,
) -> Engine:
    """An engine in the start-up state (Simul, Pause, Manual); a driver runs it.

    clock : "realtime" (absolute deadlines), "virtual" (`speed` 1..1000, None = as
        fast as possible) or "manual" (no thread, unpaced: step it by hand)
    epoch : with a virtual or manual clock the logs are stamped epoch + process
        time, so a fixed epoch makes the `.log` reproducible (default: none, the
        wall clock at LogOn, as a user at the TUI expects)
    now, sleep : the monotonic time source and the wait (default: time.monotonic and
        time.sleep; for "manual", a fresh ManualClock, so even a SetSpeed-paced
        manual engine never really waits and its snapshots are reproducible)
    """
    spec = engine_spec(par, clock=clock, speed=speed, seed=seed, params_dir=params_dir,
                       logs_dir=logs_dir, history_capacity=history_capacity, epoch=epoch)
    return assemble(spec, daq=daq, now=now, sleep=sleep)
