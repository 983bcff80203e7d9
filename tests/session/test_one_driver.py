"""One driver (issue 25): every way the control loop runs goes through
engine.driver.Driver, counted - in this process by its class counter, in a session
process by a hook (sitecustomize) that notes each drive in a file."""

from __future__ import annotations

import os
import sys
from pathlib import Path
from typing import Any, Callable

import pytest

from quadtank_tui.cli import main
from quadtank_tui.engine.commands import SetState
from quadtank_tui.engine.driver import Driver
from quadtank_tui.engine.runner import build_engine, engine_spec
from quadtank_tui.session.client import SessionClient, stop_session_at
from quadtank_tui.session.launch import SessionSpec, start_session
from quadtank_tui.session.runtime import ended_sessions, list_sessions

ROOT = Path(__file__).parents[2]

#: Imported at the start of every interpreter whose path holds it: notes each drive
#: (run inline or served on an event loop) of that process in $QUADTANK_DRIVES.
HOOK = '''
import os
if os.environ.get("QUADTANK_DRIVES"):
    from quadtank_tui.engine.driver import Driver

    def _noted(kind, real):
        def drive(self, *args, **kwargs):
            with open(os.environ["QUADTANK_DRIVES"], "a") as f:
                f.write(f"{kind} {os.getpid()}\\n")
            return real(self, *args, **kwargs)
        return drive

    Driver.run = _noted("run", Driver.run)
    Driver.serve = _noted("serve", Driver.serve)
'''


def _drives(action: Callable[[], Any]) -> int:
    before = Driver.started
    action()
    return Driver.started - before


def test_a_thread_session_is_served_by_the_driver(thread_session, poll) -> None:
    before = Driver.started
    s = thread_session()
    assert poll(lambda: Driver.started == before + 1, 30.0)
    assert s.host.driver.engine is s.engine and s.host.driver.aloop is not None


def test_quadtank_run_and_the_engine_by_hand_are_the_driver(tmp_path: Path) -> None:
    out = tmp_path / "out.log"
    assert _drives(lambda: main(["run", "--duration", "2", "--log", str(out)])) == 1
    assert out.exists()
    e = build_engine(clock="manual", params_dir=tmp_path, logs_dir=tmp_path)
    with e:
        assert _drives(lambda: e.step(3)) == 1
        assert _drives(lambda: e.run_for(1.0)) == 1
        assert e.snapshot().stats.samples == 3 + 10


def test_a_benchmark_is_the_driver(tmp_path: Path) -> None:
    sys.path.insert(0, str(ROOT / "benchmarks"))
    try:
        from session_timing import headless_speed
    finally:
        sys.path.remove(str(ROOT / "benchmarks"))
    assert _drives(lambda: headless_speed(0.05)) == 1


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="session processes")
def test_the_session_processes_are_the_driver(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                             poll: Callable[..., bool]) -> None:
    """The default session (the TUI's) and `quadtank run --detach` (its script
    rehearsed here first, by the driver too): each process drives once."""
    hook = tmp_path / "hook"
    hook.mkdir()
    (hook / "sitecustomize.py").write_text(HOOK)
    noted = tmp_path / "drives"
    monkeypatch.setenv("QUADTANK_DRIVES", str(noted))
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(hook), str(ROOT)]))
    runtime = tmp_path / "run"
    monkeypatch.setenv("QUADTANK_RUNTIME", str(runtime))
    spec = engine_spec(clock="virtual", speed=100.0, params_dir=tmp_path / "params", logs_dir=tmp_path / "logs")
    info = start_session(SessionSpec(spec, str(runtime)))
    with SessionClient(info.socket) as client:
        assert client.submit(SetState("Run")).result(30).ok
    stop_session_at(info.socket)
    assert poll(lambda: noted.exists() and f"serve {info.pid}\n" in noted.read_text(), 30.0)

    script = tmp_path / "exp.yaml"
    script.write_text("- at: 1\n  mode: Manual\n")
    before = Driver.started
    assert main(["run", "--detach", "--script", str(script), "--duration", "2",
                 "--log", str(tmp_path / "detached.log")]) == 0
    assert Driver.started == before + 1  # the rehearsal, in this process
    assert poll(lambda: len(noted.read_text().splitlines()) == 2, 30.0)
    assert poll(lambda: not list_sessions(runtime), 30.0)  # the detached run is over
    lines = noted.read_text().splitlines()
    assert len(lines) == 2 and all(line.startswith("serve ") for line in lines)
    assert len({line.split()[1] for line in lines}) == 2  # two processes, one drive each
    assert len(ended_sessions(runtime)) == 2
