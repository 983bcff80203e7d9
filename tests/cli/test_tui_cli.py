"""`quadtank` without a subcommand starts the TUI; its options fail cleanly."""

from __future__ import annotations

import pytest

from quadtank_tui.cli import build_parser, main


@pytest.mark.parametrize("argv, word", [
    (["--speed", "0"], "--speed"),
    (["--refresh", "0"], "--refresh"),
    (["--par", "no/such/file.par"], "file.par"),
    (["--daq", "no/such/daq.conf"], "daq"),
])
def test_bad_tui_options_are_one_line_and_status_2(argv: list[str], word: str,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("quadtank: error:") and word in err and "Traceback" not in err


def test_help_says_the_tui_is_the_default() -> None:
    text = build_parser().format_help()
    assert "Without a COMMAND" in text and "--par" in text and "--refresh" in text
