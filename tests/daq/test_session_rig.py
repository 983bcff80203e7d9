"""An Active session on the virtual rig (a real Modbus link on loopback): the pumps
at 0 when the session stops in order, and when it is killed (SIGKILL: it cannot
stop in order, so its operator's client commands the pumps to 0 over a link of its
own, as the TUI did for its loop process; the rig's watchdog is off here)."""

from __future__ import annotations

import contextlib
import os
import signal
import time
from pathlib import Path
from typing import Callable

import pytest

from quadtank_tui.engine.commands import SetOperation, SetParams, SetState
from quadtank_tui.engine.runner import engine_spec
from quadtank_tui.session.client import SessionClient, SessionError, stop_session_at
from quadtank_tui.session.launch import SessionSpec, start_session
from quadtank_tui.session.protocol import Hello, encode
from daqkit import rig_yaml

ROOT = Path(__file__).parents[2]


def _active_session(rig: Callable, tmp_path: Path):
    r = rig("--speed", "1", "--watchdog", "0")
    config = tmp_path / "rig.yaml"
    config.write_text(rig_yaml(r.port))
    spec = engine_spec(clock="realtime", params_dir=tmp_path / "params", logs_dir=tmp_path / "logs")
    info = start_session(SessionSpec(spec, str(tmp_path / "run"), str(config)))
    client = SessionClient(info.socket)
    for command in (SetOperation("Active"), SetParams({"REFERENCE ONE.Mean": 0.4}), SetState("Run")):
        assert client.submit(command).result(timeout=10).ok
    deadline = time.monotonic() + 60
    while r.dacs()[0] == 0.0 and time.monotonic() < deadline:
        time.sleep(0.05)
    assert r.dacs()[0] == pytest.approx(4.0, abs=1e-4)
    return r, info, client


def test_stopping_an_active_session_puts_the_pumps_at_0(rig: Callable, tmp_path: Path) -> None:
    r, info, client = _active_session(rig, tmp_path)
    try:
        assert client.snapshot().operation == "Active"
        assert stop_session_at(info.socket).startswith("stopped by ")
        assert r.dacs() == (0.0, 0.0)
    finally:
        client.close()


def test_a_killed_active_session_gets_its_pumps_to_0_from_the_client(rig: Callable, tmp_path: Path) -> None:
    r, info, client = _active_session(rig, tmp_path)
    try:
        os.kill(info.pid, signal.SIGKILL)
        assert client.wait_gone(30)
        deadline = time.monotonic() + 60
        while client.rescue is None and time.monotonic() < deadline:
            time.sleep(0.05)
        fault = client.snapshot().fault or ""
        assert f"the session process {info.id} (pid {info.pid}) stopped unexpectedly" in fault
        assert "the pumps were commanded to 0 from this client" in fault
        assert r.dacs() == (0.0, 0.0)
    finally:
        client.close()


def test_a_dropped_operator_leaves_the_pumps_to_the_session_that_runs_on(
        rig: Callable, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The operator's client floods, then a second one sends a line that is not a
    message: each is dropped and told why, neither commands the pumps to 0 (the
    session drives them on, as its lab's policy says for 10 minutes without an
    operator: before, the client took the closed connection for the session's
    death and wrote 0 to the rig over its own link)."""
    lab = tmp_path / "lab.yaml"
    lab.write_text("unattended:\n  grace_minutes: 10\n")
    monkeypatch.setenv("QUADTANK_LAB", str(lab))
    r, info, client = _active_session(rig, tmp_path)
    second = None
    stopped = False
    try:
        burst = encode(Hello("operator", "tui")) * 400  # lines the session ignores at once: the rate decides
        try:
            while not client.gone:
                client._sock.sendall(burst)
        except OSError:
            pass
        assert client.wait_gone(30)
        second = SessionClient(info.socket)
        assert second.role == "operator"
        second._sock.sendall(b"not a message\n")
        assert second.wait_gone(30)
        with SessionClient(info.socket, role="observer") as observer:
            k = observer.snapshot().k
            deadline = time.monotonic() + 30
            while observer.snapshot().k < k + 5 and time.monotonic() < deadline:
                time.sleep(0.05)
            snap = observer.snapshot()
            assert snap.state == "Run" and snap.operation == "Active" and snap.k >= k + 5
        assert r.dacs()[0] == pytest.approx(4.0, abs=1e-4)
        assert client.rescue is None and second.rescue is None
        assert client.dropped is not None and client.dropped.startswith("it sent lines faster than")
        assert second.dropped is not None and second.dropped.startswith("it sent a line that is not a message")
        assert stop_session_at(info.socket).startswith("stopped by ")
        stopped = True
    finally:
        client.close()
        if second is not None:
            second.close()
        if not stopped:  # failed on the way: the session must not outlive the test
            with contextlib.suppress(SessionError):
                stop_session_at(info.socket)
