"""The guard: a small process of its own that stops the pumps when the program driving them dies.

While a rig is driven (Active control armed, daq/modbus.py), the process driving
it - a session host, a headless `quadtank run --daq` -
starts `python -m quadtank_tui.daq.guard` and keeps a pipe to it.  The guard
watches that process (a pidfd where Linux has one, else polling) and:

- when it ends after saying "bye" on the pipe (an orderly end: it has put the
  pumps at 0 and disarmed the watchdog itself), ends without a word;
- when it says "stop" instead (it ends its control of the rig, but its own write
  of the pumps' stop values failed: the pumps may still run), acts at once as if
  it had died;
- when it ends without it (SIGKILL, a crash, the OOM killer), writes each pump
  output's stop value over a Modbus TCP connection of its own, then disarms the
  device's watchdog if its settings are still the ones the program armed (the
  strict key above all: another program that has armed it since keeps it), and
  says why on its stderr (a session's `<runtime>/<id>.out`, a headless run's
  terminal);
- when it has heard nothing on the pipe for the watchdog timeout - the program
  writes a byte after its requests (`Guard.beat`), so this is a program stopped
  (SIGSTOP), frozen (a cgroup freezer, state D) or whose loop is deadlocked,
  whatever its process state - writes the stop values, once per silence: a
  device without a watchdog would pump on.  The program, if it runs again, finds
  the gap itself and pauses (daq/modbus.py); the guard does not write again.
  (A program whose pumps are not confirmed at 0 falls silent on purpose:
  daq/modbus.py beats only while its stop is confirmed.)

A stop of its own that fails (the device busy, the link down) is tried again every
RETRY_S until it is done: while the program stays silent, or, once it is gone or
has said "stop", for at most GIVE_UP_S.

It never writes while the program is heard.  It starts its own session (a Ctrl-C or a
hang-up of the program's terminal does not reach it) and imports nothing heavy:
the socket, struct and the few lines of Modbus it needs (function 16), so it is
watching within a fraction of a second of being started.
"""

from __future__ import annotations

import json
import os
import select
import socket
import struct
import subprocess
import sys
import time
import dataclasses
from dataclasses import asdict, dataclass
from typing import IO

from quadtank_tui.files.proc import process_state

#: How often the guard looks whether the program is stopped, s (a read of
#: /proc/PID/stat: 20 a second cost nothing measurable).
POLL_S = 0.05
#: What the program writes on the pipe at an orderly end.
BYE = b"bye\n"
#: What it writes when it ends its control without its pumps confirmed at 0.
STOP = b"stop\n"
#: How often a stop of the guard's that failed is tried again, s.
RETRY_S = 0.25
#: How long it goes on trying once the program is gone (or said "stop"), s: a device
#: refusing or unreachable for longer is beyond it (its own watchdog, if any, acts).
GIVE_UP_S = 120.0


@dataclass(frozen=True)
class GuardSpec:
    """What the guard is told: whom to watch and what to write when it dies."""

    pid: int
    host: str
    port: int
    device_id: int
    timeout: float                      # s per request (the link's)
    writes: list[tuple[str, int, list[int]]]  # (output, address, words) of each pump's stop value
    gap: float                          # the watchdog timeout, s: a stop longer than it is acted on
    who: str = "the program driving the rig"
    #: (what, address, words) that disarm the device's watchdog once the pumps are at 0
    #: after the program died (it kept it armed; a next program, `daq calibrate` say,
    #: would find its pumps stopped after each silence of the timeout)
    disarm: list[tuple[str, int, list[int]]] = dataclasses.field(default_factory=list)
    #: (what, address, words) of the watchdog's settings as the program armed them
    #: (with its strict key): the guard disarms only while they still read so
    ours: list[tuple[str, int, list[int]]] = dataclasses.field(default_factory=list)


