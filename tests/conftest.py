"""Fixtures every test folder may use."""

from __future__ import annotations

import contextlib
import fcntl
import importlib.util
import itertools
import os
import shutil
import signal
import socket
import sys
import time
from pathlib import Path
from types import ModuleType
from typing import Callable, Iterator

import pytest

from quadtank_tui.files.proc import process_state

ROOT = Path(__file__).resolve().parents[1]

# The test modules' bytecode, with pytest's rewritten asserts, is kept in their
# __pycache__ even where the environment says not to write bytecode
# (PYTHONDONTWRITEBYTECODE, set on this project's machines): without it every
# pytest process, each xdist worker of both parts of `make test`, rewrote and
# compiled all 330 test modules again, 12 s of its 18 s collection (5.8 s with the
# cache).  Only the files under tests/ and what they import from outside the
# package are written; the package's own bytecode is `make`'s (compileall).
sys.dont_write_bytecode = False



def pytest_sessionstart(session: pytest.Session) -> None:
    """An xdist worker rewrites the test modules' asserts ahead of its collection,
    starting a 1/n of the way into the list for the n-th of n workers, and skips
    each one whose rewritten bytecode is there already (written by another worker:
    pytest writes it whole, by a rename).  The workers start together and collect in
    the same order, so each rewrote all 330 modules at the same time as the others
    (17.6 s of CPU each, cold); this way each rewrites about a third, and its
    collection then finds them all.  Uses pytest's own rewriting
    (_pytest.assertion.rewrite): if that ever moves, the collection rewrites as before."""
    worker = os.environ.get("PYTEST_XDIST_WORKER", "")
    count = int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "1"))
    if not worker.startswith("gw") or count < 2 or sys.dont_write_bytecode:
        return
    try:
        from _pytest.assertion.rewrite import PYC_TAIL, _rewrite_test, _write_pyc, assertstate_key, get_cache_dir
        state = session.config.stash[assertstate_key]
    except (ImportError, KeyError):  # another pytest, or asserts not rewritten (--assert=plain)
        return
    files = sorted(Path(__file__).parent.rglob("test_*.py"))
    start = len(files) * int(worker[2:]) // count
    for source in files[start:] + files[:start]:
        pyc = get_cache_dir(source) / (source.name[:-3] + PYC_TAIL)
        if pyc.exists():  # if stale, the collection's own check rewrites it
            continue
        try:
            pyc.parent.mkdir(exist_ok=True)
            stat, code = _rewrite_test(source, session.config)
            _write_pyc(state, code, stat, pyc)
        except Exception:  # noqa: BLE001 - a speed-up only: the collection meets it and says what is wrong
            continue


#: Fixtures that run a real device, link or process: a test using one is on the wall clock.
WALLCLOCK_FIXTURES = frozenset({"rig", "link_proxy", "device", "silent_device"})


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_auto_num_workers(config: pytest.Config) -> int:
    """`-n auto` (make test): one worker per core this process may run on, and one
    more; none on a single core, where a worker only adds its start-up to the serial
    run (tests/docs pinned to one core: 21 s with one worker, 8 s without).

    The extra worker fills the time a core would stand idle while a test waits: a
    pilot test for Textual's next frame or a window's worker, a wallclock test for
    its processes and timeouts.  Measured on the idle 2-core machine, one run each:
    the first part 264 s with 2 workers (85 % of the cores busy), 251 s with 3
    (96 %); the wallclock part 100 s with 2, 87 s with 3, 85 s with 4."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1
    return cores + 1 if cores > 1 else 0


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Mark `wallclock` every test that uses a real device (tests/daq/conftest.py);
    modules on the wall clock for other reasons say so with `pytestmark`."""
    for item in items:
        if WALLCLOCK_FIXTURES & set(getattr(item, "fixturenames", ())):
            item.add_marker(pytest.mark.wallclock)
    # The wallclock tests that start a whole TUI in a terminal (tests/ui) are the
    # longest of that part (3-10 s); last in the folders' order, they made its tail:
    # first, the part took 88-92 s against 99-100 s (3 workers, idle, in turns).
    items.sort(key=lambda item: not (item.nodeid.startswith("tests/ui/") and item.get_closest_marker("wallclock")))


