"""Shared pieces of the UI tests: the app on the real engine with a manual clock.

The engine only moves when a test calls `run_for`, commands apply at once, and
the wall clock the status line uses is fixed, so screens are reproducible.
"""

from __future__ import annotations

import sys
from datetime import datetime
from pathlib import Path
from typing import Any, Callable

import pytest

# The tests import Recording and make_app from here (pytest's importlib mode
# does not put the test folder on sys.path).
sys.path.insert(0, str(Path(__file__).parent))

from quadtank_tui.core.parameters import PRESET, Parameters
from quadtank_tui.engine.commands import Command
from quadtank_tui.engine.runner import Engine, build_engine
from quadtank_tui.files.par import format_par
from quadtank_tui.files.shipped import write_shipped
from quadtank_tui.ui import keyorder
from quadtank_tui.ui.app import QuadTankApp, build_app
from quadtank_tui.ui.widgets.analysis_panel import warm_up

# The analysis stack loaded once, up front: the Setup screen then shows its
# analysis at once, as it does after the Main screen's warm-up in a terminal
# (test_help_and_keys.py checks the path where it is not loaded yet).
warm_up()

EPOCH = datetime(2026, 1, 5, 9, 0, 0)


@pytest.fixture(autouse=True)
def _keys_wait_as_long_as_a_loaded_machine_needs(monkeypatch: pytest.MonkeyPatch) -> None:
    """A key that opens a window is waited for until the window is up, not at most
    KEY_CAP (2 s): on a loaded CI machine mounting a window took longer and the
    next key of a burst went to the window behind (test_trust's logging burst).  The
    tests check where keys go, not the cap for a key lost on the way."""
    monkeypatch.setattr(keyorder, "KEY_CAP", 30.0)


class Recording:
    """The engine, remembering every command the UI sent it (what a test checks
    is what reached the engine)."""

    def __init__(self, engine: Engine) -> None:
        self.engine = engine
        self.commands: list[Command] = []

    def submit(self, command: Command) -> Any:
        self.commands.append(command)
        return self.engine.submit(command)

    def sent(self, kind: type) -> list[Any]:
        return [cmd for cmd in self.commands if isinstance(cmd, kind)]

    def __getattr__(self, name: str) -> Any:
        return getattr(self.engine, name)


def write_params(folder: Path, params: Parameters) -> Path:
    """A params/ folder whose default.par holds `params`."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "default.par").write_text(format_par(params, EPOCH), encoding="ascii")
    return folder


@pytest.fixture
def make_engine(tmp_path: Path) -> Callable[..., Recording]:
    def make(params: Parameters = PRESET, **kwargs: Any) -> Recording:
        options: dict[str, Any] = dict(clock="manual", seed=1, epoch=EPOCH,
                                       params_dir=write_params(tmp_path / "params", params),
                                       logs_dir=tmp_path / "logs")
        options.update(kwargs)
        (tmp_path / "logs").mkdir(exist_ok=True)
        return Recording(build_engine(**options))
    return make


@pytest.fixture
def engine(make_engine: Callable[..., Recording]) -> Recording:
    return make_engine()


def make_app(engine: Any) -> QuadTankApp:
    """The app as the CLI builds it, with a fixed wall clock (the status line's
    "last sample ... ago" must not depend on when the test runs)."""
    return build_app(engine, refresh_interval=0.05, wall_clock=lambda: 0.0)
# --- the Setup screen's tests ----------------------------------------------------------------

@pytest.fixture
def setup_engine(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Recording:
    """The engine on ./params (the shipped files) and ./logs, in a private folder:
    relative folders, so a message reads "params/x.par" whatever tmp_path is."""
    monkeypatch.chdir(tmp_path)
    write_shipped("params")
    engine = Recording(manual_engine())
    yield engine  # type: ignore[misc]
    engine.stop()


def manual_engine() -> Engine:
    """An engine in the start-up state on ./params and ./logs."""
    return build_engine(clock="manual", params_dir="params", logs_dir="logs", epoch=EPOCH)


@pytest.fixture
def setup_app(setup_engine: Recording) -> QuadTankApp:
    """The app as the CLI builds it; `await open_setup(pilot)` goes to Setup."""
    return make_app(setup_engine)


async def open_setup(pilot: Any) -> None:
    """From Main to Setup by its key, as a user does."""
    await pilot.pause()
    await pilot.press("S")
    await pilot.pause()
