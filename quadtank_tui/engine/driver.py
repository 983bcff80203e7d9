"""The one driver of the control loop: wait for the next sample, sample, hand it on.

Every way the loop runs goes through :class:`Driver`: a session (its host serves
the clients on the driver's asyncio event loop: the TUI's session, `quadtank run
--detach`, the tests' ThreadSession) and the runs without clients (`quadtank run`, `Engine.run_for` / `Engine.step`, the
benchmarks).  The pacing and the loop-time accounting are here and nowhere else.

Waiting (a clock on the wall, time.monotonic): a sample due more than FINE_WAIT
from now is waited for on the event loop (`loop.call_at`), so the clients'
messages are served meanwhile; the last FINE_WAIT is a plain sleep (epoll rounds
its timeout up to whole milliseconds), so the jitter is the sleep's, not the
event loop's.  On Linux the driving thread's timer slack is set to 1 us first: a
sleep overshoots by the slack, whose default (50 us) is a whole sampling period at
x1000 and 50 ms.  The
thread sleeps rather than spins, so it does not take a core from the clients;
only a wait shorter than SPIN_BELOW, which a sleep would overshoot, is spun, and
a real-time clock's last SPIN_LAST (a sleeping core wakes late: the machine's
idle exit).  A real-time clock's thread runs at real-time priority while it
drives, if allowed (realtime_priority): woken at its deadline, it then gets a
core at once, and the GIL within SWITCH_INTERVAL (short_switch_interval).
The event loop gets its turns (`loop.call_at`'s waits, and every YIELD_AFTER of
wall time, or at once when a client has lines waiting) right after a sample and
its publishing, never between a wait's end and its sample: the fine wait is the
driver's alone.  A virtual clock at x1000 and 50 ms has a sample due every 50 us:
every wait is a fine one (most are spun), the event loop gets a turn every
YIELD_AFTER, and the lag such a turn leaves is made up by samples back to back
(engine/clock.py, CATCH_UP).  A drive paced on the wall writes its log on the
file thread (a virtual clock's too: at x1000 a row's write(2) inline is a large
part of a sample's time), and the rows held for it (engine/filework.py) are handed on before
every wait of FLUSH_BEFORE or more and at the end.  An injected time source (a ManualClock: tests, rehearsals) is waited
on with the engine's own `sleep`, which only moves that time on; such a drive
holds its log rows in the same batches, written inline (FileWorker.hold).

Without an event loop (:meth:`Driver.run`: no clients) the same coroutine is
stepped inline: it never has to give the event loop a turn, so it never awaits.

Loop time: `elapsed` counts sampling periods (LoopTime); on a real process the
slots the clock skipped count too (its time passes whether or not the loop keeps
up), so a run against a slow or hung device still ends on time.
"""

from __future__ import annotations

import asyncio
import ctypes
import os
import sys
import time
from typing import Awaitable, Callable, ClassVar, Protocol

from quadtank_tui.engine.clock import Clock


class Drivable(Protocol):
    """What the driver needs of what it drives: the engine (engine/runner.py)."""

    @property
    def clock(self) -> Clock:
        """The deadlines of the samples."""

    @property
    def wall_paced(self) -> bool:
        """The deadlines are on the wall's monotonic clock: waited for for real."""

    @property
    def sampling_time(self) -> float:
        """The sampling time in force, s."""

    def sleep(self, seconds: float) -> None:
        """Wait `seconds` of an injected time source (a ManualClock's moves on)."""

    def sample(self) -> int:
        """Take one sample now; returns the sampling slots it stands for (1, and on a
        real process the ones the clock skipped before it)."""

    def flush_files(self) -> None:
        """The log rows held for the file thread go to it now."""

    def hold_files(self, hold: bool) -> None:
        """Hold the log rows for batches (a drive off the wall) or let them go."""

    def use_file_thread(self) -> None:
        """From now on the log rows go to a file thread, so no sample waits for the disk."""