class Guard:
    """The program's side: start the guard process; `release` at an orderly end."""

    def __init__(self, spec: GuardSpec) -> None:
        self.spec = spec
        # -P and cwd "/": the guard imports this installation's package, never a
        # `quadtank_tui/` in the user's current folder (a checkout of another version
        # killed it at start with an ImportError, and the run drove on unguarded).
        self._proc = subprocess.Popen(
            [sys.executable, "-P", "-m", "quadtank_tui.daq.guard"], stdin=subprocess.PIPE,
            stdout=subprocess.DEVNULL, start_new_session=True, close_fds=True, cwd="/", bufsize=0,
        )
        assert self._proc.stdin is not None
        self._pipe: IO[bytes] | None = self._proc.stdin
        self._pipe.write(json.dumps(asdict(spec)).encode() + b"\n")  # (well within a pipe's 64 KiB)
        # From here on a write never blocks the sampling path: a guard that is not
        # reading (stopped itself) only costs the beats the full pipe refuses.
        os.set_blocking(self._pipe.fileno(), False)
        #: at most one beat per this many s: a quarter of the silence the guard allows
        self._beat_every = spec.gap / 4
        self._last_beat = time.monotonic()

    @property
    def pid(self) -> int:
        return self._proc.pid

    def ended(self) -> int | None:
        """The guard's exit status if it has ended (killed, or it failed to start), else None."""
        if self._pipe is None:
            return None  # released: its end is the orderly one
        return self._proc.poll()

    def beat(self) -> None:
        """After a request: one byte on the pipe, at most every quarter of the
        silence the guard allows; never blocks, never raises."""
        now = time.monotonic()
        if self._pipe is None or now - self._last_beat < self._beat_every:
            return
        try:
            os.write(self._pipe.fileno(), b".")
            self._last_beat = now
        except OSError:  # full (the guard not reading) or closed (it died: `ended` says so)
            pass

    def release(self, wait: float = 1.0) -> None:
        """The orderly end (pumps already at 0): the guard ends without writing."""
        self._end(BYE, wait)

    def hand_over(self, wait: float = 0.0) -> None:
        """The end of the program's control with its pumps NOT confirmed at 0 (its
        write of their stop values failed): the guard writes them now, over its own
        connection, and again until they are written, then ends."""
        self._end(STOP, wait)

    def _end(self, word: bytes, wait: float) -> None:
        if self._pipe is None:
            return
        try:
            self._pipe.write(word)
        except OSError:
            pass
        try:
            self._pipe.close()
        except OSError:
            pass
        self._pipe = None
        try:
            self._proc.wait(wait)
        except subprocess.TimeoutExpired:
            # It ends by itself on the word; as this process's child it is reaped by
            # subprocess (the next Popen, or this Popen's __del__, collects it).
            pass


# --- the guard process ------------------------------------------------------------------------


def _transact(spec: GuardSpec, pdu: bytes, tid: int) -> bytes:
    """One Modbus TCP request on a connection of its own and the answer's PDU;
    OSError, or ValueError for an exception answer."""
    with socket.create_connection((spec.host, spec.port), timeout=spec.timeout) as sock:
        sock.sendall(struct.pack(">HHHB", tid, 0, len(pdu) + 1, spec.device_id) + pdu)
        length = struct.unpack(">HHHB", _recv(sock, 7))[2]
        body = _recv(sock, length - 1)
    if body[0] & 0x80:
        raise ValueError(f"the device answered exception code {body[1] if len(body) > 1 else '?'}")
    return body


def write_registers(spec: GuardSpec, address: int, words: list[int], tid: int) -> None:
    """One Modbus TCP write (function 16) on a connection of its own; OSError or
    ValueError (an exception answer) when it fails."""
    _transact(spec, struct.pack(f">BHHB{len(words)}H", 16, address, len(words), 2 * len(words), *words), tid)


def read_registers(spec: GuardSpec, address: int, count: int, tid: int) -> list[int]:
    """One Modbus TCP read of holding registers (function 3); OSError or ValueError."""
    body = _transact(spec, struct.pack(">BHH", 3, address, count), tid)
    if len(body) < 2 + 2 * count:
        raise ValueError("short answer")
    return list(struct.unpack(f">{count}H", body[2:2 + 2 * count]))