@pytest.fixture(autouse=True)
def _alone_when_marked(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory) -> Iterator[None]:
    """Under pytest-xdist, a test marked `alone` runs while no other test of the run
    does, and the others wait for it (a lock every test takes before its fixtures
    start anything: shared, or exclusive for an `alone` one).  `make test` runs the
    wallclock tests on every core; an `alone` one is a bound that another test's
    processes beside it would miss (a grace of 0.8 s, a sample's jitter under h/2),
    the test says which.  Serially (no xdist worker) there is nothing to wait for."""
    if os.environ.get("PYTEST_XDIST_WORKER") is None:
        yield
        return
    with _turn(tmp_path_factory.getbasetemp().parent, request.node.get_closest_marker("alone") is not None):
        yield


@contextlib.contextmanager
def _turn(folder: Path, alone: bool) -> Iterator[None]:
    """A readers-writer lock across the run's workers (flock on two files in the
    run's temporary folder, which the workers share).  The gate: an `alone` test
    holds it from its request to its end, so no test starts meanwhile and the
    tests already running finish (flock alone would let new shared holders in
    ahead of a waiting exclusive one for ever)."""
    gate = os.open(folder / "alone.gate", os.O_RDWR | os.O_CREAT, 0o600)
    turn = os.open(folder / "alone.turn", os.O_RDWR | os.O_CREAT, 0o600)
    try:
        if alone:
            fcntl.flock(gate, fcntl.LOCK_EX)
            fcntl.flock(turn, fcntl.LOCK_EX)
        else:
            fcntl.flock(gate, fcntl.LOCK_SH)
            fcntl.flock(turn, fcntl.LOCK_SH)
            fcntl.flock(gate, fcntl.LOCK_UN)
        yield
    finally:
        os.close(turn)  # closing drops the flocks
        os.close(gate)


def poll(condition: Callable[[], bool], timeout: float, every: float = 0.05) -> bool:
    """True as soon as `condition()` holds; False after `timeout` s of trying."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if condition():
            return True
        time.sleep(every)
    return condition()


@pytest.fixture(name="poll")
def poll_fixture() -> Callable[..., bool]:
    return poll


@pytest.fixture
def unused_port() -> Iterator[int]:
    """A loopback TCP port nobody listens on, bound (never listening) for the test's
    time: a connection to it is refused, and no rig or server of a test running at
    the same time takes it meanwhile, as it could a port found free and let go."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        yield int(s.getsockname()[1])


#: The environment variable that marks a test's processes: the test process sets it
#: for the test's time, so whatever the test starts (a guard, a session that starts
#: a guard, `quadtank run --daq`) inherits it.
GUARD_MARK = "QUADTANK_TEST_MARK"
_marks = itertools.count(1)


