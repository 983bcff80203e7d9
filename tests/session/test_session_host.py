"""The session host on a thread, its clients on loopback sockets: attach, detach and
re-attach during a logged run; the operator / observer / administrator rules; the
protocol's refusal of anything that is not one of its messages.

The peers' user ids are the tests' own (conftest.Peers stands in for SO_PEERCRED):
alice owns the session, bob is another student, teacher is an administrator.
"""

from __future__ import annotations

import json
import socket
import time
from pathlib import Path

import numpy as np
import pytest
from sessionkit import STUDENT, TEACHER, Rig, ThreadSession

from quadtank_tui.engine import commands as c
from quadtank_tui.engine.handle import SIGNALS
from quadtank_tui.files.log_reader import read_log
from quadtank_tui.session.client import SessionClient, SessionError, stop_session_at
from quadtank_tui.session.policy import UnattendedPolicy, describe
from quadtank_tui.session.protocol import (
    Hello, ProtocolError, Submit, Welcome, decode, encode,
)
from quadtank_tui.session.runtime import list_sessions


def wait_for(predicate, timeout: float = 60.0, what: str = "") -> None:
    end = time.monotonic() + timeout
    while not predicate():
        if time.monotonic() > end:
            raise AssertionError(f"timed out waiting for {what or predicate}")
        time.sleep(0.01)


def ok(client: SessionClient, command: c.Command) -> None:
    result = client.submit(command).result(10)
    assert result.ok, result.message


def test_attach_detach_reattach_during_a_logged_run(thread_session, tmp_path: Path) -> None:
    """A log of 3000 rows (300 s of process time at 0.1 s) runs while no client is
    attached most of the time: the saved .log has every row, one sampling time
    apart, and the trends a client shows after re-attaching are the session's:
    equal to a fresh client's and, row by row, to the log's values."""
    s: ThreadSession = thread_session(speed=500.0)
    points, h = 3000, 0.1
    first = SessionClient(s.path)
    assert first.role == "operator" and len(first.history()["t"]) == 0
    ok(first, c.SetState("Run"))
    ok(first, c.SetParams({"REFERENCE ONE.Wave": "Square", "REFERENCE ONE.Amplitude": 0.05,
                           "REFERENCE ONE.Period": 40.0}))
    ok(first, c.LogOn(points=points))
    wait_for(lambda: first.snapshot().log.rows > 100, what="the first rows")
    first.close()  # detached mid-log: the session goes on
    assert s.thread.is_alive()
    wait_for(lambda: s.engine.snapshot().log.rows > 1000, what="rows while detached")
    second = SessionClient(s.path)  # re-attached
    at_attach = second.snapshot().log.rows
    assert 1000 < at_attach < points
    wait_for(lambda: not second.snapshot().log.active, what="the log to complete")
    ok(second, c.SetState("Pause"))
    ok(second, c.LogSave("detached"))
    log = read_log(tmp_path / "logs" / "detached.log")
    assert log.rows == points
    assert log.tsamp == pytest.approx(h)
    # The trends after re-attach equal the session's history (a fresh client's copy).
    third = SessionClient(s.path, role="observer")
    seen, fresh = second.history(), third.history()
    assert len(seen["t"]) == len(fresh["t"]) == s.engine.snapshot().k
    for name in SIGNALS:
        np.testing.assert_array_equal(seen[name], fresh[name])
    hist = s.engine.history()
    np.testing.assert_array_equal(seen["y1"], hist["y1"])
    # ... and every logged row is in them, consecutive samples h apart.
    cols = log.columns()
    names = ("y1", "y2", "u1", "u2")
    logged = np.column_stack([cols[n] for n in names])
    trend = np.column_stack([seen[n] for n in names])
    first_row = np.flatnonzero(np.all(np.abs(trend - logged[0]) <= 5e-7, axis=1))
    matches = [k for k in first_row if k + points <= len(trend)
               and np.allclose(trend[k:k + points], logged, atol=5e-7, rtol=0)]
    assert len(matches) == 1, matches
    k0 = matches[0]
    assert np.allclose(np.diff(seen["t"][k0:k0 + points]), h)
    for cl in (second, third):
        cl.close()


