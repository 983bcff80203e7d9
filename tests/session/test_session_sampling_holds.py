"""What a client does never holds the session's sampling back (found by a review of
issue 25): a read-only observer flooding Submits, a command whose file work waits
for a slow disk, attaches with a full ring buffer.  Each case runs a session on a
wall-paced clock (virtual x1, TSamp 100 ms as default.par) and asserts on the
driver's own LoopStats: no sampling slot skipped, and no sample later than h/2
(the quiet session's worst on a loaded 2-core machine is 10-15 ms), in a first run
of the case or in a second on a new session (_held).  Before the
fixes: 1 s stalls (the flood), 1 s (LogSave with fsync at 0.4 s), 100-200 ms per
attach."""

from __future__ import annotations

import json
import os
import socket
import threading
import time
from typing import Callable, Iterator

import numpy as np
import pytest
from sessionkit import OWNER, STUDENT, ThreadSession

from quadtank_tui.engine import commands as c
from quadtank_tui.engine.handle import SIGNALS
from quadtank_tui.session import host as host_module
from quadtank_tui.session.client import SessionClient, connect
from quadtank_tui.session.host import Access
from quadtank_tui.session.protocol import Hello, Submit, encode
from quadtank_tui.session.server import MAX_LINE_BURST, MAX_LINE_RATE


# The tests that check the sampling are marked `alone` (tests/conftest.py: no other
# test runs beside them under pytest-xdist): the session is a thread of the test's
# process, and with another wallclock test beside it (its TUI drawing, its session's
# thread at real-time priority) the slow-disk case saw a sample 53 ms late in a -n 2
# run at load 5.
def _stall(s: ThreadSession) -> str | None:
    """Why the sampling did not hold (a slot skipped, a sample late by h/2), or None."""
    stats, h = s.engine.snapshot().stats, s.engine.sampling_time
    s.stop()
    if stats.skipped == 0 and stats.jitter_max < h / 2:
        return None
    return f"skipped {stats.skipped}, overruns {stats.overruns}, jitter_max {stats.jitter_max * 1e3:.0f} ms"


def _held(scenario: Callable[[], ThreadSession]) -> None:
    """The sampling held through `scenario` (which returns its session), or through a
    second run of it on a new session.  Alone, the machine still stalls a process now
    and then: one sample 156 ms late in the burst case in a CI run (stop 37), one
    74 ms late in the flooding case in a local run, each passing in every run since;
    what these tests guard against (the host working for the client on the sampling's
    thread) stalled every run, for 0.3-1 s."""
    first = _stall(scenario())
    if first is not None:
        second = _stall(scenario())
        assert second is None, f"the sampling did not hold, twice: {first}; then {second}"


def _observer(s: ThreadSession) -> socket.socket:
    sock = socket.socket(socket.AF_UNIX)
    sock.settimeout(10)
    connect(sock, s.path, 10)
    sock.sendall(encode(Hello("observer", "test")))
    return sock


def _lines(sock: socket.socket) -> Iterator[bytes]:
    """The lines the session sends, until it hangs up."""
    buf = b""
    while True:
        data = sock.recv(1 << 20)
        if not data:
            return
        buf += data
        *lines, buf = buf.split(b"\n")
        yield from lines


def _count(sock: socket.socket, tag: str, until: int, counted: list[int]) -> None:
    """Read `sock` (a thread), counting the lines of message `tag`, until `until` or closed."""
    start = b'{"@":"%s"' % tag.encode()
    try:
        for line in _lines(sock):
            counted[0] += line.startswith(start)
            if counted[0] >= until:
                return
    except OSError:
        return


