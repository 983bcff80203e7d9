"""The STATE FEEDBACK section of `.par` files: old files load unchanged, new ones
round-trip, bad values name file, line and key."""

from __future__ import annotations

from datetime import datetime
from pathlib import Path

import pytest

from quadtank_tui.core.parameters import PRESET
from quadtank_tui.core.controllers.statefb.settings import StateFeedbackParams
from quadtank_tui.files.par import ParFileError, format_par, parse_par, read_par

GOLDEN = Path(__file__).parent / "golden"
STAMP = datetime(2026, 11, 22, 12, 0, 0)


@pytest.mark.parametrize("name", ["thesis_fragment1.par", "thesis_fragment2.par", "thesis_fragment3.par"])
def test_files_without_the_section_load_as_before_with_its_defaults(name: str) -> None:
    read = read_par(GOLDEN / name)
    assert read.params.statefb == StateFeedbackParams() == PRESET.statefb
    assert read.params.control.family.value in ("PID", "General")
    assert not any("STATE FEEDBACK" in w for w in read.warnings)


def test_the_type_and_the_section_round_trip() -> None:
    p = PRESET.with_values({
        "CONTROL.Type": "State feedback", "STATE FEEDBACK.Ts": 45.0,
        "STATE FEEDBACK.Poles": "-0.0575 -0.0225 -0.2+0.1j -0.2-0.1j", "STATE FEEDBACK.L3": 1.385,
        "STATE FEEDBACK.Smart": 0, "STATE FEEDBACK.LevelMargin": 1.5,
        "STATE FEEDBACK.Level1": 10.0, "STATE FEEDBACK.Level2": 11.0,
    })
    text = format_par(p, STAMP)
    assert "\nCONTROL\nMode Manual\nType State feedback\nStructure Decentralized\n" in text
    assert ("\nSTATE FEEDBACK\nTs 45.000000\nPoles -0.0575 -0.0225 -0.2+0.1j -0.2-0.1j\n"
            "L3 1.385000\nSmart 0\nLevelMargin 1.500000\nLevel1 10.000000\nLevel2 11.000000\n\nMPC\n") in text
    back = parse_par(text).params
    assert back == p
    assert back.statefb.pole_values() == (-0.0575, -0.0225, -0.2 + 0.1j, -0.2 - 0.1j)


@pytest.mark.parametrize(("line", "reason"), [
    ("Poles -0.1+0.2j", "needs its conjugate"),
    ("Poles 0.1", "negative real part"),
    ("Poles fast", "not a pole"),
    ("Ts 0", "must be >= 1"),
    ("LevelMargin 0", "must be > 0"),
])
def test_a_bad_value_names_file_line_and_key(line: str, reason: str) -> None:
    text = f"% TANK PAR-file\n\nCONTROL\nType State feedback\n\nSTATE FEEDBACK\n{line}\n"
    with pytest.raises(ParFileError) as err:
        parse_par(text, name="sf.par")
    key = line.split()[0]
    assert err.value.line == 7 and err.value.key == f"STATE FEEDBACK.{key}", str(err.value)
    assert reason in err.value.reason
