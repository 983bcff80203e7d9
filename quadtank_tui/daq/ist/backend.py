"""Active mode on an IST rig over its serial port (pyserial), in the engine's units.

Each sample the engine calls `read_levels` (one ``$``, one 14-byte answer) and
`write_pumps` (one 9-byte pump frame).  What the firmware demands of its host:

- Whole frames only.  After a ``#`` the firmware waits for the rest of the frame
  with its watchdog stopped, so a frame cut short would leave the pumps running
  with nothing to stop them.  A frame is written by one `write` call with every
  signal blocked in this thread (a Ctrl-C, a take-over or a SIGTERM cannot raise in
  the middle of it: the exception comes when the frame is out), and only into an
  empty output buffer (the kernel takes 9 bytes at once; a full buffer means a
  device that does not read, and is a fault without writing).
- A ``$`` at least every 2 s, or the firmware stops all four pumps.  The loop asks
  once a sample, and the sample may be 5 s: a keep-alive thread sends ``$`` (its
  answer read and dropped) whenever none went for `keepalive` s - but only while the
  loop itself is alive (it called within one sampling time and a second): a
  program whose loop froze stops feeding and the firmware stops the pumps 2 s later.
- A wait after opening the port: opening it resets the Nano (`open_wait`).

An answer that does not come within `timeout`, or comes short, or foreign, is a
BackendError at once (within the sample), and the port is closed so that no late
byte is taken for the next answer; the engine then pauses with the pumps to 0
(`safe_state`, one whole zero frame; a port closed by the fault is opened again
for it, and the opening itself resets the Nano, pumps off).  A silence longer than the 2 s watchdog
between two samples (this program stopped, the machine suspended) fails the next
sample: the firmware has stopped the pumps meanwhile.

There is no guard process: the port is opened exclusively (it is the rig's lock: a
second program is refused), so no other process could reach the rig.  What stops
the pumps when this program dies is the firmware's own 2 s watchdog.

Levels: h_i = dh_dr_i r_i + h0_i cm, y_i = kc h_i / 10.  Pumps: 10 u_i volts, the
PWM of the identified law (protocol.PumpCurve).  The disturbance pumps d1, d2 (a
fraction of full PWM, `set_disturbances`) go out with every pump frame.
"""

from __future__ import annotations

import math
import os
import signal
import threading
import time
from contextlib import contextmanager
from typing import TYPE_CHECKING, Any, Callable, Iterator

from quadtank_tui.core.disturbance import updated
from quadtank_tui.core.plants.common import FULL_SCALE_V
from quadtank_tui.daq.interlock import Interlock
from quadtank_tui.daq.ist import protocol as p
from quadtank_tui.daq.ist.config import IstConfig
from quadtank_tui.engine.backend import BackendError, InterlockHold, Levels4, Pair, ProcessBackend

if TYPE_CHECKING:
    from quadtank_tui.core.plants import Plant

#: An output buffer holding more than this many bytes: the device does not read.
STUCK_OUTPUT = 64
#: s to let the answer of an interrupted request arrive before it is flushed
#: (14 bytes at 9600 baud take 15 ms)
STALE_WAIT = 0.05


def open_serial(port: str, timeout: float) -> Any:
    """The port at 9600 8N1, raw, exclusive (the rig's lock), reads bounded by `timeout`."""
    import serial  # pyserial only when an IST rig is used

    return serial.Serial(port, baudrate=p.BAUD, bytesize=8, parity="N", stopbits=1, timeout=timeout,
                         write_timeout=timeout, exclusive=True)


@contextmanager
def _signals_held() -> Iterator[None]:
    """No Python signal handler runs in this thread until the block ends.

    pthread_sigmask runs the handlers of signals already pending when it returns,
    and one may raise (KeyboardInterrupt, a test's alarm).  So the mask is read
    first, by a call that blocks nothing, and the blocking call is inside the
    try: raised there, the mask is still put back.  Before, a handler raising in
    the blocking call left every signal blocked in this thread for good, and
    every process it spawned afterwards inherited that mask (sessions that ignored
    SIGTERM)."""
    try:
        old = signal.pthread_sigmask(signal.SIG_BLOCK, ())
    except (AttributeError, OSError, ValueError):  # no pthread_sigmask (Windows)
        yield
        return
    try:
        signal.pthread_sigmask(signal.SIG_BLOCK, signal.valid_signals())
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)


