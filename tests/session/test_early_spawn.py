"""The session process is spawned before the launcher has checked the files or
loaded the UI (so its boot and the launcher's work overlap: benchmarks/tui_cost.py).
What that must not cost: a refused file, or a launcher interrupted while it loads
the UI, leaves no session and no process behind; a good start still attaches.
"""

from __future__ import annotations

import gc
import select
import sys
import time
from pathlib import Path

import pytest
from sessionkit import place, place_files

from quadtank_tui.cli import main
from quadtank_tui.commands import sessions as sessions_command
from quadtank_tui.session import launch
from quadtank_tui.files.proc import pid_alive
from quadtank_tui.session.runtime import ended_sessions, list_sessions

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="uses /proc")


@pytest.fixture
def spawned(monkeypatch: pytest.MonkeyPatch) -> list[launch.Spawned]:
    """Every Spawned the launcher makes, to look at its process afterwards."""
    made: list[launch.Spawned] = []
    real_init = launch.Spawned.__init__

    def init(self: launch.Spawned) -> None:
        real_init(self)
        made.append(self)

    monkeypatch.setattr(launch.Spawned, "__init__", init)
    return made


def _gone_within(pid: int, seconds: float) -> bool:
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        if not pid_alive(pid):
            return True
        time.sleep(0.02)
    return False


def test_a_refused_par_ends_the_spawned_process_without_a_session(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str],
        spawned: list[launch.Spawned]) -> None:
    runtime = tmp_path / "run"
    monkeypatch.setenv("QUADTANK_RUNTIME", str(runtime))
    monkeypatch.chdir(tmp_path)
    bad = tmp_path / "bad.par"
    bad.write_text("this is not a parameter file\n")
    assert main(["--par", str(bad)]) == 2
    assert gc.isenabled()  # paused for the TUI's start that never came (commands.pause_gc)
    err = capsys.readouterr().err
    assert err.startswith("quadtank: error: ") and "bad.par" in err
    assert len(spawned) == 1
    assert _gone_within(spawned[0].pid, 30.0), "the spawned process outlived the refusal"
    assert list_sessions(runtime) == []
    assert place_files(runtime) == []


@pytest.mark.parametrize("when", ["before it is ready", "after it said ready"])
def test_an_interrupt_while_the_ui_loads_stops_the_session_just_handed_its_spec(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, spawned: list[launch.Spawned], when: str) -> None:
    runtime = tmp_path / "run"
    monkeypatch.setenv("QUADTANK_RUNTIME", str(runtime))
    monkeypatch.chdir(tmp_path)

    def interrupted(self: launch.Spawned, timeout: float = 0.0) -> None:
        if when == "after it said ready":
            assert select.select([self._ready], [], [], 30.0)[0]
        raise KeyboardInterrupt

    monkeypatch.setattr(launch.Spawned, "wait_ready", interrupted)
    assert main([]) == 130
    assert len(spawned) == 1
    assert _gone_within(spawned[0].pid, 30.0), "a session nobody knows of was left running"
    # It stopped in order (not killed): no socket; its record and output say why.
    (ended,) = ended_sessions(runtime)
    assert ended.ended == ("its launcher went away before it was ready" if when == "before it is ready"
                           else f"stopped by {ended.owner}")
    assert place_files(runtime) == [f"{ended.id}.json", f"{ended.id}.out"]
    assert f"session {ended.id} stopped: {ended.ended}" in (place(runtime) / f"{ended.id}.out").read_text()


def test_a_good_start_attaches_to_the_session_it_spawned(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, spawned: list[launch.Spawned]) -> None:
    runtime = tmp_path / "run"
    monkeypatch.setenv("QUADTANK_RUNTIME", str(runtime))
    monkeypatch.chdir(tmp_path)
    seen: list[str] = []

    def run_tui_on(client, refresh: float) -> int:
        seen.append(client.info.id)
        client.stop_on_close = True
        client.close()
        return 0

    monkeypatch.setattr(sessions_command, "run_tui_on", run_tui_on)
    assert main([]) == 0
    assert len(spawned) == 1 and len(seen) == 1
    assert seen[0].endswith("-1")
    assert _gone_within(spawned[0].pid, 30.0)
    assert list_sessions(runtime) == []
