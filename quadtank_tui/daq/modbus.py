"""Active mode over Modbus TCP: a LabJack T-series, a PLC, or the virtual rig.

Each sample the engine calls `read_levels` (one request for the level inputs when
the map lets them be read together) and `write_pumps` (one request for the pump
outputs likewise).  The channels are the plant's (config.PlantChannels): a two-tank
rig reads two inputs (y3, y4 are 0) and a one-pump rig writes one output.  A request that fails at once (a stale connection after the device
restarted, a refused connect, an exception answer) is tried once more; one that
waited out the timeout is not - the device had its whole `timeout` to answer, and
a second wait would only double the time a hung device holds the loop.  The
failure raises BackendError with the reason, and the engine pauses with the pumps
commanded to 0.  Nothing here reconnects in the background or restarts a pump: the
next request after a fault simply opens a new connection, so when the link is back
the user's explicit Run works again.

The sync pymodbus client is used from the engine's loop thread; the client's own
retry loop is off (retries=0), so the worst case is known: a silent device is a
fault within one timeout per request, and safe_state takes at most one more
timeout per pump.  Register values go through `registers.encode/decode`.

When Active control starts (`arm`, called by the loop with its sampling time) the
rig is watched for the program: at the next request the device's own watchdog
(daq/watchdog.py, if the configuration declares one) is armed with a timeout of a
few samples and the pumps' stop values, and a guard process (daq/guard.py) starts
to stop the pumps should this process die.  A silence longer than that timeout
between two requests (this process stopped, the machine suspended: the device's
watchdog has set the pumps to 0 meanwhile) fails the next sample instead of
driving the pumps again as if nothing had happened; the engine pauses and says
why.  A device that declares strict mode is armed with a key chosen per run, and
only our feed (every quarter timeout, while paused too: a paused loop still reads
the levels each tick) carries it.  After each request the guard hears a byte on
its pipe (rate-limited, never blocking): a frozen or deadlocked program falls
silent and the guard stops the pumps.  `close` (the orderly end, pumps already at
0) disarms both: the device's watchdog only while its settings still read as this
run armed them (the guard's rule: another program that has armed it since, a
take-over, keeps it).

While a `safe_state` is not confirmed (`safe_state_error`: a write of 0 failed),
and during its own requests, nothing here beats the guard or feeds the device's watchdog, so that they stop
the pumps within their timeout if the program cannot; a write of the pumps that
succeeds (the user's Run) ends that.  `close` then disarms nothing and hands the
guard over ("stop": it writes the stop values itself, until they are written).
"""

from __future__ import annotations

import logging
import math
import os
import secrets
import time
from typing import TYPE_CHECKING, Callable, Sequence

from pymodbus.client import ModbusTcpClient
from pymodbus.exceptions import ConnectionException, ModbusException, ModbusIOException

from quadtank_tui.core.plants.common import FULL_SCALE_V
from quadtank_tui.daq.identity import IDENTITY_ADDRESS, WORDS, RigIdentity, decode_identity, mismatches
from quadtank_tui.daq.config import DaqConfig, DaqConfigError, Output
from quadtank_tui.daq.guard import Guard, GuardSpec
from quadtank_tui.daq.interlock import Interlock
from quadtank_tui.daq.registers import Register, block, decode, encode
from quadtank_tui.daq.watchdog import gap_limit
from quadtank_tui.engine.backend import BackendError, InterlockHold, Levels4, Pair, ProcessBackend

if TYPE_CHECKING:
    from quadtank_tui.core.plants import Plant

# pymodbus logs link errors at ERROR level; with no handler of the application's,
# Python's last-resort handler would print them over the TUI.  The reason reaches
# the user through BackendError instead.
logging.getLogger("pymodbus").addHandler(logging.NullHandler())

#: Modbus exception codes a device answers with (Modbus Application Protocol 1.1b, 7).
EXCEPTION_CODES = {
    1: "illegal function", 2: "illegal data address", 3: "illegal data value",
    4: "device failure", 5: "acknowledge", 6: "device busy", 10: "gateway path unavailable",
    11: "gateway target failed to respond",
}


