"""Engines for tests: no thread, unpaced virtual time, folders under tmp_path."""

from __future__ import annotations

from pathlib import Path
from typing import Callable, Iterator

import pytest

from quadtank_tui.engine.backend import Levels4, Pair, ProcessBackend
from quadtank_tui.engine.runner import Engine, build_engine


@pytest.fixture
def make_engine(tmp_path: Path) -> Iterator[Callable[..., Engine]]:
    made: list[Engine] = []

    def make(**kwargs: object) -> Engine:
        kwargs.setdefault("clock", "manual")
        kwargs.setdefault("params_dir", tmp_path / "params")
        kwargs.setdefault("logs_dir", tmp_path / "logs")
        engine = build_engine(**kwargs)  # type: ignore[arg-type]
        made.append(engine)
        return engine

    yield make
    for engine in made:
        engine.stop()


class RecordingRig(ProcessBackend):
    """A real process (Active) at fixed levels that records what it is told:
    "pumps u1 u2", "safe", "close"."""

    kind = "Active"
    description = "rig"

    def __init__(self) -> None:
        self.calls: list[str] = []

    def read_levels(self) -> Levels4:
        return (0.6, 0.6, 0.1, 0.1)

    def write_pumps(self, u: Pair) -> None:
        self.calls.append(f"pumps {u[0]:g} {u[1]:g}")

    def safe_state(self) -> None:
        self.calls.append("safe")

    def close(self) -> None:
        self.calls.append("close")


@pytest.fixture
def rig() -> RecordingRig:
    return RecordingRig()