def not_ours(spec: GuardSpec) -> list[str]:
    """The watchdog settings that no longer read as the program armed them (or
    could not be read); empty when they are all still its own."""
    changed = []
    for tid, (what, address, words) in enumerate(spec.ours, start=100):
        try:
            if read_registers(spec, address, len(words), tid) != list(words):
                changed.append(what)
        except (OSError, ValueError) as exc:
            changed.append(f"{what} (unread: {exc or type(exc).__name__})")
    return changed


def _recv(sock: socket.socket, n: int) -> bytes:
    out = b""
    while len(out) < n:
        chunk = sock.recv(n - len(out))
        if not chunk:
            raise ConnectionError("connection closed")
        out += chunk
    return out


def stop_pumps(spec: GuardSpec, writes: list[tuple[str, int, list[int]]]) -> list[str]:
    """Each write (each pump output to its stop value), separately, each tried twice; the errors."""
    errors = []
    for tid, (output, address, words) in enumerate(writes, start=1):
        for attempt in range(2):
            try:
                write_registers(spec, address, words, tid)
                break
            except (OSError, ValueError) as exc:
                if attempt:
                    errors.append(f"{output}: {exc or type(exc).__name__}")
    return errors


class _Watch:
    def __init__(self, spec: GuardSpec, err: IO[str]) -> None:
        self.spec = spec
        self.err = err

    def say(self, text: str) -> None:
        try:
            print(f"{time.strftime('%Y-%m-%d %H:%M:%S')} quadtank guard: {text}", file=self.err, flush=True)
        except OSError:
            pass

    def act(self, why: str, *, gone: bool, tries: int = 1) -> bool:
        """The pumps to 0; when the program is `gone`, its watchdog disarmed after.
        Whether the stop values were written; a failure is said at the first try only."""
        s = self.spec
        outs = ", ".join(w[0] for w in s.writes)
        errors = stop_pumps(s, s.writes)
        if errors:
            if tries == 1:
                self.say(f"{why}; could not set the pumps ({outs}) to 0 at {s.host}:{s.port}: "
                         f"{'; '.join(errors)} - trying again every {RETRY_S:g} s (the device's watchdog, "
                         "if it has one, stops them meanwhile)")
            return False
        disarmed = ""
        if gone and s.disarm:
            changed = not_ours(s)
            if changed:
                disarmed = (f"; its watchdog left as it is: {', '.join(changed[:3])} no longer as armed by "
                            "the program (another program has armed it since?)")
            else:
                disarmed = "; its watchdog disarmed" if not stop_pumps(s, s.disarm) else \
                    "; its watchdog left armed (no answer)"
        again = f" (at try {tries})" if tries > 1 else ""
        self.say(f"{why}; pumps ({outs}) set to 0{again} over the guard's own connection to "
                 f"{s.host}:{s.port}{disarmed}")
        return True

    def until_stopped(self, why: str) -> int:
        """The program is gone (or handed over): the stop tried until it is done, for
        at most GIVE_UP_S; the exit status (1: given up)."""
        end = time.monotonic() + GIVE_UP_S
        tries = 1
        while not self.act(why, gone=True, tries=tries):
            if time.monotonic() >= end:
                self.say(f"gave up after {tries} tries in {GIVE_UP_S:g} s: the pumps may still run")
                return 1
            time.sleep(RETRY_S)
            tries += 1
        return 0