class ModbusBackend(ProcessBackend):
    """The rig behind a Modbus TCP server, in the engine's normalized units.

    y_i = kc_i * level_i / 10 with level_i = gain_i * volts_i + offset_i (cm) and kc_i
    the configuration's sensor gain of tank i; pump volts = 10 u_i, written as
    (pump volts - offset) / gain clipped to the output's limits.  Only the plant's
    channels are read and written.
    """

    kind = "Active"

    def __init__(self, config: DaqConfig, *, clock: Callable[[], float] | None = None,
                 guard: bool = True) -> None:
        self.config = config
        #: the time the silences are measured on: CLOCK_BOOTTIME counts a suspended machine
        self._clock = clock or _boot_clock
        #: the watchdog timeout armed (the longest silence allowed), s; None until `arm`
        self.watch_timeout: float | None = None
        self._arm_pending = False
        self._armed = False  # the device's watchdog is on (written by us)
        self._zeroing = False  # in safe_state
        #: (what, register, value) of the watchdog's settings as this run armed them
        self._ours: list[tuple[str, Register, float]] = []
        self._last_exchange: float | None = None
        #: the longest request since the last sample that outlasted the watchdog timeout, s
        self._stalled: float | None = None
        self._last_feed = -math.inf
        #: the strict key of this run (a LabJack UINT32; 0 is never used)
        self._key = 1 + secrets.randbelow(2**32 - 1)
        self._use_guard = guard
        nets = (["the guard process"] if guard else []) + \
            (["the device's watchdog"] if config.watchdog is not None else [])
        #: what stops the pumps when this program cannot (for the messages)
        self.safety_net = " and ".join(nets) or "nothing: no guard, no watchdog declared"
        self.guard: Guard | None = None
        self.description = f"modbus {config.host}:{config.port}"
        # `timeout` bounds the connect and each answer; the client's own retries are
        # off: this class retries once itself, so the worst case is known.
        self._client = ModbusTcpClient(config.host, port=config.port, timeout=config.timeout, retries=0)
        n = len(config.tanks)
        self._tanks = [config.tank_register(i) for i in range(1, n + 1)]
        self._tank_names = [config.channels[t] for t in config.tanks]
        self._plausible = [config.plausible_range(i) for i in range(1, n + 1)]  # cm, per tank
        self._pumps: list[Output] = [config.pump_output(i) for i in range(1, len(config.pump_channels) + 1)]
        # The requests do not change from sample to sample: planned once here.
        self._reads = _plan_reads(self._tanks, self._tank_names)
        pump_regs = [o.register for o in self._pumps]
        pump_names = [config.channels[p] for p in config.pump_channels]
        #: "write of DAC0 (holding register 1000-1001)" per pump, and for both at once
        #: when they are adjacent (one request), else None
        self._write_labels = [f"write of {_label([n], 'holding', r.address, r.count)}"
                              for n, r in zip(pump_names, pump_regs)]
        self._write_both: str | None = None
        if len(pump_regs) == 2 and pump_regs[0].address + pump_regs[0].count == pump_regs[1].address:
            count = pump_regs[0].count + pump_regs[1].count
            self._write_both = f"write of {_label(pump_names, 'holding', pump_regs[0].address, count)}"
        #: the interlock sees each level as a fraction of the tank height
        self.full_scale = 1.0
        self.interlock = Interlock.for_height(
            config.interlock_limit, self.full_scale, enabled=config.interlock_enabled,
            feeders=config.plant.feeders,
        )
        #: the pump inputs last written, after the interlock (normalized)
        self.applied: Pair = (0.0, 0.0)
        #: why the last safe_state could not be confirmed ("" when it was)
        self.safe_state_error = ""

    @property
    def alarms(self) -> tuple[str, ...]:
        """What the interlock is doing now (the engine shows it in its snapshot)."""
        return self.interlock.alarms(self.full_scale)

    # --- ProcessBackend --------------------------------------------------------------

    def arm(self, tsamp: float) -> None:
        """Active control starts (or its sampling time changed): the device's
        watchdog and the guard are set up at the next request, for `tsamp`."""
        wd = self.config.watchdog
        self.watch_timeout = wd.timeout_for(tsamp) if wd is not None else gap_limit(tsamp)
        self._arm_pending = True
        self._last_exchange = None  # a silence before Active control is none of its business
        self._stalled = None

    def read_levels(self) -> Levels4:
        self._watch()
        volts = self._read_volts()  # a dead link fails here first, and says so, before the arming
        self._arm_if_pending()
        self._feed_if_due()
        levels = self.levels_from_volts(volts)
        self.interlock.update(self.height_fractions(volts))
        return levels

    def levels_from_volts(self, volts: Sequence[float]) -> Levels4:
        """The normalized levels of the sensor voltages (0 for a tank the plant does
        not have); BackendError for a reading outside its tank's plausible range."""
        cm = [cal.level(v) for cal, v in zip(self.config.sensors, volts)]
        self._check_plausible(volts, cm)
        y = [kc * h / FULL_SCALE_V for kc, h in zip(self.config.sensor_gains, cm)]
        y += [0.0] * (4 - len(y))
        return (y[0], y[1], y[2], y[3])

    def height_fractions(self, volts: Sequence[float]) -> list[float]:
        """Each level as a fraction of the tank height (what the interlock compares)."""
        return [cal.level(v) / self.config.tank_height for cal, v in zip(self.config.sensors, volts)]

    def write_pumps(self, u: Pair) -> None:
        self._watch()
        self._arm_if_pending()  # armed before the pumps are driven
        applied = self.interlock.cut(u)
        self._write_volts([self._output_volts(i, applied[i]) for i in range(len(self._pumps))])
        self.applied = applied
        self.safe_state_error = ""  # the pumps are where this write put them, under control again
        self._feed_if_due()

    def written(self, requested: Pair) -> Pair:
        return self.applied

    def interlock_holds(self) -> tuple[InterlockHold, ...]:
        return self.interlock.holds(self.full_scale)

    def safe_state(self) -> None:
        """Each output to the value that stops its pump, separately (one bad output
        must not keep the other pump running); each tried as `_request` tries;
        never raises."""
        errors: list[str] = []
        self._zeroing = True  # its requests beat no guard: if they fail, the guard's gap runs from before
        try:
            for i in range(len(self._pumps)):
                try:
                    self._write_one(i, self._output_volts(i, 0.0))
                except BackendError as exc:
                    errors.append(str(exc))
                except Exception as exc:  # noqa: BLE001 - the contract: safe_state never raises
                    errors.append(f"{type(exc).__name__}: {exc}")
        finally:
            self._zeroing = False
        if not errors:
            self.applied = (0.0, 0.0)
        self.safe_state_error = "; ".join(errors)

    def plant_refused(self, plant: Plant) -> str | None:
        """The channels are the plant's the configuration was read for."""
        try:
            self.config.check_plant(plant)
        except DaqConfigError as exc:
            return str(exc)
        return None

    def close(self) -> None:
        """The end: the link closed.  With the pumps confirmed at 0 (the orderly end)
        the device's watchdog is disarmed - if its settings are still this run's
        (a dead link, or another program's arming: it stays armed, which only ever
        stops pumps) - and the guard told "bye".  With the pumps NOT confirmed at 0
        the watchdog stays armed, unfed, and the guard is handed over: it writes the
        stop values itself."""
        unconfirmed = bool(self.safe_state_error)
        if self._armed and self.config.watchdog is not None and not unconfirmed:
            reg = self.config.watchdog.enable
            try:
                if self._still_ours():
                    self._request("disarming the watchdog", lambda: self._write(reg.address, encode(reg, 0.0)))
                self._armed = False
            except Exception:  # noqa: BLE001 - the watchdog stays armed: it only ever stops pumps
                pass
        if self.guard is not None:
            if unconfirmed:
                self.guard.hand_over()
            else:
                self.guard.release()
            self.guard = None
        self._drop()

    def _still_ours(self) -> bool:
        """The device's watchdog settings read as this run armed them (its strict key
        above all): the guard's rule (guard.not_ours) before a disarm."""
        for what, reg, value in self._ours:
            words = self._request(f"reading the watchdog's {what} (holding register {reg.address})",
                                  lambda reg=reg: self._read("holding", reg.address, reg.count))  # type: ignore[misc]
            if words != encode(reg, value):
                return False
        return True

    def _drop(self) -> None:
        """Close the connection (the next request opens a new one)."""
        try:
            self._client.close()
        except Exception:  # noqa: BLE001 - closing a dead socket must not hide the real fault
            pass

    # --- the watch: the device's watchdog, the guard, the silences ----------------------

    def _watch(self) -> None:
        """Before a sample's request: a silence longer than the watchdog timeout ends
        Active control (BackendError)."""
        if self.watch_timeout is None:
            return
        status = self.guard.ended() if self.guard is not None else None
        if status is not None:  # nothing would stop the pumps should this program die now
            self.guard = None
            self._arm_pending = True  # Run starts a new one
            raise BackendError(
                f"the guard process ended (exit status {status}): nothing would stop the pumps if this "
                "program died. Active control ends here: Run starts it again with a new guard")
        now = self._clock()
        stalled, self._stalled = self._stalled, None
        if stalled is not None or (self._last_exchange is not None and now - self._last_exchange > self.watch_timeout):
            gap = stalled if stalled is not None else now - (self._last_exchange or now)
            self._last_exchange = None
            wd = "its watchdog has set the pumps to 0" if self.config.watchdog is not None else \
                "it has no watchdog: its guard has set the pumps to 0 (unless it could not reach the rig)"
            raise BackendError(
                f"no request reached the rig for {gap:.1f} s, longer than the watchdog timeout "
                f"{self.watch_timeout:g} s (this program was stopped or the machine suspended); {wd}. "
                "Active control ends here: Run starts it again")

    def _feed_if_due(self) -> None:
        """After a sample's request (so a dead link is reported by the read or the
        write it broke, as without a watchdog): the feed, every quarter timeout."""
        wd_decl, now = self.config.watchdog, self._clock()
        if (wd_decl is not None and wd_decl.feed is not None and self.watch_timeout is not None
                and not self._arm_pending and not self.safe_state_error
                and now - self._last_feed > self.watch_timeout / 4):
            feed, key = wd_decl.feed, float(self._key if wd_decl.strict else 0)
            self._request(f"feed of the watchdog (holding register {feed.address})",
                          lambda: self._write(feed.address, encode(feed, key)))
            self._last_feed = now

    def _arm_if_pending(self) -> None:
        if self._arm_pending:
            self._arm()

    def _arm(self) -> None:
        """Arm the device's watchdog (only the settings that differ are written: a
        LabJack keeps them in flash) and start the guard."""
        wd, timeout = self.config.watchdog, self.watch_timeout
        assert timeout is not None
        if wd is not None:
            writes = wd.arm_writes(timeout, {o: self.config.stop_volts(o) for o in self.config.outputs}, self._key)
            enable, settings = writes[-1], writes[1:-1]
            held = {id(reg): self._read_setting(what, reg) for what, reg, _ in writes[:-1]}
            differ = [(what, reg, v) for what, reg, v in settings if not math.isclose(held[id(reg)], v, abs_tol=1e-6)]
            on = held[id(wd.enable)] != 0
            plan = ([writes[0]] if differ and on else []) + differ + ([enable] if differ or not on else [])
            for what, reg, value in plan:
                self._request(f"arming the watchdog: {what} (holding register {reg.address})",
                              lambda reg=reg, value=value: self._write(reg.address, encode(reg, value)))  # type: ignore[misc]
            self._armed = True
            self._ours = writes[1:]  # the settings as armed, the enable last: what close checks
        # A guard watching with another timeout (the sampling time changed while
        # driven) is replaced: with the old, shorter one it would zero the pumps of a
        # program that is not late (and they would silently come back); with the old,
        # longer one a device without a watchdog would pump on for longer.  The new
        # guard starts before the old one is told its end: never a moment unwatched.
        if self._use_guard and (self.guard is None or self.guard.spec.gap != timeout):
            c = self.config
            writes_spec = [(c.channels[p], o.register.address, encode(o.register, c.stop_volts(c.channels[p])))
                           for p, o in zip(c.pump_channels, self._pumps)]
            disarm, ours = [], []
            if wd is not None:
                disarm = [("watchdog enable", wd.enable.address, encode(wd.enable, 0.0))]
                # what the guard reads before disarming: the settings as armed (with the
                # key when strict); another program's arming since is left alone
                ours = [(what, reg.address, encode(reg, value)) for what, reg, value in writes[1:]]
            old = self.guard
            try:
                self.guard = Guard(GuardSpec(os.getpid(), c.host, c.port, c.device_id, c.timeout,
                                             writes_spec, timeout, disarm=disarm, ours=ours))
            except OSError as exc:
                raise BackendError(f"cannot start the guard process: {exc}") from None
            if old is not None:
                old.release(wait=0.0)  # it ends at once on the word; a sample does not wait for it
        self._arm_pending = False
        self._last_feed = self._clock()  # arming has just cleared the device's timer

    def _read_setting(self, what: str, reg: Register) -> float:
        words = self._request(f"arming the watchdog: reading {what} (holding register {reg.address})",
                              lambda: self._read("holding", reg.address, reg.count))
        return decode(reg, words)

    def _check_plausible(self, volts: Sequence[float], cm: Sequence[float]) -> None:
        """A level no tank can have is a sensor fault (a broken wire at the rail), not
        a level: the controllers and the interlock would act on it."""
        for tank, (v, h, (lo, hi)) in enumerate(zip(volts, cm, self._plausible), start=1):
            if not lo <= h <= hi:
                raise BackendError(
                    f"sensor fault: tank{tank} ({self._tank_names[tank - 1]}) reads {v:.6g} V = {h:.4g} cm, "
                    f"outside its plausible {lo:g}..{hi:g} cm (a broken wire or a dead sensor?)")

    # --- registers ---------------------------------------------------------------------

    def read_raw_volts(self) -> tuple[float, ...]:
        """The sensor voltages before calibration, one per level channel (for
        calibrating, B9)."""
        return tuple(self._read_volts())

    def rig_identity(self) -> RigIdentity | None:
        """The device's identity block (daq/identity.py), None when it serves none
        (a real device answers an illegal address; BackendError: no link at all)."""
        try:
            words = self._request("the rig identity", lambda: self._read("holding", IDENTITY_ADDRESS, WORDS))
        except BackendError as exc:
            if "the device answered" in str(exc):
                return None
            raise
        return decode_identity(words)

    def identity_mismatches(self) -> tuple[list[str], list[str]] | None:
        """Where this DAQ file's pump calibration, and where its sensor calibration,
        is not the rig's (None: the device says nothing of itself)."""
        rig = self.rig_identity()
        if rig is None:
            return None
        c = self.config
        pumps = mismatches(rig, [p.gain for p in c.pumps], [p.offset for p in c.pumps], [], [])
        sensors = mismatches(rig, [], [], [t.gain for t in c.sensors], [t.offset for t in c.sensors])
        return pumps, sensors

    def identity_refused(self) -> str | None:
        """One line when the rig's pump amplifiers are not this file's (Active control
        must not start: the pumps would get other volts than the program means);
        None when they agree, the rig says nothing of itself, or it cannot be read
        now (the link's fault shows at the first sample).  Sensors that differ are
        what a calibration finds and fixes: not refused."""
        try:
            differ = self.identity_mismatches()
        except BackendError:
            return None
        if not differ or not differ[0]:
            return None
        return (f"{self.config.source}: not the rig at {self._where()}: {', '.join(differ[0])} "
                "(its pumps would get other volts than this file assumes)")

    def _output_volts(self, pump: int, u: float) -> float:
        cal = self.config.pumps[pump]
        lo, hi = self._pumps[pump].limits
        return min(hi, max(lo, cal.volts(FULL_SCALE_V * u)))

    def _read_volts(self) -> list[float]:
        """The tanks' input voltages, in as few requests as the map allows."""
        words: dict[tuple[str, int], int] = {}
        for table, first, count, what in self._reads:
            got = self._request(what, lambda: self._read(table, first, count))
            words.update(((table, a), w) for a, w in zip(range(first, first + count), got))
        volts = []
        for name, reg in zip(self._tank_names, self._tanks):
            v = decode(reg, [words[reg.table, a] for a in reg.span])
            if not math.isfinite(v):
                raise BackendError(f"{name} ({reg.describe()}) at {self._where()} returned {v}, not a voltage")
            volts.append(v)
        return volts

    def _read(self, table: str, first: int, count: int) -> list[int]:
        dev = self.config.device_id
        if table == "input":
            rr = self._client.read_input_registers(first, count=count, device_id=dev)
        else:
            rr = self._client.read_holding_registers(first, count=count, device_id=dev)
        if rr.isError():
            raise _DeviceAnswer(rr)
        if len(rr.registers) < count:
            raise ModbusIOException(f"short answer: {len(rr.registers)} of {count} registers")
        return list(rr.registers[:count])

    def _write_volts(self, volts: list[float]) -> None:
        if self._write_both is not None:  # one request for both
            first, second = (o.register for o in self._pumps)
            values = encode(first, volts[0]) + encode(second, volts[1])
            self._request(self._write_both, lambda: self._write(first.address, values))
            return
        for i in range(len(self._pumps)):
            self._write_one(i, volts[i])

    def _write_one(self, pump: int, volts: float) -> None:
        reg = self._pumps[pump].register
        values = encode(reg, volts)
        self._request(self._write_labels[pump], lambda: self._write(reg.address, values))

    def _write(self, address: int, values: list[int]) -> list[int]:
        rr = self._client.write_registers(address, values, device_id=self.config.device_id)
        if rr.isError():
            raise _DeviceAnswer(rr)
        return values

    # --- the link ---------------------------------------------------------------------

    def _request(self, what: str, call: Callable[[], list[int]]) -> list[int]:
        """`call`, tried once more if it failed fast; BackendError naming `what` and
        the reasons after that.  Its end, answered or not, ends a silence: a link
        that is down is a fault of its own, not this program gone quiet - unless
        the request itself took longer than the watchdog timeout (this program
        stopped between sending it and reading the answer: the device heard
        nothing after it, and its watchdog may have fired), which the next sample
        then finds as the silence it was."""
        start = self._clock()
        try:
            return self._tries(what, call)
        finally:
            self._last_exchange = self._clock()
            if self.watch_timeout is not None and self._last_exchange - start > self.watch_timeout:
                self._stalled = max(self._stalled or 0.0, self._last_exchange - start)
            if self.guard is not None and not (self._zeroing or self.safe_state_error):  # unconfirmed: it must act
                self.guard.beat()

    def _tries(self, what: str, call: Callable[[], list[int]]) -> list[int]:
        reasons: list[str] = []
        for _ in range(2):
            start = time.monotonic()
            try:
                if not self._client.connect():
                    raise _NoConnection()
                return call()
            except _NoConnection:
                reasons.append(f"cannot connect to {self._where()}")
            except _DeviceAnswer as exc:
                reasons.append(f"the device answered '{exc.text}'")
            except ModbusIOException:
                reasons.append(f"no answer within {self.config.timeout:g} s")
            except ConnectionException:
                reasons.append("connection lost")
            except (ModbusException, OSError) as exc:
                reasons.append(str(exc) or type(exc).__name__)
            # A late answer to the failed request must not be taken for the next one.
            self._drop()
            if time.monotonic() - start >= self.config.timeout / 2:
                break  # it waited (out) the timeout: no second wait
        seen = list(dict.fromkeys(reasons))
        tries = "failed twice" if len(reasons) == 2 else "failed"
        raise BackendError(f"{what} at {self._where()} {tries}: {', then '.join(seen)}")

    def _where(self) -> str:
        return f"{self.config.host}:{self.config.port}"


