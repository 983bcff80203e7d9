"""The session host's audit lines (issue 44): one per attach, detach, take-over,
refused take-over, stop and refused stop, naming the session, its owner and the
peer the kernel vouches for (conftest.Peers stands in for SO_PEERCRED), in the
session's .out (its stdout) and the system log (authpriv)."""

from __future__ import annotations

import re
import time

import pytest
from sessionkit import STUDENT, TEACHER

from quadtank_tui.session import host as host_module
from quadtank_tui.session.client import SessionClient, SessionError, stop_session_at


def wait_for(predicate, timeout: float = 30.0) -> None:
    end = time.monotonic() + timeout
    while not predicate():
        assert time.monotonic() < end, "timed out"
        time.sleep(0.01)


def test_take_overs_and_stops_are_recorded_with_the_kernels_peer(thread_session, capsys: pytest.CaptureFixture[str],
                                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    logged: list[str] = []
    monkeypatch.setattr(host_module, "system_log", logged.append)
    s = thread_session()
    with SessionClient(s.path) as alice:
        s.peers.queue = [STUDENT]
        with pytest.raises(SessionError):
            SessionClient(s.path, take_over=True)  # bob is refused: not his session
        s.peers.queue = [STUDENT]
        with pytest.raises(SessionError):
            stop_session_at(s.path)
        s.peers.queue = [TEACHER]
        teacher = SessionClient(s.path, take_over=True)
        wait_for(lambda: alice.role == "observer")
        s.peers.queue = [TEACHER]
        assert stop_session_at(s.path) == "stopped by teacher"
        s.thread.join(10)
        teacher.close()
    wait_for(lambda: sum(" detach " in line for line in logged) >= 2)
    base = "session=alice-1 owner=alice"
    assert logged[:6] == [
        f"audit: attach {base} user=alice uid=1000 role=operator",
        f"audit: refused {base} user=bob uid={STUDENT} wanted=take-over",  # not his session
        f"audit: refused {base} user=bob uid={STUDENT} wanted=stop",
        f"audit: take-over {base} user=teacher uid={TEACHER} from=alice",
        f"audit: attach {base} user=teacher uid={TEACHER} role=operator",
        f"audit: stop {base} user=teacher uid={TEACHER}",
    ], logged
    assert sorted(logged[6:]) == [f"audit: detach {base} user=alice uid=1000 role=observer",  # the stop let both go
                                  f"audit: detach {base} user=teacher uid={TEACHER} role=operator"], logged
    out = capsys.readouterr().out
    assert all(re.search(rf"^\d\d:\d\d:\d\d {re.escape(line)}$", out, re.M) for line in logged), out  # the .out too