def test_the_first_client_is_live_at_once_with_the_whole_history(thread_session) -> None:
    s = thread_session(speed=1000.0)
    with SessionClient(s.path) as a:
        ok(a, c.SetState("Run"))
        wait_for(lambda: a.snapshot().k > 2000, what="2000 samples")
        ok(a, c.SetState("Pause"))
        t0 = time.monotonic()
        with SessionClient(s.path, role="observer") as b:
            took = time.monotonic() - t0
            assert len(b.history()["t"]) == b.snapshot().k == a.snapshot().k
            assert b.snapshot().params == a.snapshot().params
        assert took < 1.0


def test_a_reset_clears_the_clients_trends(thread_session) -> None:
    s = thread_session(speed=1000.0)
    with SessionClient(s.path) as a:
        ok(a, c.SetState("Run"))
        wait_for(lambda: len(a.history()["t"]) > 200)
        ok(a, c.SetState("Reset"))
        wait_for(lambda: len(a.history()["t"]) == len(s.engine.history()["t"]))
        assert len(a.history()["t"]) == 0 and a.snapshot().k == 0


def test_an_observer_is_refused_every_command_and_sees_who_controls(thread_session) -> None:
    s = thread_session()
    with SessionClient(s.path) as op, SessionClient(s.path, role="observer") as obs:
        wait_for(lambda: obs.clients == 2)
        result = obs.submit(c.SetState("Run")).result(30)
        assert not result.ok and "read-only" in result.message and "alice" in result.message
        assert "alice (pid" in obs.session_banner() and "read-only" in obs.session_banner()
        assert "you operate it" in op.session_banner()
        # The session refuses too, whatever a client claims to be.
        raw = socket.socket(socket.AF_UNIX)
        raw.connect(str(s.path))
        raw.sendall(encode(Hello("observer")))
        _read_welcome(raw)
        raw.sendall(encode(Submit(7, c.SetState("Run"))))
        answer = _read_until(raw, "Result")
        assert answer["id"] == 7 and answer["result"]["ok"] is False
        assert "read-only" in answer["result"]["message"]
        raw.close()
        assert s.engine.snapshot().state == "Pause"


def test_a_second_operator_is_refused(thread_session) -> None:
    s = thread_session()
    with SessionClient(s.path):
        s.peers.queue = [TEACHER]  # may connect (an administrator), asks to operate without --take-over
        with pytest.raises(SessionError, match=r"alice-1 is operated by alice \(pid \d+\) since \d\d:\d\d.*--observe"):
            SessionClient(s.path)
        with pytest.raises(SessionError, match=r"is operated by alice .*--take-over alice-1. takes it from your "
                           "other client"):
            SessionClient(s.path)  # alice again, from another terminal


def test_the_operators_own_user_may_take_over_from_its_other_client(thread_session) -> None:
    """A screen left on an SSH link that died unnoticed holds the operator's place:
    its user takes it back with --take-over (no administrator needed)."""
    s = thread_session()
    with SessionClient(s.path) as stale, SessionClient(s.path, take_over=True) as fresh:
        assert fresh.role == "operator"
        wait_for(lambda: stale.role == "observer")
        ok(fresh, c.SetState("Run"))


def test_a_student_cannot_take_over_nor_stop_an_administrator_can(thread_session) -> None:
    s = thread_session()
    with SessionClient(s.path) as alice:
        s.peers.queue = [STUDENT]
        with pytest.raises(SessionError, match="belongs to alice; you are bob"):
            SessionClient(s.path, take_over=True)
        s.peers.queue = [STUDENT]
        with pytest.raises(SessionError, match="you are bob"):
            stop_session_at(s.path)
        s.peers.queue = [TEACHER]
        teacher = SessionClient(s.path, take_over=True)
        assert teacher.role == "operator"
        wait_for(lambda: alice.role == "observer", what="alice to be told")
        assert "teacher" in alice.session_banner()
        refused = alice.submit(c.SetState("Run")).result(30)
        assert not refused.ok and "teacher" in refused.message
        ok(teacher, c.SetState("Run"))
        s.peers.queue = [TEACHER]
        assert "stopped by teacher" == stop_session_at(s.path)
        s.thread.join(10)
        assert s.reason == "stopped by teacher"
        wait_for(lambda: alice.gone and teacher.gone)
        assert "ended: stopped by teacher" in (alice.snapshot().fault or "")
        teacher.close()
    assert not s.path.exists() and list_sessions(s.runtime) == []


