"""`quadtank` without a subcommand starts the TUI; its options fail cleanly."""

from __future__ import annotations

import os

import pytest

import time
from pathlib import Path

from quadtank_tui.cli import build_parser, main
from quadtank_tui.commands.tui import build_tui
from quadtank_tui.engine.handle import lab_session_of
from quadtank_tui.files.proc import pid_alive
from quadtank_tui.session.runtime import list_sessions


@pytest.mark.parametrize("argv, word", [
    (["--speed", "0"], "--speed"),
    (["--refresh", "0"], "--refresh"),
    (["--par", "no/such/file.par"], "file.par"),
    (["--daq", "no/such/daq.yaml"], "daq.yaml"),
])
def test_bad_tui_options_are_one_line_and_status_2(argv: list[str], word: str,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("quadtank: error:") and word in err and "Traceback" not in err


def test_help_says_the_tui_is_the_default() -> None:
    text = build_parser().format_help()
    assert "Without a COMMAND" in text and "--par" in text and "--refresh" in text


def test_tui_options_do_not_shadow_run_options() -> None:
    args = build_parser().parse_args(["--par", "minphase", "run", "--par", "nonminphase",
                                      "--duration", "1", "--log", "x.log"])
    assert (args.tui_par, args.par) == ("minphase", "nonminphase")


def test_loop_thread_is_gone(capsys: pytest.CaptureFixture[str]) -> None:
    """One way to run the loop in a terminal: a session (lab or private)."""
    with pytest.raises(SystemExit):
        build_parser().parse_args(["--loop", "thread"])
    assert "--loop" not in build_parser().format_help()


def test_no_session_is_a_private_session_on_a_virtual_clock(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """--no-session: the session process and protocol, for this terminal alone: not
    listed, nothing to detach from (Exit stops it), gone with its client."""
    runtime = tmp_path / "run"
    monkeypatch.setenv("QUADTANK_RUNTIME", str(runtime))
    monkeypatch.chdir(tmp_path)
    engine, app = build_tui(build_parser().parse_args(["--no-session", "--speed", "4", "--refresh", "0.2"]))
    try:
        s = engine.snapshot()
        assert (s.operation, s.state, s.control) == ("Simul", "Pause", "Manual")
        assert not s.realtime and s.speed == 4.0 and not s.active_available
        assert app.main.refresh_interval == 0.2
        assert list_sessions(runtime) == [] and lab_session_of(engine) is None
        (folder,) = (runtime / "users" / str(os.getuid())).iterdir()  # its own, the owner's only
        assert folder.name.startswith("private-") and folder.stat().st_mode & 0o777 == 0o700
        assert Path(engine.info.socket).parent == folder and Path(engine.info.socket).stat().st_mode & 0o777 == 0o600
        pid = engine.info.pid
    finally:
        engine.stop()
    assert engine.ended == "stopped by " + engine.info.owner
    deadline = time.monotonic() + 30
    while pid_alive(pid) and time.monotonic() < deadline:
        time.sleep(0.02)
    assert not pid_alive(pid)
    assert sorted((runtime / "users" / str(os.getuid())).iterdir()) == []  # its socket, record and output went