def guard_main(stdin: IO[bytes], err: IO[str]) -> int:
    """Read the spec, watch, act; returns the exit status."""
    fd = stdin.fileno()
    line, heard = _spec_line(fd)
    if not line or BYE.strip() in heard:
        return 0  # nothing to watch, or a program that drove for less than this start and ended in order
    raw = json.loads(line)
    spec = GuardSpec(**{**raw, "writes": [tuple(w) for w in raw["writes"]],
                        "disarm": [tuple(w) for w in raw.get("disarm", [])],
                        "ours": [tuple(w) for w in raw.get("ours", [])]})
    watch = _Watch(spec, err)
    os.set_blocking(fd, False)
    try:
        pidfd: int | None = os.pidfd_open(spec.pid)
    except (AttributeError, OSError):  # gone already, or no pidfd: poll
        pidfd = None
    pipe_open = True
    last_heard = time.monotonic()
    acted_on_silence = False
    retry: tuple[str, int, float] | None = None  # a silence's stop that failed: why, tries, when next
    while True:
        watched = ([fd] if pipe_open else []) + ([pidfd] if pidfd is not None else [])
        ready: list[int] = select.select(watched, [], [], POLL_S)[0] if watched else []
        if not watched:
            time.sleep(POLL_S)
        if fd in ready or not pipe_open or pidfd in ready:
            heard, pipe_open, got = _drain(fd, heard, pipe_open)
            if BYE.strip() in heard:
                return 0  # the orderly end: the program put its pumps at 0 itself
            if STOP.strip() in heard:
                return watch.until_stopped(f"{spec.who} (pid {spec.pid}) ended its control of the rig without "
                                           "its pumps confirmed at 0 (its own write of 0 failed)")
            if got:  # a beat: the program is sampling
                last_heard, acted_on_silence, retry = time.monotonic(), False, None
        state = process_state(spec.pid)
        if not state or (pidfd is not None and pidfd in ready):
            heard, pipe_open, _ = _drain(fd, heard, pipe_open)
            if BYE.strip() in heard:
                return 0
            return watch.until_stopped(f"{spec.who} (pid {spec.pid}) ended without stopping its pumps "
                                       "(killed, or it crashed)")
        silent = time.monotonic() - last_heard
        if not acted_on_silence and silent >= spec.gap:
            how = {"T": "stopped", "t": "stopped by a debugger", "D": "frozen (uninterruptible sleep)"}.get(
                state, "running but not sampling (a deadlocked loop?)")
            why = (f"{spec.who} (pid {spec.pid}) has not been heard from for {silent:.1f} s, longer than "
                   f"the watchdog timeout {spec.gap:g} s: {how}")
            done = watch.act(why, gone=False)
            acted_on_silence = True  # once per silence: if it comes back, it finds the gap and pauses
            retry = None if done else (why, 2, time.monotonic() + RETRY_S)
        elif retry is not None and time.monotonic() >= retry[2]:  # still silent: the failed stop again
            why, tries, _ = retry
            retry = None if watch.act(why, gone=False, tries=tries) else (why, tries + 1, time.monotonic() + RETRY_S)


def _spec_line(fd: int) -> tuple[bytes, bytes]:
    """The spec's line, read from the pipe itself, and what followed it in the same
    reads (kept short).  Not a buffered readline: the bytes behind the line stayed in
    its buffer, out of reach of the watch's os.read, and a program that wrote its bye
    before this process had started (an Active run of a few samples, a fault at
    once) went unheard: the guard watched on until the program ended, then wrote
    the stop values to a rig someone else may be driving by then (7 such guards
    outlived their tests in a run of tests/daq)."""
    data = b""
    while b"\n" not in data:
        chunk = os.read(fd, 65536)
        if not chunk:
            break
        data += chunk
    line, _, rest = data.partition(b"\n")
    return line, rest[-64:]


def _drain(fd: int, heard: bytes, pipe_open: bool) -> tuple[bytes, bool, bool]:
    """What the program wrote since (kept short), whether the pipe is still open,
    and whether anything was read."""
    if not pipe_open:
        return heard, False, False
    got = False
    try:
        while True:
            chunk = os.read(fd, 4096)
            if not chunk:
                return heard, False, got
            heard, got = (heard + chunk)[-64:], True
    except BlockingIOError:
        return heard, True, got
    except OSError:
        return heard, False, got


if __name__ == "__main__":  # pragma: no cover - the guard process
    import signal

    for sig in (signal.SIGINT, signal.SIGHUP, signal.SIGTSTP):
        signal.signal(sig, signal.SIG_IGN)
    raise SystemExit(guard_main(sys.stdin.buffer, sys.stderr))
