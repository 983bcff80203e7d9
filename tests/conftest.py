"""Fixtures every test folder may use."""

from __future__ import annotations

import contextlib
import fcntl
import gc
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
from typing import Callable, Generator, Iterator

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


#: The most tests xdist hands a worker at once (unless --maxschedchunk says).
SCHEDULE_CHUNK = 2


def pytest_configure(config: pytest.Config) -> None:
    """xdist hands a worker that runs short of tests up to a sixth of those left, in
    the order: tests/ui's pilot tests (1.4 s each on average, 0.2 s in tests/core)
    come near the end, so one worker was handed some 50 of them at once, 70 s of
    work, and ran them alone while the two others had finished the first phase:
    it ended 46-56 s after them.  Two at a time, the workers finish together: that
    run's test durations replayed under xdist's rule end the first phase at 311 s
    without a limit, at 280 s with 2 (277.6 s of tests a worker, evenly shared)."""
    if hasattr(config.option, "maxschedchunk") and config.option.maxschedchunk is None:
        config.option.maxschedchunk = SCHEDULE_CHUNK


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Mark `wallclock` every test that uses a real device (tests/daq/conftest.py);
    modules on the wall clock for other reasons say so with `pytestmark`.  Then the
    order of the two phases (below): the tests off the wall clock as collected, then
    the wallclock ones."""
    for item in items:
        if WALLCLOCK_FIXTURES & set(getattr(item, "fixturenames", ())):
            item.add_marker(pytest.mark.wallclock)
    items.sort(key=_phase_and_turn)


def _phase_and_turn(item: pytest.Item) -> tuple[int, bool]:
    """The first phase as collected, then the wallclock tests.  Among those, the ones
    that start a whole TUI in a terminal (tests/ui) are the longest (3-10 s); last in
    the folders' order, they made the phase's tail: first, it took 88-92 s against
    99-100 s (3 workers, idle, in turns).  (The first phase with tests/ui first, the
    slowest folder, made it worse: xdist hands a worker up to a quarter of its share
    at once, and one was left with 65 s of pilot tests.)"""
    if _on_the_wall_clock(item):
        return (1, not item.nodeid.startswith("tests/ui/"))
    return (0, False)


# --- One session, two phases -------------------------------------------------------------
#
# `make test` is one pytest session on every core.  The tests on the wall clock do
# not run beside the others: a Textual pilot test on each core made the TUI in a pty
# miss its 0.8 s grace (docs/development.md).  They used to be a second pytest run,
# which started its workers and collected the whole suite again (about 13 s before
# its first test).  Now they come last in the order (above), and a worker that
# reaches one waits until every test off the wall clock has finished, on any worker:
# each worker adds a byte to a file the run's workers share when one of those ends.

#: The number of tests off the wall clock in this run (after -m, -k, deselection).
_FIRST_PHASE = pytest.StashKey[int]()
#: How long a worker waits with no test of the first phase ending before it gives up
#: (a worker that crashed never ends its test; xdist reports the crash, the run is red).
FIRST_PHASE_STALL_S = 180.0
_first_phase_over = False


def _on_the_wall_clock(item: pytest.Item) -> bool:
    return item.get_closest_marker("wallclock") is not None


def _in_a_worker() -> bool:
    """This process is a pytest-xdist worker (not a serial run, nor xdist's controller)."""
    return os.environ.get("PYTEST_XDIST_WORKER") is not None


def _run_folder(config: pytest.Config) -> Path:
    """The folder all the workers of an xdist run share (the run's temporary folder:
    xdist gives each worker a folder in it as its --basetemp).  What the workers
    coordinate by lives there: the `alone` turn, the first phase's count, what is
    built once."""
    return Path(config.getoption("basetemp")).parent


def _first_phase_file(config: pytest.Config) -> Path:
    return _run_folder(config) / "first-phase.done"


def pytest_collection_finish(session: pytest.Session) -> None:
    session.config.stash[_FIRST_PHASE] = sum(not _on_the_wall_clock(item) for item in session.items)


@pytest.hookimpl(wrapper=True)
def pytest_runtest_protocol(item: pytest.Item, nextitem: pytest.Item | None) -> Generator[None, object, object]:
    """A wallclock test waits for the first phase to be over before its setup (so
    before any of its fixtures, a module's included, starts anything, and outside
    its times in --durations); a test off the wall clock that ends, passed, failed
    or broken, adds its byte."""
    del nextitem
    on_the_wall_clock = _on_the_wall_clock(item)
    if on_the_wall_clock:
        _wait_for_the_first_phase(item.config)
    try:
        return (yield)
    finally:
        if _in_a_worker() and not on_the_wall_clock:
            fd = os.open(_first_phase_file(item.config), os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o600)
            try:
                os.write(fd, b".")  # one byte, O_APPEND: the workers' writes never overlap
            finally:
                os.close(fd)


def _wait_for_the_first_phase(config: pytest.Config) -> None:
    """Under pytest-xdist, until every test off the wall clock has ended."""
    global _first_phase_over
    if _first_phase_over or not _in_a_worker():
        return
    need = config.stash.get(_FIRST_PHASE, 0)
    path = _first_phase_file(config)
    seen, since = -1, time.monotonic()
    while True:
        done = path.stat().st_size if path.exists() else 0
        if done >= need:
            break
        if done != seen:
            seen, since = done, time.monotonic()
        elif time.monotonic() - since > FIRST_PHASE_STALL_S:
            sys.stderr.write(f"\nconftest: {done} of the {need} tests off the wall clock have ended, none for "
                             f"{FIRST_PHASE_STALL_S:.0f} s (a worker crashed?): the wallclock tests start anyway\n")
            break
        time.sleep(0.05)
    _first_phase_over = True
    # What the first phase left in this worker is collected, and what survives is
    # frozen out of later collections (as tests/ui does before each of its tests).
    # Up to 25,000 objects were left unfrozen (a full collection of them: 38 ms),
    # and with so few long-lived objects counted the collector makes a full
    # collection often: a pause of every thread of the process.  The likely cause
    # of the one sample 74 ms late that a session host on a thread of a wallclock
    # test saw (h = 100 ms, its bound h/2), in the first runs of this one session.
    gc.collect()
    gc.freeze()


@pytest.fixture(autouse=True)
def _alone_when_marked(request: pytest.FixtureRequest) -> Iterator[None]:
    """Under pytest-xdist, a test marked `alone` runs while no other test of the run
    does, and the others wait for it (a lock every test takes before its fixtures
    start anything: shared, or exclusive for an `alone` one).  `make test` runs the
    wallclock tests on every core; an `alone` one is a bound that another test's
    processes beside it would miss (a grace of 0.8 s, a sample's jitter under h/2),
    the test says which.  Serially (no xdist worker) there is nothing to wait for."""
    if not _in_a_worker():
        yield
        return
    with _turn(_run_folder(request.config), request.node.get_closest_marker("alone") is not None):
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


@pytest.fixture(scope="session")
def built_once(pytestconfig: pytest.Config,
               tmp_path_factory: pytest.TempPathFactory) -> Callable[[str, Callable[[Path], None]], Path]:
    """built_once(name, build): a folder `build` fills once for the whole run.  Under
    pytest-xdist the first worker that needs it builds it in the run's temporary
    folder, holding a lock the others wait on, and they read it.  The workers are
    handed two tests at a time (pytest_configure), so a module's tests are spread
    over them: test_identify_experiments' six 4200-s runs (6.5 s) and its two
    models were built on two or three workers.  A build that failed is done again."""
    root = _run_folder(pytestconfig) if _in_a_worker() else tmp_path_factory.getbasetemp()

    def get(name: str, build: Callable[[Path], None]) -> Path:
        folder = root / name
        lock = os.open(root / f"{name}.lock", os.O_RDWR | os.O_CREAT, 0o600)
        try:
            fcntl.flock(lock, fcntl.LOCK_EX)
            if not (folder / ".built").exists():
                shutil.rmtree(folder, ignore_errors=True)
                folder.mkdir()
                build(folder)
                (folder / ".built").touch()
        finally:
            os.close(lock)  # closing drops the flock
        return folder

    return get


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
    """A test calling cli.main for the TUI (commands/tui.py) has no terminal (pytest holds stdin and
    stdout) yet tests what comes after the check; the check itself is tested on a
    real `quadtank` process (tests/cli/test_no_terminal.py)."""
    import quadtank_tui.commands.tui

    monkeypatch.setattr(quadtank_tui.commands.tui, "terminal_missing", lambda: None)


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
