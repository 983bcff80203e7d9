"""Sessions for tests (conftest.py makes the fixture of it): a host on a thread of the test process (fast: no interpreter
to start) with fake peer credentials, or a real detached session process."""

from __future__ import annotations

import os

import threading
from pathlib import Path
from typing import Any


from quadtank_tui.engine.runner import build_engine
from quadtank_tui.session.host import Access, SessionHost
from quadtank_tui.engine.backend import ProcessBackend
from quadtank_tui.session.policy import UnattendedPolicy
from quadtank_tui.session.protocol import SessionInfo
from quadtank_tui.session.runtime import socket_path
from quadtank_tui.session.roles import Peer
from quadtank_tui.session.server import listen

OWNER, STUDENT, TEACHER = 1000, 1001, 2000
NAMES = {OWNER: "alice", STUDENT: "bob", TEACHER: "teacher"}


class Peers:
    """Who the next connections are (the tests' stand-in for SO_PEERCRED)."""

    def __init__(self) -> None:
        self.queue: list[int] = []
        self.default = OWNER
        self._pid = 50000

    def __call__(self, sock: Any) -> Peer:
        uid = self.queue.pop(0) if self.queue else self.default
        self._pid += 1
        return Peer(uid=uid, gid=uid, pid=self._pid, user=NAMES.get(uid, str(uid)))


class ThreadSession:
    def __init__(self, tmp_path: Path, *, speed: float = 200.0, tsamp_ms: float | None = None,
                 daq: Any = None, policy: UnattendedPolicy | None = None) -> None:
        self.runtime = tmp_path / "run"
        self.runtime.mkdir(exist_ok=True)
        self.engine = build_engine(clock="virtual", speed=speed, params_dir=tmp_path / "params",
                                   logs_dir=tmp_path / "logs", daq=daq)
        if tsamp_ms is not None:
            assert self.engine.submit(_set({"SAMPLING TIME.TSamp": tsamp_ms})).result().ok
        self.path = socket_path(self.runtime, "alice-1")
        self.peers = Peers()
        info = SessionInfo(id="alice-1", owner="alice", uid=OWNER, pid=1, started="2026-11-22T23:00:00",
                           plant="quadtank", socket=str(self.path))
        self.host = SessionHost(self.engine, listen(str(self.path)), info, runtime=self.runtime,
                                access=Access(OWNER, is_admin=lambda uid: uid == TEACHER,
                                              admin_words="member of group teachers"),
                                peer_of=self.peers, policy=policy)
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


class Rig(ProcessBackend):
    """A stand-in rig (Active): steady levels; it remembers the pumps it was given."""

    kind = "Active"
    description = "test rig"

    def __init__(self) -> None:
        self.pumps: tuple[float, float] = (0.0, 0.0)
        self.safe_states = 0
        self.held = threading.Event()      # set while the session is held (hold_after)
        self.release = threading.Event()   # set by the test to let it go on
        self._reads_left: int | None = None

    def hold_after(self, reads: int) -> None:
        """Hold the session inside its `reads`-th read from now until `release` is set:
        a test looks at a running session at a point of its own choosing, not at
        whatever point a loaded machine lets it reach."""
        self.held.clear()
        self.release.clear()
        self._reads_left = reads

    def read_levels(self):
        if self._reads_left is not None:
            self._reads_left -= 1
            if self._reads_left <= 0:
                self._reads_left = None
                self.held.set()
                assert self.release.wait(60), "the test never released the rig"
        return (0.6, 0.6, 0.1, 0.1)

    def write_pumps(self, u: Any) -> None:
        self.pumps = (float(u[0]), float(u[1]))

    def safe_state(self) -> None:
        self.pumps = (0.0, 0.0)
        self.safe_states += 1


def place(runtime: Path) -> Path:
    """This user's folder of sessions in the runtime folder `runtime` (session/folders.py)."""
    return runtime / "users" / str(os.getuid())


def place_files(runtime: Path) -> list[str]:
    """The names in this user's folder of sessions ([] while there is none)."""
    folder = place(runtime)
    return sorted(p.name for p in folder.iterdir()) if folder.exists() else []