def test_the_owner_stops_the_session_pumps_at_0_log_kept(thread_session, tmp_path: Path) -> None:
    s = thread_session(speed=1000.0)
    with SessionClient(s.path) as a:
        ok(a, c.SetState("Run"))
        ok(a, c.LogOn(points=100000))
        wait_for(lambda: a.snapshot().log.rows > 50)
    assert stop_session_at(s.path) == "stopped by alice"
    s.thread.join(10)
    snap = s.engine.snapshot()
    assert snap.state == "Pause" and snap.u == (0.0, 0.0) or snap.state == "Pause"
    partial = list((tmp_path / "logs").glob("*.partial"))
    assert partial and read_log(partial[0]).rows > 50  # the unsaved rows are kept
    # No socket; the record stays, saying why and when it ended.
    assert sorted(p.name for p in s.runtime.iterdir()) == ["alice-1.json"]
    # (the thread session's "alice" is uid 1000 with a record of root's: the
    # listing, which believes the file's owner, counts it for no one; read it)
    ended = json.loads((s.runtime / "alice-1.json").read_text())
    assert ended["ended"] == "stopped by alice" and ended["ended_at"] and ended["clients"] == 0


def test_the_record_lists_the_session(thread_session) -> None:
    s = thread_session()
    with SessionClient(s.path) as a:
        ok(a, c.SetState("Run"))
        ok(a, c.LogOn(points=1000000))
        wait_for(lambda: json.loads((s.runtime / "alice-1.json").read_text())["clients"] == 1)
        wait_for(lambda: "%" in json.loads((s.runtime / "alice-1.json").read_text())["logging"])
        record = json.loads((s.runtime / "alice-1.json").read_text())
        assert record["state"] == "Run" and record["operator"] == "alice" and record["operation"] == "Simul"


def test_unattended_active_session_keeps_logging_then_pauses_pumps_at_0(thread_session) -> None:
    """The lab's policy (keep while logging, then a grace of 0.6 s): detached mid-log,
    the Active session logs every row, then pauses with the pumps at 0."""
    rig = Rig()
    policy = UnattendedPolicy(keep_while_logging=True, grace_minutes=0.01)
    s = thread_session(speed=200.0, daq=rig, policy=policy)
    points, detached = 4000, 3000
    with SessionClient(s.path) as a:
        ok(a, c.SetOperation("Active"))
        assert a.policy == describe(policy, active=True) and "0.01 minutes" in a.policy
        ok(a, c.SetParams({"REFERENCE ONE.Mean": 0.4}))
        ok(a, c.SetState("Run"))
        ok(a, c.LogOn(points=points))  # 400 s at 0.1 s: 2 s of wall time at x200
        # Held mid-log once it has run detached for 3000 samples: at x200 at least
        # 1.5 s, so the policy (looked at every second) has been asked while logging.
        rig.hold_after(detached)
    assert rig.held.wait(60), "the session stopped sampling while detached"
    snap = s.engine.snapshot()
    assert snap.state == "Run" and snap.log.active and detached - 1 <= snap.log.rows < points
    assert rig.pumps != (0.0, 0.0)
    rig.release.set()
    wait_for(lambda: s.engine.snapshot().state == "Pause", timeout=60, what="the policy's pause")
    snap = s.engine.snapshot()
    assert snap.log.rows == points and rig.pumps == (0.0, 0.0) and rig.safe_states >= 1
    # The record is written just after the pause: wait for it, not for the state.
    wait_for(lambda: "unattended" in json.loads((s.runtime / "alice-1.json").read_text())["note"],
             what="the record to say why it paused")


def test_unattended_active_session_without_a_policy_pauses_pumps_at_0(thread_session) -> None:
    """No lab policy: the client leaves mid-log and the Active session pauses with
    the pumps at 0 (its rows kept), at the next look at the policy."""
    rig = Rig()
    s = thread_session(speed=200.0, daq=rig)
    with SessionClient(s.path) as a:
        ok(a, c.SetOperation("Active"))
        assert a.policy == "Unattended, an Active session pauses with the pumps at 0 as soon as the last client leaves."
        ok(a, c.SetParams({"REFERENCE ONE.Mean": 0.4}))
        ok(a, c.SetState("Run"))
        ok(a, c.LogOn(points=100000))
        wait_for(lambda: rig.pumps != (0.0, 0.0), what="pumps on")
    wait_for(lambda: s.engine.snapshot().state == "Pause", timeout=60, what="the pause without a policy")
    snap = s.engine.snapshot()
    assert rig.pumps == (0.0, 0.0) and snap.log.rows > 0


