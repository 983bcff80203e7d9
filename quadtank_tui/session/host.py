"""A session: the one driver (engine/driver.py) on an asyncio event loop, serving clients.

One thread does everything, in this order, forever: wait (the event loop) until the
next sample is due or a client says something; apply the commands that came in
(between samples, so a sample never sees half a change); take the sample when it
is due; publish what changed to every attached client (the new ring-buffer rows
and the snapshot, at most every PUBLISH_INTERVAL, and always before a command's
result, so a client sees the effect of its command when it hears that it was
applied).

The driver samples the engine (``Engine.sample`` at each deadline); the host
applies the clients' commands on the same thread (``Engine.submit`` applies at
once).  Nobody else touches it.

Stops (pumps at 0, logging stopped with the rows kept, backends closed): a client's
StopSession from someone allowed to, SIGTERM / SIGHUP / SIGINT, or the loop failing.
The socket is removed; the record stays, saying why it ended and when (`quadtank
sessions` lists it a while: runtime.ENDED_KEPT); the clients are told why.  Nothing
a client sends ends the session unless it is a StopSession it may send (the
server drops a client whose line is not a message, or whose message fails).
"""

from __future__ import annotations

import asyncio
import collections
import dataclasses
import signal
import socket
import time
from datetime import datetime
from pathlib import Path
from typing import Any, Callable

from quadtank_tui.engine.commands import Command, CommandResult, InstallPar, LoadPar, SetState
from quadtank_tui.engine.driver import Driver, LoopTime
from quadtank_tui.engine.parload import ParReading
from quadtank_tui.engine.runner import Engine
from quadtank_tui.engine.snapshot import Snapshot
from quadtank_tui.session.protocol import (
    Ended, Hello, Refused, Result, Role, Roster, SessionInfo, StopSession, Submit, Update, Welcome, encode,
)
from quadtank_tui.session.lab import LabConfig
from quadtank_tui.session.policy import UnattendedPolicy, describe, unattended_action
from quadtank_tui.session.roles import group_id, groups_of, is_administrator, who_administers
from quadtank_tui.session.roles import Peer
from quadtank_tui.session.runtime import end_record, write_record
from quadtank_tui.session.scripted import ScriptedRun
from quadtank_tui.session.server import Connection, Rank, Server

#: Least wall time between two updates to the clients, s (a 1000x virtual clock
#: samples 20000 times a second; a screen redraws 20).
PUBLISH_INTERVAL = 0.02
#: Least wall time between two rewrites of the record for logging progress alone, s.
RECORD_INTERVAL = 1.0
#: Seconds a peer's rank (administrator or not: a look at the lab's group or files)
#: is remembered: a flood of connections from one user asks it once.
RANK_KEPT = 30.0


class Access:
    """Who may do what in a session (before the lab's roles: the owner and root).

    is_admin(uid) : an administrator of the lab (take over, stop others' sessions)
    may_connect(uid) : may attach (observe) at all
    """

    def __init__(self, owner_uid: int, *, is_admin: Callable[[int], bool] | None = None,
                 may_connect: Callable[[int], bool] | None = None, admin_words: str = "root") -> None:
        self.owner_uid = owner_uid
        self.is_admin = is_admin or (lambda uid: uid == 0)
        self._may_connect = may_connect
        self.admin_words = admin_words

    @classmethod
    def for_lab(cls, owner_uid: int, lab: LabConfig) -> Access:
        """The lab's rules: its administrators; its share group may observe."""
        share = group_id(lab.share_group) if lab.share_group else None
        return cls(owner_uid, is_admin=lambda uid: is_administrator(uid, lab),
                   may_connect=(lambda uid: share in groups_of(uid)) if share is not None else None,
                   admin_words=who_administers(lab))

    def may_connect(self, uid: int) -> bool:
        if uid == self.owner_uid or self.is_admin(uid):
            return True
        return self._may_connect(uid) if self._may_connect is not None else False

    def may_stop(self, uid: int) -> bool:
        return uid == self.owner_uid or self.is_admin(uid)


