"""A virtual rig in a subprocess on loopback, for the tests that need a real link.

The rig binds port 0 (a free port, chosen by the OS, no race) unless a port is
given, and prints the address it serves on its first line; the helper waits for
that line (with a timeout) instead of sleeping.
"""

from __future__ import annotations

import dataclasses
import queue
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any, Callable, Iterator

import pytest
from pymodbus.client import ModbusTcpClient

from quadtank_tui.daq.config import DaqConfig, load_daq_config
from quadtank_tui.daq.registers import decode
from quadtank_tui.daq.server import ModbusTcpServer

# The tests import daqkit's helpers by name (pytest's importlib mode does not put
# the test folder on sys.path).
sys.path.insert(0, str(Path(__file__).parent))

from daqkit import DAC, LINK_TIMEOUT, VIRTUAL_RIG, FixedBank  # noqa: E402


class RigProcess:
    """`quadtank rig ...` running; `lines` collects its stdout."""

    def __init__(self, *args: str, port: int = 0, full_cli: bool = False) -> None:
        # `python -m quadtank_tui.commands.daq rig` is the same command through
        # its module's own entry point; one test starts the full `quadtank rig`.
        entry = "quadtank_tui" if full_cli else "quadtank_tui.commands.daq"
        cmd = [sys.executable, "-m", entry, "rig", "--port", str(port),
               "--map", str(VIRTUAL_RIG), *args]
        self.proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        self.lines: queue.Queue[str] = queue.Queue()
        self.seen: list[str] = []
        threading.Thread(target=self._pump, daemon=True).start()
        first = self.wait_for("serving on", timeout=60.0)
        self.port = int(first.split("serving on ")[1].split()[0].rsplit(":", 1)[1])

    def _pump(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            self.lines.put(line.rstrip("\n"))

    def wait_for(self, text: str, timeout: float) -> str:
        """The first line (seen or coming) containing `text`."""
        for line in self.seen:
            if text in line:
                return line
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            try:
                line = self.lines.get(timeout=0.1)
            except queue.Empty:
                if self.proc.poll() is not None and self.lines.empty():
                    err = self.proc.stderr.read() if self.proc.stderr else ""
                    raise AssertionError(f"rig exited ({self.proc.returncode}): {err}")
                continue
            self.seen.append(line)
            if text in line:
                return line
        raise AssertionError(f"rig did not print {text!r} within {timeout} s; got {self.seen}")

    def config(self, **changes: object) -> DaqConfig:
        """The virtual-rig configuration pointed at this rig (LINK_TIMEOUT unless given)."""
        options: dict[str, object] = {"host": "127.0.0.1", "port": self.port, "timeout": LINK_TIMEOUT, **changes}
        return dataclasses.replace(load_daq_config(VIRTUAL_RIG), **options)  # type: ignore[arg-type]

    def dacs(self) -> tuple[float, float]:
        """The two pump registers as the rig holds them, read by a client of its own."""
        client = ModbusTcpClient("127.0.0.1", port=self.port, timeout=2.0)
        try:
            rr = client.read_holding_registers(1000, count=4, device_id=1)
            assert not rr.isError(), rr
            return decode(DAC, rr.registers[:2]), decode(DAC, rr.registers[2:])
        finally:
            client.close()

    def kill(self) -> None:
        """SIGKILL: the rig vanishes as a crashed or unplugged device would."""
        if self.proc.poll() is None:
            self.proc.kill()
        self.proc.wait(timeout=10)

    def stop(self) -> None:
        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(timeout=10)


@pytest.fixture
def rig() -> Iterator[Callable[..., RigProcess]]:
    """Start rigs with `rig(*args, port=0, full_cli=False)`; all stopped after the test."""
    started: list[RigProcess] = []

    def start(*args: str, port: int = 0, full_cli: bool = False) -> RigProcess:
        r = RigProcess(*args, port=port, full_cli=full_cli)
        started.append(r)
        return r

    yield start
    for r in started:
        r.stop()


class LinkProxy:
    """A TCP relay between the program and a rig whose cable can be "cut": while
    cut, it accepts and holds connections but forwards nothing (a switch that died,
    a cable pulled out: no reset, just silence).  Threads, loopback only."""

    def __init__(self, target_port: int) -> None:
        import socket

        self.target = ("127.0.0.1", target_port)
        self.cut = threading.Event()
        self._listener = socket.create_server(("127.0.0.1", 0))
        self.port = self._listener.getsockname()[1]
        self._closing = False
        self._socks: list[socket.socket] = []
        threading.Thread(target=self._accept, daemon=True).start()

    def _accept(self) -> None:
        import socket

        while not self._closing:
            try:
                client, _ = self._listener.accept()
            except OSError:
                return
            self._socks.append(client)
            try:
                upstream = socket.create_connection(self.target, timeout=2.0)
            except OSError:
                client.close()
                continue
            self._socks.append(upstream)
            for a, b in ((client, upstream), (upstream, client)):
                threading.Thread(target=self._relay, args=(a, b), daemon=True).start()

    def _relay(self, src, dst) -> None:
        try:
            while True:
                data = src.recv(4096)
                if not data:
                    break
                if not self.cut.is_set():
                    dst.sendall(data)
        except OSError:
            pass

    def close(self) -> None:
        self._closing = True
        for s in [self._listener, *self._socks]:
            try:
                s.close()
            except OSError:
                pass


@pytest.fixture
def link_proxy() -> Iterator[Callable[[int], LinkProxy]]:
    made: list[LinkProxy] = []

    def make(port: int) -> LinkProxy:
        p = LinkProxy(port)
        made.append(p)
        return p

    yield make
    for p in made:
        p.close()


class Device:
    """A Modbus TCP device in this process (our server on a thread of its own) over a
    FixedBank, or over `bank` (a VirtualRig on a clock of the test's); `reply_delay` s
    before each answer."""

    def __init__(self, volts: tuple[float, float, float, float], reply_delay: float = 0.0,
                 bank: Any = None) -> None:
        import asyncio

        self.bank = FixedBank(volts) if bank is None else bank
        self._loop = asyncio.new_event_loop()
        self._server = ModbusTcpServer(self.bank, reply_delay=reply_delay)
        self.port = self._loop.run_until_complete(self._server.start("127.0.0.1", 0))[1]
        self._thread = threading.Thread(target=self._loop.run_forever, daemon=True)
        self._thread.start()

    def config(self, **changes: object) -> DaqConfig:
        """The virtual-rig configuration pointed at this device; over a FixedBank,
        which has no watchdog registers, one saying so (`watchdog: none`)."""
        options: dict[str, object] = {"host": "127.0.0.1", "port": self.port, "timeout": LINK_TIMEOUT, **changes}
        if isinstance(self.bank, FixedBank):
            options.setdefault("watchdog", None)
        return dataclasses.replace(load_daq_config(VIRTUAL_RIG), **options)  # type: ignore[arg-type]

    def close(self) -> None:
        import asyncio

        asyncio.run_coroutine_threadsafe(self._server.stop(), self._loop).result(timeout=10)
        self._loop.call_soon_threadsafe(self._loop.stop)
        self._thread.join(timeout=10)
        self._loop.close()


@pytest.fixture
def device() -> Iterator[Callable[..., Device]]:
    """Start in-process devices with `device(volts, reply_delay=0.0, bank=None)`; closed after."""
    made: list[Device] = []

    def make(volts: tuple[float, float, float, float], reply_delay: float = 0.0, bank: Any = None) -> Device:
        d = Device(volts, reply_delay, bank)
        made.append(d)
        return d

    yield make
    for d in made:
        d.close()


class SilentDevice:
    """Accepts connections and never answers: a hung device (a PLC stuck in its
    program, a gateway whose far side is gone)."""

    def __init__(self) -> None:
        import socket

        self._listener = socket.create_server(("127.0.0.1", 0))
        self.port = self._listener.getsockname()[1]
        self._held: list[socket.socket] = []
        threading.Thread(target=self._accept, daemon=True).start()

    def _accept(self) -> None:
        while True:
            try:
                conn, _ = self._listener.accept()
            except OSError:
                return
            self._held.append(conn)

    def close(self) -> None:
        for s in [self._listener, *self._held]:
            try:
                s.close()
            except OSError:
                pass


@pytest.fixture
def silent_device() -> Iterator[SilentDevice]:
    d = SilentDevice()
    yield d
    d.close()


@pytest.fixture(autouse=True)
def _no_guard_outlives_its_test(guards_of_this_test: object) -> None:
    """A test against a dead or hung device leaves a guard retrying its stop for up
    to 2 minutes (daq/guard.py GIVE_UP_S): the test's own guards end with it."""