@pytest.mark.wallclock
@pytest.mark.alone  # a sample late by h/2 at most: see _held
def test_a_burst_of_refused_submits_is_answered_without_holding_a_sample(thread_session) -> None:
    """900 Submits from an observer in one write (within the burst allowed): each is
    refused, none forces an update to every client, and they are handled a few per
    event-loop turn.  Before: all in one read's callback, each with an update and a
    record check: 0.3-0.5 ms each, a stall of a few hundred ms."""
    def scenario() -> ThreadSession:
        s: ThreadSession = thread_session(speed=1.0)
        sock = _observer(s)
        n = MAX_LINE_BURST - 100
        answered = [0]
        reader = threading.Thread(target=_count, args=(sock, "Result", n, answered), daemon=True)
        reader.start()
        time.sleep(0.3)
        sock.sendall(encode(Submit(1, c.NudgeMean(1, 0.0))) * n)
        reader.join(15)
        assert answered[0] == n
        assert any(conn.role == "observer" for conn in s.host.server.connections)  # within the rate: kept
        sock.close()
        return s
    _held(scenario)


@pytest.mark.wallclock
@pytest.mark.alone  # a sample late by h/2 at most: see _held
def test_a_flooding_observer_is_dropped_and_the_sampling_holds(thread_session, capfd) -> None:
    """An observer writing Submits as fast as it can (the review's: 10000 in 5 s held
    the sampling 1 s) goes within a second, and the session's output says why; the
    operator is not disturbed."""
    def scenario() -> ThreadSession:
        s: ThreadSession = thread_session(speed=1.0)
        s.host.access._may_connect = lambda uid: True  # bob may observe
        with SessionClient(s.path) as alice:
            assert alice.submit(c.SetState("Run")).result(10).ok
            s.peers.queue.append(STUDENT)
            sock = _observer(s)
            threading.Thread(target=_count, args=(sock, "-", 1, [0]), daemon=True).start()  # drain it
            burst = encode(Submit(1, c.NudgeMean(1, 0.0))) * 800
            t0 = time.monotonic()
            with pytest.raises(OSError):  # the session hung up on it
                while time.monotonic() - t0 < 4.0:
                    sock.sendall(burst)
            assert time.monotonic() - t0 < 2.0
            sock.close()
            assert alice.submit(c.SetState("Pause")).result(10).ok
        err = capfd.readouterr().err
        assert "dropped bob (pid " in err and f"faster than {MAX_LINE_RATE:g} a second" in err, err
        return s
    _held(scenario)


@pytest.mark.wallclock
@pytest.mark.alone  # a sample late by h/2 at most: see _held
def test_a_slow_disk_delays_the_answer_not_the_samples(thread_session, monkeypatch: pytest.MonkeyPatch) -> None:
    """LogOn and LogSave with every fsync taking 0.4 s (a busy or networked disk):
    the answers wait for the file thread, the samples do not (before: the host waited
    for the Future on the driver's thread, LogSave 1 s, 13 slots skipped).  A command
    sent behind LogSave is answered after it, in order."""
    real_fsync = os.fsync

    def slow_fsync(fd: int) -> None:
        time.sleep(0.4)
        real_fsync(fd)

    runs = iter(range(2))

    def scenario() -> ThreadSession:
        s: ThreadSession = thread_session(speed=1.0)  # the same logs/ folder: a new name each run
        name = f"slow{next(runs)}"
        with SessionClient(s.path) as alice:
            assert alice.submit(c.SetState("Run")).result(10).ok
            monkeypatch.setattr(os, "fsync", slow_fsync)
            t0 = time.monotonic()
            assert alice.submit(c.LogOn(points=1000)).result(10).ok
            time.sleep(0.3)
            save = alice.submit(c.LogSave(name))
            after = alice.submit(c.SetState("Pause"))
            assert after.result(10).ok and save.done() and save.result().ok
            assert time.monotonic() - t0 > 1.0  # the fsyncs were waited for (by the file thread)
        monkeypatch.setattr(os, "fsync", real_fsync)
        assert s.engine.snapshot().state == "Pause"
        return s
    _held(scenario)