class SessionHost:
    """Drives `engine` and serves `listener` until stopped.

    info : the session's record (id, owner, ...); kept up to date on disk in `runtime`
    policy : what the session does while no operator is attached (the lab's
        unattended policy: an Active session pauses, pumps at 0, when it says so)
    scripted : a headless run (`quadtank run --detach`): its script drives the
        loop, every client observes, the session ends when the run is over
    """

    def __init__(self, engine: Engine, listener: socket.socket, info: SessionInfo, *, runtime: Path,
                 access: Access, peer_of: Callable[[socket.socket], Any] | None = None,
                 policy: UnattendedPolicy | None = None, scripted: ScriptedRun | None = None,
                 wall: Callable[[], float] = time.time) -> None:
        self.engine = engine
        if scripted is None:  # clients on a paced clock: no sample waits for the disk (a rig's engine does this itself)
            engine.loop.use_file_thread()
        self.info = info
        self.runtime = runtime
        self.access = access
        self.aloop = asyncio.new_event_loop()
        self.aloop.set_exception_handler(self._loop_failed)
        kwargs = {} if peer_of is None else {"peer_of": peer_of}
        self._ranks: dict[int, tuple[float, Rank]] = {}
        self.server = Server(listener, self.aloop, self._on_message, self._on_gone, rank=self._rank, **kwargs)
        self.driver = Driver(engine, after=self._after, urgent=lambda: self.server.writing > 0,
                             before=self._before if scripted is not None else None,
                             duration=scripted.duration if scripted is not None else None)
        self.policy = policy if policy is not None else UnattendedPolicy()
        self.scripted = scripted
        self._log_ended: float | None = None  # when a log ended while nobody operated
        self._was_logging = False
        self._wall = wall
        self._operator: Connection | None = None
        self._operator_left = time.monotonic()  # a session starts unattended until its launcher attaches
        self._stop_reason: str | None = None
        #: Commands waiting behind a LoadPar whose file is being read (engine/parload.py).
        self._waiting: collections.deque[tuple[Connection, int, Command | ParReading]] = collections.deque()
        # What the clients have been sent: history rows up to `_sent_total` of
        # clear generation `_sent_gen`, and the parameters of the last update.
        self._sent_total, self._sent_gen = 0, 0
        self._sent_params: object = None
        self._last_publish = -float("inf")
        self._last_policy = time.monotonic()
        self._record_key: tuple[object, ...] = ()
        self._record_at = -float("inf")
        self.ended: str | None = None

    # --- the driver ------------------------------------------------------------------------

    def serve(self) -> str:
        """Run until stopped; returns why it stopped.  The engine is stopped (pumps at
        0, log kept) and the socket and record removed before this returns."""
        self._write_record(force=True)
        self.driver.serve(self.aloop, self._end)
        return self._stop_reason or "stopped"

    def _before(self, elapsed: LoopTime) -> None:
        """A detached run: the script's due events ahead of the sample."""
        assert self.scripted is not None
        try:
            self.scripted.before(elapsed)
        except ValueError as exc:  # a refused command of the script (ScriptError names file and line)
            self.request_stop(f"the script stopped: {exc}")

    def _after(self) -> None:
        """After a sample: publish and look after the record, at most every PUBLISH_INTERVAL."""
        if time.monotonic() - self._last_publish >= PUBLISH_INTERVAL:
            self._publish(force=True)
            self._housekeeping()

    def _loop_failed(self, aloop: asyncio.AbstractEventLoop, context: dict[str, Any]) -> None:
        """Something the event loop ran failed (not a client's message: the server
        drops that client): stop in order and say why."""
        exc = context.get("exception")
        why = f"{type(exc).__name__}: {exc}" if exc is not None else str(context.get("message"))
        self.request_stop(f"the session failed: {why}")

    def _rank(self, peer: Peer) -> Rank:
        """An administrator (no per-user limit), the owner (the reserve), or another."""
        now = time.monotonic()
        kept = self._ranks.get(peer.uid)
        if kept is not None and now - kept[0] < RANK_KEPT:
            return kept[1]
        rank: Rank = "admin" if self.access.is_admin(peer.uid) else \
            "owner" if peer.uid == self.access.owner_uid else "other"
        if len(self._ranks) > 1000:
            self._ranks.clear()
        self._ranks[peer.uid] = (now, rank)
        return rank

    def request_stop(self, reason: str) -> None:
        """From any thread: stop at the next turn."""
        if self._stop_reason is None:
            self._stop_reason = reason
        self.driver.stop()

    def install_signal_handlers(self) -> None:
        """SIGTERM, SIGHUP, SIGINT stop the session in order (main thread only).

        They are unblocked too: a process inherits its launcher's signal mask, and a
        session spawned while its launcher held them blocked (seen: a pytest whose
        main thread kept every signal blocked) ignored SIGTERM for good - it sat
        on, sampling, until SIGKILL."""
        stops = (signal.SIGTERM, signal.SIGHUP, signal.SIGINT)
        signal.pthread_sigmask(signal.SIG_UNBLOCK, stops)
        for sig in stops:
            self.aloop.add_signal_handler(sig, self.request_stop, sig.name)

    # --- publishing ------------------------------------------------------------------------

    def _update(self, snap: Snapshot) -> Update:
        rows, total, gen = self.engine.loop.history.since(self._sent_total)
        cleared = gen != self._sent_gen
        if cleared:
            rows, total, gen = self.engine.loop.history.since(0)
        self._sent_total, self._sent_gen = total, gen
        same = snap.params is self._sent_params
        self._sent_params = snap.params
        return Update(dataclasses.replace(snap, params=None) if same else snap, rows, cleared)  # type: ignore[arg-type]

    def _publish(self, *, force: bool = False) -> None:
        now = time.monotonic()
        if not force and now - self._last_publish < PUBLISH_INTERVAL:
            return
        self._last_publish = now
        update = self._update(self.engine.snapshot())
        if any(c.role is not None for c in self.server.connections):
            self.server.broadcast(encode(update))

    # --- messages ----------------------------------------------------------------------------

    def _on_message(self, conn: Connection, message: Any) -> None:
        if isinstance(message, Hello):
            self._hello(conn, message)
        elif conn.role is None:
            self.server.send(conn, encode(Refused("say Hello first")), close=True)
        elif isinstance(message, Submit):
            self._submit(conn, message.id, message.command)
            self.driver.poke()  # the command may have moved the next deadline (SetSpeed, TSamp)
        elif isinstance(message, StopSession):
            self._stop_asked(conn)

    def _hello(self, conn: Connection, hello: Hello) -> None:
        peer = conn.peer
        if conn.role is not None:
            return
        if not self.access.may_connect(peer.uid):
            self._refuse(conn, f"session {self.info.id} belongs to {self.info.owner}; you are {peer.user} "
                         f"(an administrator, {self.access.admin_words}, may attach to it)")
            return
        if hello.role == "control":  # a one-shot `quadtank stop`: no Welcome, no updates
            conn.role = "control"
            return
        role = hello.role
        if self.scripted is not None:
            role = "observer"  # the script is the operator
        if role == "operator":
            current = self._operator
            if current is not None and current is not conn:
                # The operator's own user may take over from its other client (a screen
                # left on a link that died unnoticed); otherwise only an administrator.
                own = peer.uid == current.peer.uid
                if not hello.take_over:
                    hint = (f"`quadtank attach --take-over {self.info.id}` takes it from your other client"
                            if own else f"`quadtank attach --observe {self.info.id}` watches it")
                    self._refuse(conn, f"session {self.info.id} is operated by {current.name} since "
                                 f"{_hhmm(current.since)}; {hint}")
                    return
                if not own and not self.access.is_admin(peer.uid):
                    self._refuse(conn, f"taking over session {self.info.id} needs an administrator "
                                 f"({self.access.admin_words}); you are {peer.user}")
                    return
                current.role = "observer"  # it stays, read-only, and is told so below
            elif peer.uid != self.info.uid and not self.access.is_admin(peer.uid):
                self._refuse(conn, f"session {self.info.id} belongs to {self.info.owner}: you may observe it "
                             "(quadtank attach --observe), not operate it")
                return
            self._operator = conn
        self._publish(force=True)  # the others are up to date before this one joins
        conn.role = role
        conn.since = self._wall()
        loop = self.engine.loop
        rows, _, _ = loop.history.since(0)
        welcome = Welcome(self._info(), role, self.engine.snapshot(), loop.defaults, rows,
                          loop.history.capacity, str(loop.store.folder.resolve()),
                          str(loop.logs_dir.resolve()), self._controller(),
                          describe(self.policy, active=False), describe(self.policy, active=True))
        self.server.send(conn, encode(welcome))
        self._roster_changed()

    def _refuse(self, conn: Connection, reason: str) -> None:
        self.server.send(conn, encode(Refused(reason)), close=True)

    def _submit(self, conn: Connection, cid: int, command: Command) -> None:
        if conn.role != "operator":
            who = self._operator.name if self._operator is not None else "nobody"
            self._answer(conn, cid, CommandResult.refused(
                f"read-only: you observe session {self.info.id}; {who} controls it"))
            return
        if isinstance(command, LoadPar):  # the file is read on a thread of its own: samples go on
            self._waiting.append((conn, cid, ParReading.start(self.engine.loop.store, command, self._wake)))
        elif self._waiting:  # behind a LoadPar: in order
            self._waiting.append((conn, cid, command))
        else:
            self._answer(conn, cid, self._apply(command))

    def _apply(self, command: Command | InstallPar) -> CommandResult:
        try:
            return self.engine.submit(command).result()
        except Exception as exc:  # noqa: BLE001 - a bug must not end the session
            return CommandResult.refused(f"{type(command).__name__} failed: {type(exc).__name__}: {exc}")

    def _answer(self, conn: Connection, cid: int, result: CommandResult) -> None:
        self._publish(force=True)  # the effect before the answer
        self.server.send(conn, encode(Result(cid, result)))
        self._write_record()

    def _apply_waiting(self) -> None:
        """The commands behind a LoadPar whose file has been read, in order."""
        while self._waiting:
            conn, cid, command = self._waiting[0]
            if isinstance(command, ParReading):
                if not command.done:
                    return
                prepared = command.future.result()
                self._waiting.popleft()
                self._answer(conn, cid, prepared if isinstance(prepared, CommandResult) else self._apply(prepared))
            else:
                self._waiting.popleft()
                self._answer(conn, cid, self._apply(command))

    def _wake(self) -> None:
        """A LoadPar's file has been read (from its thread): the commands behind it go on."""
        try:
            self.aloop.call_soon_threadsafe(self._apply_waiting)
        except RuntimeError:  # the session is over
            pass

    def _stop_asked(self, conn: Connection) -> None:
        if not self.access.may_stop(conn.peer.uid):
            self._refuse(conn, f"stopping session {self.info.id} needs its owner ({self.info.owner}) or an "
                         f"administrator ({self.access.admin_words}); you are {conn.peer.user}")
            return
        self.request_stop(f"stopped by {conn.peer.user}")

    def _on_gone(self, conn: Connection) -> None:
        if conn is self._operator:
            self._operator = None
            self._operator_left = time.monotonic()
            self._log_ended = None
        if conn.role is not None:
            self._roster_changed()

    def _controller(self) -> str:
        if self.scripted is not None:
            return f"the script of quadtank run controls session {self.info.id}"
        op = self._operator
        return f"{op.name} controls session {self.info.id}" if op is not None else \
            f"nobody controls session {self.info.id}"

    def _roster_changed(self) -> None:
        clients = sum(1 for c in self.server.connections if c.role in ("operator", "observer"))
        for conn in self.server.connections:
            if conn.role in ("operator", "observer"):
                role: Role = "operator" if conn.role == "operator" else "observer"
                self.server.send(conn, encode(Roster(self._controller(), clients, role)))
        self._write_record(force=True)

    # --- the record, the unattended policy -----------------------------------------------------

    def _info(self) -> SessionInfo:
        snap = self.engine.snapshot()
        log = snap.log
        if log.active:
            logging = f"{100 * log.progress:.0f}% ({log.rows}/{log.points})"
        elif log.unsaved:
            logging = f"{log.rows} rows unsaved"
        else:
            logging = "off"
        clients = sum(1 for c in self.server.connections if c.role in ("operator", "observer"))
        op = self._operator
        return dataclasses.replace(self.info, operation=snap.operation, state=snap.state, logging=logging,
                                   clients=clients, operator=op.peer.user if op is not None else "")

    def _write_record(self, *, force: bool = False) -> None:
        info = self._info()
        # Logging progress alone rewrites the record at most every RECORD_INTERVAL.
        kind = "on" if "%" in info.logging else "unsaved" if "unsaved" in info.logging else info.logging
        key = dataclasses.astuple(dataclasses.replace(info, logging=kind))
        now = time.monotonic()
        if not force and key == self._record_key and (info.logging == self.info.logging or
                                                       now - self._record_at < RECORD_INTERVAL):
            return
        self.info, self._record_key, self._record_at = info, key, now
        try:
            write_record(self.runtime, info)
        except OSError:
            pass  # the listing is out of date; the session goes on

    def _housekeeping(self) -> None:
        now = time.monotonic()
        snap = self.engine.snapshot()
        if self._was_logging and not snap.log.active and self._operator is None:
            self._log_ended = now
        self._was_logging = snap.log.active
        if now - self._last_policy < 1.0:
            return
        self._last_policy = now
        self._write_record()
        if self._operator is None and snap.state == "Run" and self.scripted is None:
            action = unattended_action(
                self.policy, active=snap.operation == "Active", logging=snap.log.active,
                seconds_unattended=now - self._operator_left,
                seconds_since_log=None if self._log_ended is None else now - self._log_ended)
            if action == "pause":
                self.engine.submit(SetState("Pause"))  # a real process: pumps at 0
                whose = "the default policy" if self.policy == UnattendedPolicy() else "the lab's policy"
                pumps = self.engine.loop.pumps_unconfirmed or "pumps at 0"  # tried again each tick if not
                self.info = dataclasses.replace(self.info, note=f"paused unattended at {datetime.now():%H:%M:%S}, "
                                                f"{pumps} ({whose})")
                self._publish(force=True)
                self._write_record(force=True)

    # --- the end -------------------------------------------------------------------------------

    async def _end(self, failure: BaseException | None) -> None:
        """The drive is over: stopped, failed, or a detached run's time is up."""
        if failure is not None:
            self._stop_reason = f"the session failed: {type(failure).__name__}: {failure}"
        elif self._stop_reason is None and self.scripted is not None:
            self._publish(force=True)
            try:
                self._stop_reason = self.scripted.finish()
            except Exception as exc:  # noqa: BLE001 - stop in order and say why
                self._stop_reason = f"the session failed: {type(exc).__name__}: {exc}"
        await self._shutdown()

    async def _shutdown(self) -> None:
        reason = self._stop_reason or "stopped"
        self.ended = reason
        try:
            self.engine.stop()  # pumps at 0, logging stopped (rows kept), backends closed
        finally:
            if unsafe := self.engine.loop.pumps_unconfirmed:  # the rig's guard and watchdog were left to it
                reason = self.ended = f"{reason}; {unsafe}"
            try:
                self._publish(force=True)
                self.server.broadcast(encode(Ended(reason)))
                await self.server.flush_all(1.0)
            finally:
                self.server.close()
                self._operator = None
                try:
                    end_record(self.runtime, self._info(), reason)
                except Exception:  # noqa: BLE001 - the engine may be what failed; the record says it ended
                    end_record(self.runtime, self.info, reason)


def _hhmm(wall: float) -> str:
    return datetime.fromtimestamp(wall).strftime("%H:%M")