def _boot_clock() -> float:
    """Seconds on a clock that runs on while the machine is suspended (Linux's
    CLOCK_BOOTTIME; elsewhere the monotonic clock)."""
    try:
        return time.clock_gettime(time.CLOCK_BOOTTIME)
    except (AttributeError, OSError):
        return time.monotonic()


class _NoConnection(Exception):
    """connect() returned False (refused, unreachable, or timed out)."""


class _DeviceAnswer(Exception):
    """The device answered with a Modbus exception response."""

    def __init__(self, response: object) -> None:
        code = int(getattr(response, "exception_code", 0) or 0)
        self.text = EXCEPTION_CODES.get(code, f"exception code {code}") if code else str(response)
        super().__init__(self.text)


def _plan_reads(regs: list[Register], names: list[str]) -> list[tuple[str, int, int, str]]:
    """(table, first address, count, "read of ...") of each request that reads `regs`:
    one for all when they form one block, else one per register."""
    span = block(regs)
    if span is not None:
        first, count = span
        return [(regs[0].table, first, count, f"read of {_label(names, regs[0].table, first, count)}")]
    return [(r.table, r.address, r.count, f"read of {_label([n], r.table, r.address, r.count)}")
            for r, n in zip(regs, names)]


def _label(names: list[str], table: str, first: int, count: int) -> str:
    """e.g. "AIN0..AIN3 (input registers 0-7)"."""
    who = names[0] if len(names) == 1 else f"{names[0]}..{names[-1]}"
    regs = f"register {first}" if count == 1 else f"registers {first}-{first + count - 1}"
    return f"{who} ({table} {regs})"
