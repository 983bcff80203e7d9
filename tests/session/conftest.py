"""The session tests' fixtures; their helpers live in sessionkit.py (a name of its
own: pytest's importlib mode and the other folders' `conftest` modules)."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any, Callable, Iterator

import pytest

sys.path.insert(0, str(Path(__file__).parent))

from sessionkit import ThreadSession  # noqa: E402


@pytest.fixture
def thread_session(tmp_path: Path) -> Iterator[Callable[..., ThreadSession]]:
    made: list[ThreadSession] = []

    def make(**kwargs: Any) -> ThreadSession:
        s = ThreadSession(tmp_path, **kwargs)
        made.append(s)
        return s

    yield make
    for s in made:
        s.stop()


@pytest.fixture(autouse=True)
def _no_guard_outlives_its_test(guards_of_this_test: object) -> None:
    """A test against a dead or hung device leaves a guard retrying its stop for up
    to 2 minutes (daq/guard.py GIVE_UP_S): the test's own guards end with it."""