#: Below this, the last part of a wait is a sleep and a spin, not the event loop's
#: timer (whose epoll timeout rounds up to whole milliseconds), s.
FINE_WAIT = 0.002
#: A wait shorter than this is spun, not slept, s: even at 1 us of timer slack a
#: sleep of a few microseconds costs more wall time and CPU than the wait itself,
#: and at x1000 and 50 ms every wait is that short: sleeping them would not hold x1000.
SPIN_BELOW = 20e-6
#: The last part of a real-time clock's fine wait that is spun, not slept, s.  A
#: sleeping thread is woken late by the time its core takes to come out of idle
#: (a virtual machine's halted vCPU, most of all): spinning the last part of the
#: wait takes that lateness out of the jitter's tail.  It costs SPIN_LAST of CPU a
#: sample (a few per cent of a core at 10 ms); a virtual clock, whose jitter the
#: simulated plant never sees, sleeps to its deadline.
SPIN_LAST = 0.0003
#: The real-time priority (SCHED_FIFO, 1..99) a real-time clock's driving thread
#: asks for: the lowest, which is enough to run before every ordinary process.
RT_PRIORITY = 1
#: The interpreter's switch interval while a real-time clock drives, s (Python's
#: default is 5 ms).  The driving thread, woken at its deadline, must also get the
#: GIL from the process's other threads (the file thread, a client's reader, a
#: design): they hand it over after at most this long (benchmarks/session_timing.py
#: shows what it does to the jitter's p99).
SWITCH_INTERVAL = 0.0005
#: A fine wait at least this long hands the held log rows to the file thread
#: first, s; a shorter one keeps them for the next batch (engine/filework.py,
#: BATCH_WINDOW), so a row waits at most about two batch windows.  Handing them on
#: before every wait would wake the file thread every sample at x1000 and 50 ms
#: (whose waits are a few microseconds) and defeat the batches.
FLUSH_BEFORE = 0.001
#: The driving thread's timer slack, ns (Linux prctl PR_SET_TIMERSLACK).
TIMER_SLACK_NS = 1000
_PR_SET_TIMERSLACK = 29
#: Longest wall time the driver samples without giving its event loop a turn
#: (the clients' messages, the signals), s.
YIELD_AFTER = 0.002


class LoopTime:
    """Seconds of loop time as whole samples per sampling time (base + n h), so that
    8 h of 50 ms samples is exactly 576000 of them, not one more from summed rounding."""

    def __init__(self, h: float) -> None:
        self._base, self._n, self._h = 0.0, 0, h
        self.samples = 0

    @property
    def seconds(self) -> float:
        return self._base + self._n * self._h

    def add(self, h: float, slots: int = 1) -> None:
        """One sample went by, and with it `slots` sampling periods of `h` s (more than
        one when a real process's sample came late: its missed slots passed too)."""
        if h != self._h:
            self._base, self._n, self._h = self.seconds, 0, h
        self._n += slots
        self.samples += 1

    def reached(self, t: float) -> bool:
        h = self._h
        return t - (self._base + self._n * h) <= 1e-6 * h  # (seconds, written out: asked every sample)


def fine_wait(deadline: float, spin: float = 0.0) -> None:
    """Until `deadline` (time.monotonic): a sleep until `spin` s before it, then a
    spin (all of it spun when the sleep would be shorter than SPIN_BELOW: a sleep
    would take longer than the wait).  The spin holds the GIL: given away this close
    to the deadline, it could take SWITCH_INTERVAL to get back."""
    monotonic = time.monotonic
    rest = deadline - spin - monotonic()
    if rest >= SPIN_BELOW:
        time.sleep(rest)
    while monotonic() < deadline:
        pass


def tight_timer_slack() -> None:
    """This thread's sleeps end within TIMER_SLACK_NS of their time (Linux; elsewhere
    and if refused, the system's slack stays)."""
    if not sys.platform.startswith("linux"):
        return
    try:
        ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_TIMERSLACK, TIMER_SLACK_NS, 0, 0, 0)
    except (OSError, AttributeError):
        pass