def test_unattended_simul_session_keeps_running(thread_session) -> None:
    s = thread_session(speed=200.0, policy=UnattendedPolicy(keep_while_logging=False, grace_minutes=0.0))
    with SessionClient(s.path) as a:
        assert a.policy == describe(UnattendedPolicy(), active=False)
        ok(a, c.SetState("Run"))
    k = s.engine.snapshot().k
    time.sleep(1.5)  # the policy is looked at every second
    assert s.engine.snapshot().state == "Run" and s.engine.snapshot().k > k


def test_garbage_drops_the_client_not_the_session(thread_session) -> None:
    s = thread_session()
    for junk in (b"not json\n", b'{"@": "os.system", "command": "true"}\n',
                 b'{"@": "Welcome"}\n', b'\x80\x04\x95pickle\n', b"x" * (2 << 20)):
        raw = socket.socket(socket.AF_UNIX)
        raw.connect(str(s.path))
        raw.settimeout(5)
        try:
            raw.sendall(junk)
            assert raw.recv(100) == b""  # hung up on
        except (BrokenPipeError, ConnectionResetError):  # hung up on while still sending
            pass
        raw.close()
    with SessionClient(s.path) as a:
        ok(a, c.SetState("Run"))


@pytest.mark.parametrize("line", [
    b'{"@": "Submit", "id": 1, "command": {"@": "Parameters"}}',
    b'{"@": "Submit", "id": 1, "command": {"@": "SetState", "state": "Run", "evil": 1}}',
    b'{"@": "subprocess.Popen", "args": ["sh"]}',
    b'{"@": "Hello", "role": {"@": "enum", "t": "Path", "v": "/"}}',
    b'{"@": "Submit", "id": 1, "command": {"@": "StopSession"}}',
])
def test_decode_refuses_what_is_not_a_message(line: bytes) -> None:
    with pytest.raises(ProtocolError):
        decode(line, (Hello, Submit))


def test_commands_round_trip() -> None:
    commands: list[c.Command] = [c.SetParams({"CONTROLLER ONE.K": 3.0, "CONTROL.Type": "PID"}), c.SetDefaults(("A.b", "C.d")),
                c.ResetControllers((1, 2)), c.ResetControllers(None), c.LogOn(None), c.LogSave("x", True),
                c.SetSpeed(2.5), c.AddWater(3, -0.1), c.SetFault("leak", 2, 0.5, False)]
    for command in commands:
        assert decode(encode(Submit(3, command))) == Submit(3, command)


def _read_welcome(sock: socket.socket) -> None:
    assert _read_until(sock, "Welcome")["@"] == "Welcome"


def _read_until(sock: socket.socket, tag: str) -> dict:
    buf = b""
    sock.settimeout(10)
    while True:
        while b"\n" not in buf:
            data = sock.recv(1 << 20)
            assert data, f"closed before {tag}"
            buf += data
        line, buf = buf.split(b"\n", 1)
        obj = json.loads(line)
        if obj["@"] == tag:
            if tag == "Welcome":
                assert isinstance(decode(line), Welcome)
            return obj


@pytest.mark.parametrize("par, values", [
    ("default", {"CONTROL.Type": "State feedback"}),  # complex poles, the lazily known StateFeedbackInfo
    ("coupled-tito", {}),  # another plant (PLANT section: PlantSpec)
])
def test_snapshots_round_trip_exactly(par: str, values: dict, tmp_path: Path) -> None:
    from quadtank_tui.engine.runner import build_engine
    from quadtank_tui.session.protocol import Update

    root = Path(__file__).parents[2] / "params"
    engine = build_engine(str(root / f"{par}.par"), clock="manual", params_dir=root, logs_dir=tmp_path)
    if values:
        assert engine.submit(c.SetParams(values)).result().ok
    assert engine.submit(c.SetState("Run")).result().ok
    snap = engine.step(20)
    rows = np.column_stack([engine.history()[n] for n in SIGNALS])
    back = decode(encode(Update(snap, rows)))
    assert back.snapshot == snap and (back.snapshot.statefb is not None) == (par == "default")
    np.testing.assert_array_equal(back.rows, rows)
    engine.stop()
