"""Fixtures every test folder may use."""

from __future__ import annotations

import importlib.util
import os
import shutil
import time
from pathlib import Path
from types import ModuleType
from typing import Callable

import pytest

ROOT = Path(__file__).resolve().parents[1]

#: Fixtures that run a real device, link or process: a test using one is on the wall clock.
WALLCLOCK_FIXTURES = frozenset({"rig", "link_proxy", "device", "silent_device"})


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_auto_num_workers(config: pytest.Config) -> int:
    """`-n auto` (make test): one worker per core this process may run on; none on a
    single core, where a worker only adds its start-up to the serial run (tests/docs
    pinned to one core: 21 s with one worker, 8 s without)."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1
    return cores if cores > 1 else 0


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Mark `wallclock` every test that uses a real device (tests/daq/conftest.py);
    modules on the wall clock for other reasons say so with `pytestmark`."""
    for item in items:
        if WALLCLOCK_FIXTURES & set(getattr(item, "fixturenames", ())):
            item.add_marker(pytest.mark.wallclock)


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
