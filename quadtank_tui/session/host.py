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
once).  Nobody else touches it.  Nothing here waits: a command's file work (a
LogSave's fsyncs, a LoadPar's read) runs on a thread and its answer goes out when
it is done, the operator's later commands queued behind it; a new client's
history goes out in parts, a few per turn; a client's lines are handled a few
per turn (session/server.py).

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
from concurrent.futures import Future
from datetime import datetime
from pathlib import Path
from typing import Any, Callable, Iterator

import numpy as np

from quadtank_tui.engine.commands import (Command, CommandResult, InstallPar, LoadPar, LogOff, LogSave,
                                          SetControlMode, SetOperation, SetParams, SetState)
from quadtank_tui.engine.driver import Driver, LoopTime
from quadtank_tui.engine.design_ahead import MPCDesigning
from quadtank_tui.engine.parload import ParReading
from quadtank_tui.engine.runner import Engine
from quadtank_tui.engine.snapshot import Snapshot
from quadtank_tui.session.protocol import (
    Ended, Hello, Refused, Result, Role, Roster, SessionInfo, StopSession, Submit, Update, Welcome, encode,
    encode_history_part, encode_update,
)
from quadtank_tui.session.bookings import SlotWatch
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
#: Seconds a user's rights here (administrator, may observe) are remembered.  Each
#: answer is a look-up in the name service (the lab's group, its files' owners: on a
#: lab's LDAP or NIS, milliseconds to seconds) on the driver's thread; remembered, a
#: flood of connections or of attaches from one user asks it once.  Short, because
#: group membership changes: a student taken out of the share group (or a teacher
#: out of the admin group) can attach or stop sessions at most this long after.
ACCESS_KEPT = 10.0
#: Rows of the ring buffer per line on attach: they follow the Welcome in order, one
#: line (HistoryPart) encoded per event-loop turn, a fraction of a millisecond; the
#: whole 36000 encoded at once would hold the sampling for a tenth of a second or more.
PART_ROWS = 1000


