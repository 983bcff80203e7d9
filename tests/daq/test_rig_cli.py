"""`quadtank rig` refuses bad options with one line, never a traceback."""

from __future__ import annotations

import socket

import pytest

from quadtank_tui.cli import main


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--speed", "0"], "--speed must be a number > 0, got 0.0"),
        (["--speed", "nan"], "--speed must be a number > 0, got nan"),
        (["--noise", "-1"], "--noise must be a number >= 0, got -1.0"),
        (["--reply-delay", "-0.5"], "--reply-delay must be a number >= 0, got -0.5"),
        (["--noise", "nan"], "--noise must be a number >= 0, got nan"),
        (["--offset", "nan"], "--offset must be a number of volts, got nan"),
        (["--lsb", "nan"], "--lsb must be a number >= 0, got nan"),
        (["--reply-delay", "nan"], "--reply-delay must be a number >= 0, got nan"),
        (["--status", "nan"], "--status must be a number >= 0, got nan"),
        (["--watchdog", "inf"], "--watchdog must be a number >= 0, got inf"),
        (["--port", "70000"], "--port must be in 0..65535, got 70000"),
        (["--map", "siemens"], "siemens: no such file"),
        (["--par", "nope.par"], "nope.par"),
    ],
)
def test_bad_options(args: list[str], message: str, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["rig", *args]) == 2
    err = capsys.readouterr().err
    assert err.startswith("quadtank: error: ") and message in err and err.count("\n") == 1


def test_a_port_in_use_is_one_line(capsys: pytest.CaptureFixture[str]) -> None:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        port = s.getsockname()[1]
        assert main(["rig", "--port", str(port)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("quadtank: error: ") and str(port) in err and err.count("\n") == 1
