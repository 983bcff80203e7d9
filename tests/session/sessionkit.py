"""Sessions for tests (conftest.py makes the fixture of it): a host on a thread of the test process (fast: no interpreter
to start) with fake peer credentials, or a real detached session process."""

from __future__ import annotations

import threading
from pathlib import Path
from typing import Any, Callable


from quadtank_tui.engine.runner import build_engine
from quadtank_tui.session.host import Access, SessionHost
from quadtank_tui.session.protocol import SessionInfo
from quadtank_tui.session.runtime import socket_path
from quadtank_tui.session.server import PeerCred, listen

OWNER, STUDENT, TEACHER = 1000, 1001, 2000
NAMES = {OWNER: "alice", STUDENT: "bob", TEACHER: "teacher"}


class Peers:
    """Who the next connections are (the tests' stand-in for SO_PEERCRED)."""

    def __init__(self) -> None:
        self.queue: list[int] = []
        self.default = OWNER
        self._pid = 50000

    def __call__(self, sock: Any) -> PeerCred:
        uid = self.queue.pop(0) if self.queue else self.default
        self._pid += 1
        return PeerCred(self._pid, uid, uid, NAMES.get(uid, str(uid)))


class ThreadSession:
    def __init__(self, tmp_path: Path, *, speed: float = 200.0, tsamp_ms: float | None = None,
                 unattended: Callable[..., str] | None = None, policy_text: str = "") -> None:
        self.runtime = tmp_path / "run"
        self.runtime.mkdir(exist_ok=True)
        self.engine = build_engine(clock="virtual", speed=speed, params_dir=tmp_path / "params",
                                   logs_dir=tmp_path / "logs", threaded=False)
        if tsamp_ms is not None:
            assert self.engine.submit(_set({"SAMPLING TIME.TSamp": tsamp_ms})).result().ok
        self.path = socket_path(self.runtime, "alice-1")
        self.peers = Peers()
        info = SessionInfo(id="alice-1", owner="alice", uid=OWNER, pid=1, started="2026-11-22T23:00:00",
                           plant="quadtank", socket=str(self.path))
        self.host = SessionHost(self.engine, listen(str(self.path)), info, runtime=self.runtime,
                                access=Access(OWNER, is_admin=lambda uid: uid == TEACHER,
                                              admin_words="member of group teachers"),
                                peer_of=self.peers, unattended=unattended, policy_text=policy_text)
        self.reason: str | None = None
        self.thread = threading.Thread(target=self._serve, daemon=True)
        self.thread.start()

    def _serve(self) -> None:
        self.reason = self.host.serve()

    def stop(self) -> None:
        self.host.request_stop("test over")
        self.thread.join(10)


def _set(values: dict[str, Any]) -> Any:
    from quadtank_tui.engine.commands import SetParams

    return SetParams(values)
