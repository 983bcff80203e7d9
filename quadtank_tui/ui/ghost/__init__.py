"""Old runs as ghost traces: a saved `.log` drawn dimmed in the trends
behind the live signals, so a student compares today's controller with
yesterday's.

`GhostControl` is the Main screen's part: it opens the window, reads the file in
a worker (files/ghost.py does the reading), and works out where the ghost's
first row goes: at the current log's LogOn (until there is one, where the
process was when it was loaded) or at a chosen process time.  On a session the
choice is remembered for this user (files/ghost_memory.py) and drawn again when a
client re-attaches to the same session.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Protocol

from textual.app import App

from quadtank_tui.engine.handle import EngineHandle, lab_session_of
from quadtank_tui.engine.snapshot import Snapshot
from quadtank_tui.files.ghost import LoggedRun, load_run, logs_newest_first
from quadtank_tui.files.ghost_memory import RememberedGhost, recall, remember
from quadtank_tui.files.log_reader import LogFileError
from quadtank_tui.ui.ghost.window import GhostChoice, GhostWindow

class GhostHost(Protocol):
    """What the ghost needs of the screen it draws on (the Main screen): named
    here rather than imported, so ui/ghost does not depend on ui/screens, which
    depends on it."""

    @property
    def engine(self) -> EngineHandle: ...  # read-only

    @property
    def app(self) -> App[Any]: ...

    def current(self) -> Snapshot: ...

    def refresh_view(self) -> None: ...

    def notify(self, message: str, *, severity: Any = ..., timeout: float | None = ...,
               markup: bool = ...) -> None: ...

    def run_worker(self, work: Any, *, thread: bool = ..., group: str = ..., exclusive: bool = ...,
                   exit_on_error: bool = ...) -> Any: ...


class GhostControl:
    """The ghost run of the Main screen's trends."""

    def __init__(self, screen: GhostHost) -> None:
        self.screen = screen
        self.run: LoggedRun | None = None
        #: Process time of the ghost's first row when chosen, else None: at LogOn.
        self.at: float | None = None
        self._loaded_at = 0.0
        self._logon: float | None = None
        self._rows = 0

    @property
    def start(self) -> float:
        """Process time of the ghost's first row, s."""
        if self.at is not None:
            return self.at
        return self._logon if self._logon is not None else self._loaded_at

    def follow(self, snap: Snapshot) -> None:
        """Keep the LogOn time of the current log: its first row was logged
        `rows` samples before the snapshot's time (which is that of the next
        sample)."""
        log = snap.log
        if log.rows and (self._rows == 0 or log.rows < self._rows):  # a new log
            self._logon = snap.t - log.rows * snap.params.tsamp
        self._rows = log.rows

    def folder(self) -> Path:
        return Path(self.screen.engine.logs_dir)

    def choose(self) -> None:
        now = self.screen.current().t
        window = GhostWindow(logs_newest_first(self.folder()), at=self.at, now=now, opener="b")
        self.screen.app.push_screen(window, self._chosen)

    def session(self) -> str | None:
        """The key the ghost is remembered under: the session's id and start, when
        the screen shows a lab session (its handle offers one), else None."""
        session = lab_session_of(self.screen.engine)
        return f"{session.session_id} {session.started}" if session is not None else None

    def restore(self) -> None:
        """Draw again the ghost this user showed on this session (a re-attach)."""
        session = self.session()
        remembered = recall(session) if session is not None else None
        if remembered is not None:
            choice = GhostChoice(Path(remembered.path), remembered.at)
            self.screen.run_worker(lambda: self._load(choice, remembered.loaded_at), thread=True,
                                   group="ghost", exclusive=True, exit_on_error=False)

    def _chosen(self, choice: GhostChoice | None) -> None:
        if choice is None:
            return
        self.screen.run_worker(lambda: self._load(choice), thread=True, group="ghost",
                               exclusive=True, exit_on_error=False)

    def _load(self, choice: GhostChoice, loaded_at: float | None = None) -> None:
        """In a worker thread: read the file, then hand it to the screen."""
        try:
            run = load_run(choice.path)
        except LogFileError as exc:
            # The message quotes the file (a row's text, its name): plain text.
            self.screen.app.call_from_thread(self.screen.notify, f"Ghost run: {exc}",
                                             severity="error", timeout=8, markup=False)
            return
        self.screen.app.call_from_thread(self.loaded, run, choice.at, loaded_at, choice.path)

    def loaded(self, run: LoggedRun, at: float | None, loaded_at: float | None = None,
               path: Path | None = None) -> None:
        """`loaded_at`: the process time it was first loaded at (a restored ghost)."""
        self.run, self.at = run, at
        self._loaded_at = self.screen.current().t if loaded_at is None else loaded_at
        session = self.session()
        if session is not None and path is not None:
            remember(session, RememberedGhost(str(Path(path).resolve()), at, self._loaded_at))
        if at is not None:
            where = f"from t = {at:g} s"
        elif self._logon is not None:
            where = f"from the LogOn at t = {self._logon:g} s"
        else:
            where = f"from now (t = {self._loaded_at:g} s) until a LogOn"
        self.screen.notify(f"Ghost run {run.name} ({len(run.t)} rows) drawn dimmed {where}; B clears it.",
                           timeout=5, markup=False)
        self.screen.refresh_view()

    def clear(self) -> None:
        if self.run is not None:
            self.run = None
            session = self.session()
            if session is not None:
                remember(session, None)
            self.screen.refresh_view()