def realtime_priority() -> Callable[[], None]:
    """This thread runs SCHED_FIFO at RT_PRIORITY from now on, if the system allows
    it (Linux: root, CAP_SYS_NICE or an RLIMIT_RTPRIO of 1 at least; refused, the
    thread keeps its policy); returns what gives the thread its old policy back.

    A sleeping thread of an ordinary process that wakes at its deadline waits for
    a core while both are busy (a client drawing, other users' programs), until a
    scheduler tick gives it one: milliseconds late on a loaded machine; at
    SCHED_FIFO 1 it runs before every ordinary process.  Threads started from
    this one (a LoadPar's read, an MPC's design) do not inherit it
    (SCHED_RESET_ON_FORK); the kernel's real-time throttling keeps 5 % of a core
    for the others whatever happens."""
    if not hasattr(os, "sched_setscheduler"):
        return _unchanged
    try:
        policy, param = os.sched_getscheduler(0), os.sched_getparam(0)
        os.sched_setscheduler(0, os.SCHED_FIFO | os.SCHED_RESET_ON_FORK, os.sched_param(RT_PRIORITY))
    except OSError:  # not allowed: the ordinary policy, and its jitter under load
        return _unchanged

    def restore() -> None:
        try:
            os.sched_setscheduler(0, policy, param)
        except OSError:
            pass
    return restore


def _unchanged() -> None:
    pass


def short_switch_interval() -> Callable[[], None]:
    """The process's threads hand the GIL over after SWITCH_INTERVAL (if longer now);
    returns what puts the old interval back."""
    old = sys.getswitchinterval()
    if old <= SWITCH_INTERVAL:
        return _unchanged
    sys.setswitchinterval(SWITCH_INTERVAL)
    return lambda: sys.setswitchinterval(old)


def _release(waiter: asyncio.Future[None]) -> None:
    if not waiter.done():
        waiter.set_result(None)


