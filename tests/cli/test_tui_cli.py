"""`quadtank` without a subcommand starts the TUI; its options fail cleanly."""

from __future__ import annotations

import pytest

from quadtank_tui.cli import build_parser, build_tui, main
from quadtank_tui.engine.process import EngineProcess
from quadtank_tui.engine.runner import Engine


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


@pytest.mark.parametrize("loop, kind", [([], EngineProcess), (["--loop", "thread"], Engine)])
def test_the_tui_runs_the_simulator_on_a_virtual_clock(loop: list[str], kind: type) -> None:
    engine, app = build_tui(build_parser().parse_args(["--speed", "4", "--refresh", "0.2", *loop]))
    try:
        assert isinstance(engine, kind)  # its own process unless asked otherwise
        s = engine.snapshot()
        assert (s.operation, s.state, s.control) == ("Simul", "Pause", "Manual")
        assert not s.realtime and s.speed == 4.0 and not s.active_available
        assert app.main.refresh_interval == 0.2
    finally:
        engine.stop()