class IstBackend(ProcessBackend):
    """An IST rig behind a serial port (see the module docstring)."""

    kind = "Active"

    def __init__(self, config: IstConfig, *, opener: Callable[[str, float], Any] = open_serial,
                 clock: Callable[[], float] = time.monotonic, sleep: Callable[[float], None] = time.sleep) -> None:
        self.config = config
        self.description = f"ist serial {config.port}"
        self._opener, self._clock, self._sleep = opener, clock, sleep
        self._port: Any = None
        self._lock = threading.RLock()  # one exchange at a time: the loop's or the keep-alive's
        self._last_request: float | None = None  # when the last '$' was answered
        self._loop_call: float | None = None     # when the loop last called
        self._tsamp: float | None = None
        self._keepalive: threading.Thread | None = None
        self._stop = threading.Event()
        self._keepalive_error = ""
        self._interrupted = False  # an exchange was cut by a signal's exception
        #: the disturbance pumps' PWM codes (0..255) sent with every pump frame
        self.disturbance: tuple[int, int] = (0, 0)
        self.full_scale = 1.0
        self.interlock = Interlock.for_height(config.interlock_limit, self.full_scale,
                                              enabled=config.interlock_enabled, feeders=config.plant.feeders)
        self.applied: Pair = (0.0, 0.0)
        self.safe_state_error = ""
        #: the PWM codes of the last frame written (u1, u2, d1, d2)
        self.last_frame: tuple[int, int, int, int] = (0, 0, 0, 0)

    @property
    def disturbances(self) -> tuple[float, float]:
        """The disturbance pumps' duties d1, d2 going out with the pump frames (0..1)."""
        return (self.disturbance[0] / p.DISTURBANCE_MAX, self.disturbance[1] / p.DISTURBANCE_MAX)

    @property
    def alarms(self) -> tuple[str, ...]:
        return self.interlock.alarms(self.full_scale)

    # --- ProcessBackend --------------------------------------------------------------

    def arm(self, tsamp: float) -> None:
        """Active control starts (or its sampling time changes): the keep-alive runs
        for a loop sampling every `tsamp` s.  A loop that comes back to the rig (Simul
        -> Active) left it on purpose, pumps at 0: the silence meanwhile is no stall."""
        now = self._clock()
        if self._loop_call is None or now - self._loop_call > (self._tsamp or 0.0) + 1.0:
            self._last_request = None
        self._tsamp = tsamp
        self._loop_call = now
        if self._keepalive is None:
            self._stop.clear()
            self._keepalive = threading.Thread(target=self._keep_alive, name="ist-keepalive", daemon=True)
            self._keepalive.start()

    def read_levels(self) -> Levels4:
        with self._lock:
            self._loop_called()
            codes = self._request_levels()
        cm = self.levels_cm(codes)
        self.interlock.update([h / self.config.tank_height for h in cm])
        kc = self.config.sensor_gain
        return (kc * cm[0] / FULL_SCALE_V, kc * cm[1] / FULL_SCALE_V, kc * cm[2] / FULL_SCALE_V,
                kc * cm[3] / FULL_SCALE_V)

    def levels_cm(self, codes: tuple[int, int, int, int, int]) -> list[float]:
        """The levels (cm) of an answer's codes; BackendError for a sensor fault."""
        out = []
        for tank, (s, code) in enumerate(zip(self.config.sensors, codes), start=1):
            try:
                h = s.level(p.ratio(code, codes[4]))
            except p.FrameError as exc:
                raise BackendError(f"sensor fault: tank{tank}: {exc}") from None
            lo, hi = self.config.plausible_range(tank)
            if not lo <= h <= hi:
                raise BackendError(f"sensor fault: tank{tank} reads code {code} of Vcc {codes[4]} = {h:.4g} cm, "
                                   f"outside its plausible {lo:g}..{hi:g} cm (a broken wire or a dead sensor?)")
            out.append(h)
        return out

    def write_pumps(self, u: Pair) -> None:
        applied = self.interlock.cut(u)
        pwm = [self.config.pumps[i].pwm(FULL_SCALE_V * applied[i]) for i in range(2)]
        with self._lock:
            self._loop_called()
            self._write_frame((pwm[0], pwm[1], *self.disturbance))
        self.applied = applied
        self.safe_state_error = ""  # the pumps are where this frame put them, under control again

    def written(self, requested: Pair) -> Pair:
        return self.applied

    def interlock_holds(self) -> tuple[InterlockHold, ...]:
        return self.interlock.holds(self.full_scale)

    def set_disturbances(self, d1: float | None, d2: float | None) -> None:
        """The disturbance pumps at fractions d1, d2 of full PWM (None: as it is)
        from the next pump frame (a pause's safe_state stops them)."""
        duties = updated(self.disturbances, d1, d2)
        self.disturbance = (round(duties[0] * p.DISTURBANCE_MAX), round(duties[1] * p.DISTURBANCE_MAX))

    def safe_state(self) -> None:
        """One whole zero frame (all four pumps); never raises.  A port closed by a
        fault is opened again first: the opening resets the Nano, which stops the
        pumps by itself and clears a firmware hung in a frame cut on the line,
        which its watchdog would never stop."""
        self.disturbance = (0, 0)
        try:
            with self._lock:
                self._write_frame((0, 0, 0, 0))
            self.applied = (0.0, 0.0)
            self.safe_state_error = ""
        except Exception as exc:  # noqa: BLE001 - the contract: safe_state never raises
            self.safe_state_error = str(exc) or type(exc).__name__

    #: What stops the pumps when this program cannot (for the messages).
    safety_net = f"the rig's firmware watchdog (within {p.WATCHDOG_S:g} s of the last level request)"

    def plant_refused(self, plant: Plant) -> str | None:
        if plant.kind != "quadtank":
            return (f"{self.config.source}: the IST rig is a quadruple tank (four levels, two pumps), "
                    f"not the {plant.kind} plant in use")
        return None

    def close(self) -> None:
        """The keep-alive ends, the port is closed (the pumps already at 0)."""
        self._stop.set()
        if self._keepalive is not None:
            self._keepalive.join(timeout=2 * self.config.timeout + 1.0)
            self._keepalive = None
        with self._lock:
            self._drop()

    # --- the link --------------------------------------------------------------------

    def read_raw_volts(self) -> tuple[float, ...]:
        """The calibration procedure's raw readings (daq/calibrate.py): the four
        sensors' ratios r = (Vcc - v) / v, the quantity the level is linear in (its
        fit's gain is dh_dr, its offset h0)."""
        codes = self.read_codes()
        try:
            return tuple(p.ratio(code, codes[4]) for code in codes[:4])
        except p.FrameError as exc:
            raise BackendError(f"sensor fault: {exc}") from None

    def read_codes(self) -> tuple[int, int, int, int, int]:
        """One '$' exchange: the raw codes v1..v4, Vcc (for `daq check`)."""
        with self._lock:
            return self._request_levels()

    def _loop_called(self) -> None:
        """The loop is here: the keep-alive may feed for one more sampling time; a
        silence over the firmware's watchdog since the last '$' is reported."""
        now = self._clock()
        self._loop_call = now
        error, self._keepalive_error = self._keepalive_error, ""
        if error:
            self._drop()
            raise BackendError(error)
        if self._tsamp is not None and self._last_request is not None and now - self._last_request > p.WATCHDOG_S:
            gap, self._last_request = now - self._last_request, None
            raise BackendError(f"no level request reached the rig for {gap:.1f} s, longer than its watchdog "
                               f"({p.WATCHDOG_S:g} s): it has set the pumps to 0 (this program was stopped or "
                               "the machine suspended). Active control ends here: Run starts it again")

    def _ensure_open(self) -> Any:
        if self._port is None:
            try:
                port = self._opener(self.config.port, self.config.timeout)
            except Exception as exc:  # noqa: BLE001 - pyserial's SerialException, OSError, ...
                raise BackendError(f"cannot open the serial port {self.config.port}: {exc}") from None
            self._sleep(self.config.open_wait)  # the Nano resets when the port opens
            try:
                port.reset_input_buffer()
            except Exception:  # noqa: BLE001 - a bootloader's stray bytes are dropped if possible
                pass
            self._port = port
        return self._port

    def _drop(self) -> None:
        port, self._port = self._port, None
        self._last_request = None
        if port is not None:
            try:
                port.close()
            except Exception:  # noqa: BLE001 - closing a dead port must not hide the real fault
                pass

    def _request_levels(self) -> tuple[int, int, int, int, int]:
        def ask(port: Any) -> bytes:
            if self._interrupted:  # the answer to the interrupted '$' may be on its way
                self._sleep(STALE_WAIT)
                self._interrupted = False
            port.reset_input_buffer()  # no stray or stale byte is taken for this answer
            self._write_whole(port, p.REQUEST)
            return bytes(port.read(p.LEVELS_REPLY_LEN))

        reply = self._io("level request", ask)
        try:
            codes = p.parse_levels_reply(reply)
        except p.FrameError as exc:
            self._drop()  # a late byte must not be taken for the next answer
            why = (f"no answer within {self.config.timeout:g} s" if not reply else str(exc))
            raise BackendError(f"level request on {self.config.port}: {why}") from None
        self._last_request = self._clock()
        return codes

    def _write_frame(self, pwm: tuple[int, int, int, int]) -> None:
        frame = p.pump_frame(*pwm)
        self._io("pump frame", lambda port: self._write_whole(port, frame))
        self.last_frame = pwm

    def _io(self, what: str, call: Callable[[Any], Any]) -> Any:
        """`call(port)` on the open port; any failure closes it (no late byte is
        taken for the next answer) and is a BackendError naming `what`."""
        port = self._ensure_open()
        try:
            return call(port)
        except BackendError:
            self._drop()
            raise
        except Exception as exc:  # noqa: BLE001 - pyserial's SerialException, OSError, ...
            self._drop()
            raise BackendError(f"{what} on {self.config.port} failed: {exc}") from None
        except BaseException:  # Ctrl-C, a stop signal: the port stays open for safe_state
            self._interrupted = True
            raise

    def _write_whole(self, port: Any, frame: bytes) -> None:
        """`frame` by one write system call, signals held in this thread, into an
        empty output buffer (so the kernel takes it whole).  Should it ever take
        part, the rest follows at once (a frame is never left cut) and it is a fault."""
        waiting = getattr(port, "out_waiting", 0)
        if waiting > STUCK_OUTPUT:
            raise BackendError(f"{self.config.port}: {waiting} bytes wait to go out: the device does not read")
        fileno = getattr(port, "fileno", None)
        with _signals_held():
            if fileno is None:
                port.write(frame)
                return
            try:
                n = os.write(fileno(), frame)
            except BlockingIOError:
                raise BackendError(f"{self.config.port}: the output buffer is full: the device does not read") \
                    from None
            if n < len(frame):
                port.write(frame[n:])  # pyserial waits (up to its write timeout) for room
                raise BackendError(f"{self.config.port}: the frame went out in two parts ({n} + "
                                   f"{len(frame) - n} bytes)")

    # --- the keep-alive ----------------------------------------------------------------

    def _keep_alive(self) -> None:
        """A '$' whenever none went for `keepalive` s, while the loop lives."""
        period = self.config.keepalive
        while not self._stop.wait(period / 4):
            now = self._clock()
            tsamp = self._tsamp or 0.0
            if self._loop_call is None or now - self._loop_call > tsamp + 1.0 or self.safe_state_error:
                continue  # the loop is gone or frozen, or its zero frame failed: let the firmware's watchdog act
            last = self._last_request
            if last is None or now - last < period:
                continue
            with self._lock:
                if self._port is None or self._stop.is_set() or (self._last_request or -math.inf) > last:
                    continue
                try:
                    self._request_levels()
                except BackendError as exc:
                    self._keepalive_error = f"keep-alive: {exc}"
