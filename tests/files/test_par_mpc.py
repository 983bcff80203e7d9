"""The MPC section of `.par` files (issue 26): old files load with its defaults, a
changed section round-trips exactly, bad values name file, line and key."""

from __future__ import annotations

from datetime import datetime
from pathlib import Path

import pytest

from quadtank_tui.core.controllers.mpc.settings import MPCSettings
from quadtank_tui.core.parameters import PRESET
from quadtank_tui.files.par import ParFileError, format_par, parse_par, read_par

GOLDEN = Path(__file__).parent / "golden"
STAMP = datetime(2026, 11, 26, 12, 0, 0)


@pytest.mark.parametrize("name", ["thesis_fragment1.par", "thesis_fragment2.par", "thesis_fragment3.par"])
def test_files_without_the_section_load_with_its_defaults(name: str) -> None:
    read = read_par(GOLDEN / name)
    assert read.params.mpc == MPCSettings() == PRESET.mpc
    assert not any("MPC" in w for w in read.warnings)


def test_the_section_round_trips() -> None:
    p = PRESET.with_values({
        "MPC.Horizon": 60, "MPC.Step": 2.5, "MPC.ControlHorizon": 20, "MPC.OutputWeight": 2.5, "MPC.InputWeight": 0.05,
        "MPC.RateWeight": 0.3, "MPC.RateLimit": 0.5, "MPC.LevelMargin": 1.5, "MPC.Preview": 0,
        "MPC.Disturbance": "output", "MPC.Measured": "1 2", "MPC.SlackWeight": 500.0,
    })
    text = format_par(p, STAMP)
    assert ("\nMPC\nHorizon 60\nStep 2.500000\nControlHorizon 20\nOutputWeight 2.500000\nInputWeight 0.050000\n"
            "RateWeight 0.300000\nRateLimit 0.500000\nLevelMargin 1.500000\nPreview 0\n"
            "Disturbance output\nMeasured 1 2\nSlackWeight 500.000000\n") in text
    back = parse_par(text).params
    assert back == p
    assert back.mpc == MPCSettings(60, 20, 2.5, 0.05, 0.3, 0.5, 1.5, False, "output", "1 2", 500.0, 2.5)
    assert back.mpc.measured_states(4) == (0, 1)
    assert [back.mpc.step_samples(T) for T in (0.1, 0.5, 1.0, 2.0, 10.0)] == [25, 5, 2, 1, 1]
    assert PRESET.mpc.step == 0.0 and PRESET.mpc.step_samples(0.1) == 1  # 0: the sampling time


@pytest.mark.parametrize(("line", "reason"), [
    ("Horizon 0", "whole number in 1..1000"),
    ("Horizon 2.5", "whole"),
    ("Step -1", "must be >= 0"),
    ("Step 900", "must be <= 600"),
    ("InputWeight 0", "must be > 0"),
    ("Disturbance state", "must be one of input, output"),
    ("Measured 1 x", "not a list of tank numbers"),
])
def test_a_bad_value_names_file_line_and_key(line: str, reason: str) -> None:
    text = f"% TANK PAR-file\n\nMPC\n{line}\n"
    with pytest.raises(ParFileError) as err:
        parse_par(text, name="m.par")
    key = line.split()[0]
    assert err.value.line == 4 and err.value.key == f"MPC.{key}", str(err.value)
    assert reason in err.value.reason, err.value.reason


def test_the_command_uses_the_file_section(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    import json

    from quadtank_tui.cli import main

    f = tmp_path / "h.par"
    f.write_text(format_par(PRESET.with_values({"MPC.Horizon": 17, "MPC.RateWeight": 0.2}), STAMP))
    assert main(["mpc", "--par", str(f), "--no-compare", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)["design"]
    assert d["horizon"] == 17 and d["rate_weight"] == 0.2 and d["gain_state"] == "[x; u_prev]"
