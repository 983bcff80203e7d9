"""`make test` is one pytest session in two phases (tests/conftest.py): under
pytest-xdist a test on the wall clock starts only once every test off it has ended,
on any worker, before any of its fixtures runs."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

CONFTEST = Path(__file__).with_name("conftest.py")

#: The wallclock tests come first in the file: the order alone does not hold them back.
CASE = '''
import pathlib
import time

import pytest

LOG = pathlib.Path(__file__).with_name("times.txt")


def _note(what: str) -> None:
    with LOG.open("a") as f:
        f.write(f"{what} {time.monotonic()}\\n")


@pytest.fixture(scope="module")
def started_device() -> None:
    _note("fixture")


@pytest.mark.wallclock
def test_on_the_clock_1(started_device: None) -> None:
    _note("on")


@pytest.mark.wallclock
def test_on_the_clock_2(started_device: None) -> None:
    _note("on")


def test_off_the_clock() -> None:
    _note("off-start")
    time.sleep(1.0)
    _note("off-end")
'''


def test_a_wallclock_test_waits_for_the_tests_off_the_wall_clock_on_other_workers(tmp_path: Path) -> None:
    shutil.copy(CONFTEST, tmp_path / "conftest.py")
    (tmp_path / "test_case.py").write_text(CASE)
    (tmp_path / "pytest.ini").write_text("[pytest]\nmarkers =\n    wallclock: x\n    alone: x\n")
    env = {k: v for k, v in os.environ.items() if not k.startswith("PYTEST_")}  # not this run's worker
    env["PYTEST_DISABLE_PLUGIN_AUTOLOAD"] = "1"  # xdist alone: 1.5 s of CPU, not 4
    run = subprocess.run([sys.executable, "-m", "pytest", "-p", "xdist", "-n", "2", "-p", "no:cacheprovider", "-q",
                          "--basetemp", str(tmp_path / "basetemp"), "test_case.py"],
                         cwd=tmp_path, env=env, capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stdout + run.stderr
    assert "3 passed" in run.stdout
    times: dict[str, list[float]] = {}
    for line in (tmp_path / "times.txt").read_text().splitlines():
        what, t = line.split()
        times.setdefault(what, []).append(float(t))
    # Two workers: the test off the clock on one, a wallclock test on the other at once.
    assert len(times["on"]) == 2 and len(times["off-end"]) == 1
    assert min(times["on"] + times["fixture"]) > times["off-end"][0]
