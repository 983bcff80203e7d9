"""Fixtures of the Setup screen's UI tests: the real engine with a manual clock
(no thread; time passes only in `run_for`) on private `params/` and `logs/`
folders holding the shipped files, and the app showing the Setup screen on it."""

from __future__ import annotations

import sys
from datetime import datetime
from pathlib import Path
from typing import Iterator

import pytest

from quadtank_tui.engine.runner import Engine, build_engine
from quadtank_tui.files.shipped import write_shipped

sys.path.insert(0, str(Path(__file__).parent))

from setup_app import SetupApp  # noqa: E402

EPOCH = datetime(2026, 11, 21, 6, 0, 0)


def manual_engine() -> Engine:
    """An engine in the start-up state on ./params and ./logs."""
    return build_engine(clock="manual", params_dir="params", logs_dir="logs", epoch=EPOCH)


@pytest.fixture
def engine(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[Engine]:
    # Relative folders, so messages read "params/x.par" whatever tmp_path is.
    monkeypatch.chdir(tmp_path)
    write_shipped("params")
    e = manual_engine()
    yield e
    e.stop()


@pytest.fixture
def app(engine: Engine) -> SetupApp:
    return SetupApp(engine)