class Driver:
    """Drives `engine` until stopped, or until `duration` s of loop time / `samples`
    samples have been taken.

    before(elapsed) : ahead of each sample (a script applies its due events); an
        exception ends the drive and is raised by run / handed to serve's finish
    after() : after each sample (a session publishes, at most every so often)
    urgent() : the event loop has work that should not wait YIELD_AFTER (a
        session's lines queued for a client: a full ring buffer on attach goes
        out a socket buffer per turn)
    """

    #: Drives started since the program began (the test that every mode goes through here counts them).
    started: ClassVar[int] = 0

    def __init__(self, engine: Drivable, *, duration: float | None = None, samples: int | None = None,
                 before: Callable[[LoopTime], None] | None = None,
                 after: Callable[[], None] | None = None, urgent: Callable[[], bool] | None = None) -> None:
        self.engine = engine
        self.duration = duration
        self.samples = samples
        self.before = before
        self.after = after
        self.urgent = urgent
        self.elapsed = LoopTime(engine.sampling_time)
        self.aloop: asyncio.AbstractEventLoop | None = None
        self._stopping = False
        self._waiter: asyncio.Future[None] | None = None

    # --- the two ways to run it ---------------------------------------------------------------

    def run(self) -> int:
        """Drive here, without an event loop (no clients); returns the samples taken."""
        Driver.started += 1
        coro = self._drive()
        try:
            coro.send(None)  # it never awaits without an event loop: one send runs it to the end
        except StopIteration:
            return self.elapsed.samples
        coro.close()
        raise RuntimeError("the driver awaited without an event loop")

    def serve(self, aloop: asyncio.AbstractEventLoop,
              finish: Callable[[BaseException | None], Awaitable[None]] | None = None) -> None:
        """Drive on `aloop` (whatever else is registered on it is served during the
        waits) until stopped; then `finish(failure)` runs on it (failure: what ended
        the drive, None when it was stopped or its time was up).  The loop is closed
        afterwards."""
        Driver.started += 1
        self.aloop = aloop
        try:
            aloop.run_until_complete(self._serve(finish))
        finally:
            self.aloop = None
            self._waiter = None
            aloop.close()

    async def _serve(self, finish: Callable[[BaseException | None], Awaitable[None]] | None) -> None:
        failure: BaseException | None = None
        try:
            await self._drive()
        except Exception as exc:  # noqa: BLE001 - handed to finish, which stops in order and says why
            failure = exc
        if finish is not None:
            await finish(failure)

    # --- stopping and waking ----------------------------------------------------------------

    def stop(self) -> None:
        """End the drive at its next turn (any thread, a signal handler)."""
        self._stopping = True
        self.poke_threadsafe()

    @property
    def stopping(self) -> bool:
        return self._stopping

    def poke(self) -> None:
        """On the event loop's thread: end the current wait (the schedule or the
        commands may have changed)."""
        if self._waiter is not None:
            _release(self._waiter)

    def poke_threadsafe(self) -> None:
        """From any thread: end the current wait."""
        aloop = self.aloop
        if aloop is not None:
            try:
                aloop.call_soon_threadsafe(self.poke)
            except RuntimeError:  # the loop closed in between: the drive is over
                pass

    # --- the drive --------------------------------------------------------------------------

    def _done(self) -> bool:
        if self._stopping:
            return True
        if self.duration is not None and self.elapsed.reached(self.duration):
            return True
        return self.samples is not None and self.elapsed.samples >= self.samples

    async def _drive(self) -> None:
        engine, clock = self.engine, self.engine.clock
        wall = engine.wall_paced
        if wall:
            tight_timer_slack()
            engine.use_file_thread()  # paced on the wall: no sample waits for the disk (a virtual clock's too)
        else:
            engine.hold_files(True)  # the log rows go in batches, as to the file thread (engine/filework.py)
        # What a real-time drive changes for its time, and what puts each back.
        restores = [realtime_priority(), short_switch_interval()] if wall and clock.realtime else []
        sleep = engine.sleep
        before, after, urgent, elapsed = self.before, self.after, self.urgent, self.elapsed
        aloop = self.aloop
        monotonic = time.monotonic
        turned = monotonic()
        flush = engine.flush_files
        spin = SPIN_LAST if wall and clock.realtime else 0.0
        try:
            while not self._done():
                deadline = clock.deadline()
                if deadline is not None:
                    if wall:
                        delay = deadline - monotonic()
                        if delay > FINE_WAIT and aloop is not None:
                            flush()
                            await self._wait(aloop, deadline - FINE_WAIT)
                            turned = monotonic()
                            continue  # woken early maybe: look at the commands and the deadline again
                        if delay >= FLUSH_BEFORE:
                            flush()
                        if delay > 0:
                            fine_wait(deadline, spin)
                    else:
                        delay = deadline - clock.now()
                        if delay > 0:
                            sleep(delay)
                if before is not None:
                    before(elapsed)
                    if self._stopping:
                        break
                h = engine.sampling_time
                elapsed.add(h, engine.sample())
                if after is not None:
                    after()
                if aloop is not None and (monotonic() - turned > YIELD_AFTER or urgent is not None and urgent()):
                    # The clients and the signals get a turn right after a sample, the
                    # farthest from the next deadline: never between a wait's end and
                    # its sample (a turn may encode a ring buffer's part, 1 ms).
                    flush()
                    await asyncio.sleep(0)
                    turned = monotonic()
        finally:
            flush()
            if not wall:
                engine.hold_files(False)
            for restore in restores:
                restore()

    async def _wait(self, aloop: asyncio.AbstractEventLoop, until: float) -> None:
        """Until `until` (monotonic, the event loop's own time) or a poke."""
        waiter: asyncio.Future[None] = aloop.create_future()
        self._waiter = waiter
        timer = aloop.call_at(until, _release, waiter)
        try:
            await waiter
        finally:
            timer.cancel()
            self._waiter = None