class GuardsOfATest:
    """The DAQ guard processes one test started, found by its mark in their
    environment (never by name alone: other tests run in parallel, in other
    pytest-xdist workers and other checkouts).  A guard retries its stop for up to
    GIVE_UP_S (120 s) after a run against a dead or hung device: right on a rig,
    a process left behind by a test."""

    variable = GUARD_MARK

    def __init__(self) -> None:
        self.mark = f"{os.getpid()}-{next(_marks)}"
        self._entry = f"{GUARD_MARK}={self.mark}".encode()

    def alive(self) -> list[int]:
        found = []
        for name in os.listdir("/proc"):
            if not name.isdigit():
                continue
            try:
                with open(f"/proc/{name}/cmdline", "rb") as f:
                    if b"quadtank_tui.daq.guard" not in f.read():
                        continue
                with open(f"/proc/{name}/environ", "rb") as f:
                    if self._entry not in f.read().split(b"\0"):
                        continue
            except OSError:  # gone meanwhile, or another user's
                continue
            if process_state(int(name)):  # a zombie is gone
                found.append(int(name))
        return found

    def end(self, timeout: float = 10.0) -> list[int]:
        """SIGTERM each of them and wait until they are gone; those still there.

        Gone is judged by each pid's state, not by looking for the mark again: a
        process that is exiting has already given up its command line and
        environment while it still runs (state R), so the search no longer found
        it although it was there (test_guard_leftovers failed so once in CI, with
        3 workers on 2 cores)."""
        found = self.alive()  # (one look at /proc, about 2 ms: most tests start no guard)
        if not found:
            return []
        for pid in found:
            try:
                os.kill(pid, signal.SIGTERM)
            except ProcessLookupError:
                pass
        poll(lambda: not any(process_state(pid) for pid in found), timeout, every=0.01)
        return [pid for pid in found if process_state(pid)]


@pytest.fixture
def guards_of_this_test(monkeypatch: pytest.MonkeyPatch) -> Iterator[GuardsOfATest]:
    """Marks the test's processes; at its end, ends the guards it started and fails
    if one is left."""
    guards = GuardsOfATest()
    monkeypatch.setenv(GUARD_MARK, guards.mark)
    yield guards
    left = guards.end()
    assert not left, f"the test left DAQ guard processes that would not end: {left}"


@pytest.fixture(autouse=True)
def _runtime_of_its_own(monkeypatch: pytest.MonkeyPatch, tmp_path_factory: pytest.TempPathFactory) -> None:
    """Every test its own runtime folder (session sockets and records, DAQ locks), its
    own state folder (the ghosts a client remembers, files/ghost_memory.py) and no
    lab file named: a test run leaves nothing in the machine's /tmp/quadtank-sessions
    or the user's ~/.local/state, never lists, attaches to or locks out a lab's real
    sessions, and tests running at the same time (`make test` runs them on every
    core) share none of these.  A test about one of them sets or removes the
    variable itself."""
    monkeypatch.setenv("QUADTANK_RUNTIME", str(tmp_path_factory.mktemp("runtime")))
    monkeypatch.setenv("XDG_STATE_HOME", str(tmp_path_factory.mktemp("state")))
    monkeypatch.delenv("QUADTANK_LAB", raising=False)


@pytest.fixture(autouse=True)
def _a_terminal_for_main(monkeypatch: pytest.MonkeyPatch) -> None:
    """A test calling cli.main for the TUI has no terminal (pytest holds stdin and
    stdout) yet tests what comes after the check; the check itself is tested on a
    real `quadtank` process (tests/cli/test_no_terminal.py)."""
    import quadtank_tui.cli

    monkeypatch.setattr(quadtank_tui.cli, "terminal_missing", lambda: None)


def copy_params(folder: Path) -> Path:
    """A private copy of the repository's params/ (and an empty logs/) in `folder`:
    a test that runs a command the way a user does, from a folder holding params/,
    neither depends on nor writes into the checkout (issue 18)."""
    shutil.copytree(ROOT / "params", folder / "params")
    (folder / "logs").mkdir(exist_ok=True)
    return folder


@pytest.fixture
def in_params_copy(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """The working directory is a folder with a copy of params/ (see copy_params)."""
    folder = copy_params(tmp_path / "work")
    monkeypatch.chdir(folder)
    return folder


@pytest.fixture(scope="session")
def pty_kit() -> ModuleType:
    """The pseudo-terminal harness of tests/ui/test_terminal_hangup.py (Tui,
    _wait_gone, GONE_WITHIN), for the session and rig tests that
    run `quadtank` in a terminal too: one copy of it, loaded once."""
    spec = importlib.util.spec_from_file_location("hangup_kit", ROOT / "tests" / "ui" / "test_terminal_hangup.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module