class Access:
    """Who may do what in a session (before the lab's roles: the owner and root).

    is_admin(uid) : an administrator of the lab (take over, stop others' sessions)
    may_connect(uid) : may attach (observe) at all
    """

    def __init__(self, owner_uid: int, *, is_admin: Callable[[int], bool] | None = None,
                 may_connect: Callable[[int], bool] | None = None, admin_words: str = "root") -> None:
        self.owner_uid = owner_uid
        self._is_admin = is_admin or (lambda uid: uid == 0)
        self._may_connect = may_connect
        self.admin_words = admin_words
        self._kept: dict[tuple[str, int], tuple[float, bool]] = {}

    @classmethod
    def for_lab(cls, owner_uid: int, lab: LabConfig) -> Access:
        """The lab's rules: its administrators; its share group may observe."""
        share = group_id(lab.share_group) if lab.share_group else None
        return cls(owner_uid, is_admin=lambda uid: is_administrator(uid, lab),
                   may_connect=(lambda uid: share in groups_of(uid)) if share is not None else None,
                   admin_words=who_administers(lab))

    def is_admin(self, uid: int) -> bool:
        return self._remembered("admin", uid, self._is_admin)

    def may_connect(self, uid: int) -> bool:
        if uid == self.owner_uid or self.is_admin(uid):
            return True
        may = self._may_connect
        return may is not None and self._remembered("observe", uid, may)

    def _remembered(self, what: str, uid: int, ask: Callable[[int], bool]) -> bool:
        """`ask(uid)`, remembered for ACCESS_KEPT s."""
        now = time.monotonic()
        kept = self._kept.get((what, uid))
        if kept is not None and now - kept[0] < ACCESS_KEPT:
            return kept[1]
        if len(self._kept) > 1000:
            self._kept.clear()
        answer = bool(ask(uid))
        self._kept[(what, uid)] = (now, answer)
        return answer

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
                 wall: Callable[[], float] = time.time, slots: SlotWatch | None = None) -> None:
        self.engine = engine
        #: the rig's bookings (a session driving a rig): Active refused in another's slot, the hand-over at its end
        self.slots = slots
        self._handover: tuple[str, list[Future[CommandResult]], float] | None = None
        self._drain_until: float | None = None  # a hand-over's drain: its deadline (monotonic)
        self._handed_over = False
        if scripted is None:  # clients on a paced clock: no sample waits for the disk (a rig's engine does this itself)
            engine.use_file_thread()
        self.info = info
        self.runtime = runtime
        self.access = access
        self.aloop = asyncio.new_event_loop()
        self.aloop.set_exception_handler(self._loop_failed)
        kwargs = {} if peer_of is None else {"peer_of": peer_of}
        self.server = Server(listener, self.aloop, self._on_message, self._on_gone, rank=self._rank, **kwargs)
        self.driver = Driver(engine, after=self._after, urgent=lambda: self.server.writing + self.server.producing > 0,
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
        #: The operator's commands in order: the first may be waiting for its file work
        #: (a LoadPar's read: engine/parload.py; a LogSave's write and fsyncs) or for its
        #: MPC's design (engine/design_ahead.py), the rest behind it.
        self._waiting: collections.deque[_Pending] = collections.deque()
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
        """A detached run: the script's due events ahead of the sample (none once a
        slot's hand-over began: its pumps stay at 0)."""
        assert self.scripted is not None
        if self._handover is not None:
            return
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
        return "admin" if self.access.is_admin(peer.uid) else "owner" if peer.uid == self.access.owner_uid else "other"

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
        rows, total, gen = self.engine.history_since(self._sent_total)
        cleared = gen != self._sent_gen
        if cleared:
            rows, total, gen = self.engine.history_since(0)
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
            self.server.broadcast(encode_update(update))

    # --- messages ----------------------------------------------------------------------------

    def _on_message(self, conn: Connection, message: Any) -> None:
        if isinstance(message, Hello):
            self._hello(conn, message)
        elif conn.role is None:
            self.server.send(conn, encode(Refused("say Hello first")), close=True)
        elif isinstance(message, Submit):
            self._submit(conn, message.id, message.command)
        elif isinstance(message, StopSession):
            self._stop_asked(conn)

    def _hello(self, conn: Connection, hello: Hello) -> None:
        peer = conn.peer
        if conn.role is not None:
            return
        if not self.access.may_connect(peer.uid):
            wanted = "stop" if hello.role == "control" else "take-over" if hello.take_over else hello.role
            self._audit("refused", peer, f"wanted={wanted}")
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
                    self._audit("refused", peer, f"wanted=take-over operator={current.peer.user}")
                    self._refuse(conn, f"taking over session {self.info.id} needs an administrator "
                                 f"({self.access.admin_words}); you are {peer.user}")
                    return
                current.role = "observer"  # it stays, read-only, and is told so below
                self._audit("take-over", peer, f"from={current.peer.user}")
            elif peer.uid != self.info.uid and not self.access.is_admin(peer.uid):
                self._refuse(conn, f"session {self.info.id} belongs to {self.info.owner}: you may observe it "
                             "(quadtank attach --observe), not operate it")
                return
            self._operator = conn
        self._publish(force=True)  # the others are up to date before this one joins
        conn.role = role
        conn.since = self._wall()
        self._audit("attach", peer, f"role={role}")
        engine = self.engine
        rows, _, _ = engine.history_since(0)  # a copy: the parts are encoded later, from it
        welcome = Welcome(self._info(), role, engine.snapshot(), engine.defaults(),
                          engine.history_capacity, str(engine.par_store.folder.resolve()),
                          str(engine.logs_dir.resolve()), self._controller(),
                          describe(self.policy, active=False), describe(self.policy, active=True),
                          parts=-(-len(rows) // PART_ROWS))
        self.server.send(conn, encode(welcome))
        if len(rows):
            self.server.send_parts(conn, _parts(rows))
        self._roster_changed()

    def _refuse(self, conn: Connection, reason: str) -> None:
        self.server.send(conn, encode(Refused(reason)), close=True)

    def _submit(self, conn: Connection, cid: int, command: Command) -> None:
        if conn.role != "operator":  # nothing changed: no update, no record (a flood of these costs little)
            who = self._operator.name if self._operator is not None else "nobody"
            self.server.send(conn, encode(Result(cid, CommandResult.refused(
                f"read-only: you observe session {self.info.id}; {who} controls it"))))
            return
        if isinstance(command, SetOperation) and command.operation == "Active" and self.slots is not None \
                and (why := self._slot_refusal(conn)) is not None:
            self.server.send(conn, encode(Result(cid, CommandResult.refused(why))))
            return
        if isinstance(command, LoadPar):  # the file is read on a thread of its own: samples go on
            self._waiting.append(_Pending(conn, cid, ParReading.start(self.engine.par_store, command, self._wake)))
        elif not self._waiting and isinstance(command, SetParams) \
                and (new := self.engine.mpc_design_needed(command)) is not None:
            # designed on a thread of its own: samples go on (a first design imports scipy and OSQP)
            self._waiting.append(_Pending(conn, cid, MPCDesigning.start(command, new, self._wake)))
        else:
            self._waiting.append(_Pending(conn, cid, command))
        self._apply_waiting()

    def _answer(self, conn: Connection, cid: int, result: CommandResult) -> None:
        self._publish(force=True)  # the effect before the answer
        self.server.send(conn, encode(Result(cid, result)))
        self._write_record()

    def _apply_waiting(self) -> None:
        """The operator's commands in order: each applied once the one before it is
        done, and answered once its own file work is (never waited for here: the
        driver samples meanwhile; the file thread wakes us)."""
        applied = False
        while self._waiting:
            head = self._waiting[0]
            if head.applied is None:
                what = head.what
                if isinstance(what, ParReading):
                    if not what.done:
                        return
                    prepared = what.future.result()
                    head.applied = _resolved(prepared) if isinstance(prepared, CommandResult) else \
                        self._begin(prepared)
                elif isinstance(what, MPCDesigning):
                    if not what.done:
                        return
                    designed = what.future.result()
                    if designed is not None:  # else the loop designs it again and says why it refuses
                        self.engine.offer_mpc(*designed)
                    head.applied = self._begin(what.command)
                else:
                    head.applied = self._begin(what)
                applied = True
                if not head.applied.done():
                    head.applied.add_done_callback(lambda _: self._wake())
            if not head.applied.done():
                break
            self._waiting.popleft()
            self._answer(head.conn, head.cid, head.applied.result())
        if applied:
            self.driver.poke()  # a command may have moved the next deadline (SetSpeed, TSamp)

    def _begin(self, command: Command | InstallPar) -> Future[CommandResult]:
        """Apply `command` now; the Future resolves (to a result, never an exception)
        once its file work is done."""
        name = type(command).__name__
        try:
            started = self.engine.submit(command)
        except Exception as exc:  # noqa: BLE001 - a bug must not end the session
            return _resolved(_failed(name, exc))
        if started.done():
            return _resolved(_outcome(started, name))
        result: Future[CommandResult] = Future()
        started.add_done_callback(lambda fut: result.set_result(_outcome(fut, name)))
        return result

    def _wake(self) -> None:
        """A command's file work is done or its MPC designed (from the file thread, a LoadPar's or the design's): the
        commands behind it go on."""
        try:
            self.aloop.call_soon_threadsafe(self._apply_waiting)
        except RuntimeError:  # the session is over
            pass

    def _stop_asked(self, conn: Connection) -> None:
        if not self.access.may_stop(conn.peer.uid):
            self._audit("refused", conn.peer, "wanted=stop")
            self._refuse(conn, f"stopping session {self.info.id} needs its owner ({self.info.owner}) or an "
                         f"administrator ({self.access.admin_words}); you are {conn.peer.user}")
            return
        self._audit("stop", conn.peer)
        self.request_stop(f"stopped by {conn.peer.user}")

    def _audit(self, event: str, peer: Peer, more: str = "") -> None:
        """One line for the administrators: who (the kernel's word, SO_PEERCRED) did
        `event` to this session, in the session's .out and in the system log
        (authpriv: readable by the administrators, the journal stamps the writer's
        uid).  Never fails the session: a machine without a system log keeps the
        .out line."""
        line = f"audit: {event} session={self.info.id} owner={self.info.owner} user={peer.user} uid={peer.uid}" + \
            (f" {more}" if more else "")
        print(f"{datetime.now():%H:%M:%S} {line}", flush=True)
        system_log(line)

    def _on_gone(self, conn: Connection) -> None:
        if conn is self._operator:
            self._operator = None
            self._operator_left = time.monotonic()
            self._log_ended = None
        if conn.role is not None and conn.role != "control":
            self._audit("detach", conn.peer, f"role={conn.role}")
        if conn.role is not None:
            self._roster_changed()

    def _controller(self) -> str:
        notice = f"; {self.slots.notice}" if self.slots is not None and self.slots.notice else ""
        if self.scripted is not None:
            return f"the script of quadtank run controls session {self.info.id}{notice}"
        op = self._operator
        return (f"{op.name} controls session {self.info.id}" if op is not None else
                f"nobody controls session {self.info.id}") + notice

    def _slot_refusal(self, conn: Connection) -> str | None:
        assert self.slots is not None
        try:
            return self.slots.refusal()
        except (OSError, ValueError) as exc:  # an unreadable bookings folder refuses nobody
            print(f"{datetime.now():%H:%M:%S} bookings: {exc}", flush=True)
            return None

    def _watch_slot(self) -> None:
        """The rig's bookings each second: a notice on the screens before this
        session's time on the rig ends, then the hand-over: pumps at 0 (Pause), the
        log saved with its rows, the session stopped (the rig's lock freed)."""
        if self.slots is None:
            return
        if self._handover is not None:
            reason, pending, since = self._handover
            if self._handed_over:
                return  # stopping
            if pending and (all(f.done() for f in pending) or time.monotonic() - since > 10.0):
                saved = [f.result().message for f in pending if f.done() and f.result().ok and f.result().message]
                print(f"{datetime.now():%H:%M:%S} slot: log {'; '.join(saved) or 'none to save'}", flush=True)
                pending.clear()
            if pending:
                return
            if self._drain_until is not None:
                below = self.slots.rules.drain_below
                levels = self.engine.snapshot().y
                if below is not None and max(levels) >= below and time.monotonic() < self._drain_until:
                    return
                self.engine.submit(SetState("Pause"))
                done = "drained: every tank under" if below is not None and max(levels) < below else \
                    "drain time up, a tank still at or over"
                print(f"{datetime.now():%H:%M:%S} slot: {done} {below:g} ({', '.join(f'{y:.3f}' for y in levels)})",
                      flush=True)
                reason = f"{reason}; {done} {below:g}"
                self._drain_until = None
            self._handed_over = True
            self.request_stop(reason)
            return
        before = self.slots.notice
        try:
            notice, end = self.slots.step()
        except (OSError, ValueError) as exc:
            print(f"{datetime.now():%H:%M:%S} bookings: {exc}", flush=True)
            return
        if self.slots.fresh and notice:
            print(f"{datetime.now():%H:%M:%S} slot: {notice}", flush=True)
        if notice != before:
            self._roster_changed()  # the screens' banner: the countdown
        if end is None:
            return
        self.engine.submit(SetState("Pause"))  # a real process: pumps at 0
        print(f"{datetime.now():%H:%M:%S} slot: {end}: pumps at 0", flush=True)
        snap = self.engine.snapshot()
        saving: list[Future[CommandResult]] = []
        if snap.log.active:
            saving.append(self.engine.submit(LogOff()))
        if snap.log.active or snap.log.unsaved:
            saving.append(self.engine.submit(LogSave()))
        rules = self.slots.rules
        if rules.drain_below is not None:  # pumps off and sampled, until the tanks are low (the log is saved first)
            self.engine.submit(SetControlMode("Manual"))
            self.engine.submit(SetParams({"REFERENCE ONE.Mean": 0.0, "REFERENCE ONE.On": 0,
                                          "REFERENCE TWO.Mean": 0.0, "REFERENCE TWO.On": 0}))
            self.engine.submit(SetState("Run"))
            self._drain_until = time.monotonic() + rules.drain_max_minutes * 60.0
            print(f"{datetime.now():%H:%M:%S} slot: draining, pumps at 0, until every tank is under "
                  f"{rules.drain_below:g} (at most {rules.drain_max_minutes:g} min)", flush=True)
        self.slots.notice = f"{end}: pumps at 0, the log saved" + (", draining" if self._drain_until else "") + \
            ", this session stops"
        self._roster_changed()
        self._handover = (f"{end}: pumps at 0, the log saved", saving, time.monotonic())

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
        self._watch_slot()
        self._write_record()
        if self._operator is None and snap.state == "Run" and self.scripted is None and self._handover is None:
            action = unattended_action(
                self.policy, active=snap.operation == "Active", logging=snap.log.active,
                seconds_unattended=now - self._operator_left,
                seconds_since_log=None if self._log_ended is None else now - self._log_ended)
            if action == "pause":
                self.engine.submit(SetState("Pause"))  # a real process: pumps at 0
                whose = "the default policy" if self.policy == UnattendedPolicy() else "the lab's policy"
                pumps = self.engine.pumps_unconfirmed or "pumps at 0"  # tried again each tick if not
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
            if unsafe := self.engine.pumps_unconfirmed:  # the rig's guard and watchdog were left to it
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


@dataclasses.dataclass(eq=False)
class _Pending:
    """An operator's command in the queue: `applied` once it was applied (it resolves
    when its file work is done)."""

    conn: Connection
    cid: int
    what: Command | ParReading | MPCDesigning
    applied: Future[CommandResult] | None = None


def _resolved(result: CommandResult) -> Future[CommandResult]:
    fut: Future[CommandResult] = Future()
    fut.set_result(result)
    return fut


def _outcome(fut: Future[CommandResult], name: str) -> CommandResult:
    try:
        return fut.result()
    except Exception as exc:  # noqa: BLE001 - the file work failed: say so, the session goes on
        return _failed(name, exc)


def _failed(name: str, exc: BaseException) -> CommandResult:
    return CommandResult.refused(f"{name} failed: {type(exc).__name__}: {exc}")


def _parts(rows: np.ndarray) -> Iterator[bytes]:
    """The ring buffer's rows, PART_ROWS a line, each encoded when asked for."""
    for lo in range(0, len(rows), PART_ROWS):
        yield encode_history_part(rows[lo:lo + PART_ROWS])


def _hhmm(wall: float) -> str:
    return datetime.fromtimestamp(wall).strftime("%H:%M")


def system_log(line: str) -> None:
    """`line` to syslog(3), facility authpriv, as `quadtank[PID]`; nothing if the
    machine has none (libc drops it) or the call fails."""
    try:
        import syslog

        syslog.openlog("quadtank", syslog.LOG_PID, syslog.LOG_AUTHPRIV)
        syslog.syslog(syslog.LOG_INFO, line)
    except (ImportError, OSError, ValueError):
        pass