@pytest.mark.wallclock
@pytest.mark.alone  # a sample late by h/2 at most: see _held
def test_attaching_with_a_full_ring_buffer_holds_no_sample(thread_session) -> None:
    """Ten attaches and a client's, each receiving the whole ring buffer (36000 rows, 3.5 MB of
    lines): the session sends it a part per event-loop turn (before: encoded at once,
    100-200 ms per attach on the driver's thread).  A client holds the whole history,
    exactly, before it is live."""
    def scenario() -> ThreadSession:
        s: ThreadSession = thread_session(speed=1.0)
        history = s.engine.loop.history
        rows = np.arange(history.capacity * len(SIGNALS), dtype=float).reshape(-1, len(SIGNALS))
        rows[:, 0] = 0.1 * np.arange(history.capacity) - 3600.0
        history.extend(rows)  # before any sample is due: a session that ran for an hour
        for _ in range(10):
            sock = _observer(s)
            lines = _lines(sock)
            parts = json.loads(next(lines)).get("parts", 0)  # the Welcome
            assert all(next(lines).startswith(b'{"@":"HistoryPart"') for _ in range(parts))
            sock.close()
        with SessionClient(s.path, role="observer") as client:  # an eleventh, whole
            got = client.history()
            np.testing.assert_array_equal(np.column_stack([got[n] for n in SIGNALS])[:len(rows)], rows)
        return s
    _held(scenario)


def test_rights_are_asked_once_per_user_while_remembered(monkeypatch: pytest.MonkeyPatch) -> None:
    """The name-service look-ups behind Access are remembered per uid for ACCESS_KEPT
    (a flood of Hellos from one user asks once), and asked again after it (group
    membership changes)."""
    asked: list[tuple[str, int]] = []
    now = [1000.0]
    monkeypatch.setattr(host_module.time, "monotonic", lambda: now[0])

    def ask(what: str, answer: bool) -> Callable[[int], bool]:
        def f(uid: int) -> bool:
            asked.append((what, uid))
            return answer
        return f

    access = Access(OWNER, is_admin=ask("admin", False), may_connect=ask("observe", True))
    for _ in range(50):
        assert access.may_connect(STUDENT) and not access.may_stop(STUDENT)
    assert asked == [("admin", STUDENT), ("observe", STUDENT)]
    now[0] += host_module.ACCESS_KEPT + 0.1
    access._may_connect = ask("observe", False)
    assert not access.may_connect(STUDENT)
    assert asked[2:] == [("admin", STUDENT), ("observe", STUDENT)]


def test_a_history_part_is_encoded_as_any_message_is() -> None:
    """The attach's fast path writes the same line the generic encoder would, and it
    decodes to the same rows, exactly."""
    from quadtank_tui.session.protocol import HistoryPart, decode, encode_history_part

    rows = np.random.default_rng(1).normal(size=(1000, len(SIGNALS)))
    rows[3, 2], rows[4, 1] = np.inf, np.nan
    line = encode_history_part(rows)
    assert line == encode(HistoryPart(rows))
    np.testing.assert_array_equal(decode(line).rows, rows)


@pytest.mark.parametrize("cleared", [False, True])
@pytest.mark.parametrize("same_params", [False, True])
def test_an_update_is_encoded_as_any_message_is(tmp_path, cleared: bool, same_params: bool) -> None:
    """The publishing's fast path writes the same line the generic encoder would (a
    snapshot of a running loop, with its parameters or without), and it decodes to
    the same rows, exactly."""
    import dataclasses

    from quadtank_tui.engine.runner import build_engine
    from quadtank_tui.session.protocol import Update, decode, encode_update

    engine = build_engine(clock="manual", params_dir=tmp_path, logs_dir=tmp_path)
    engine.submit(c.SetParams({"SAMPLING TIME.TSamp": 50}))
    engine.submit(c.SetState("Run"))
    engine.run_for(20.0)
    snap = engine.snapshot()
    if same_params:
        snap = dataclasses.replace(snap, params=None)  # type: ignore[arg-type]
    rows = np.random.default_rng(2).normal(size=(400, len(SIGNALS)))
    rows[5, 3] = np.nan
    update = Update(snap, rows, cleared)
    line = encode_update(update)
    assert line == encode(update)
    back = decode(line)
    np.testing.assert_array_equal(back.rows, rows)
    assert back.cleared is cleared and back.snapshot.k == snap.k == 400
