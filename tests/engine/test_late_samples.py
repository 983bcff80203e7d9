"""Late samples on a real process: the loop's side of the contract, without a rig.

The runner tells the loop how many sampling slots its clock skipped before a
sample (`record_timing`).  On a real process those slots went by - the water did
not wait - so t moves on over them and the log notes the late row; on the
simulator nothing went by (its time is the loop's), so nothing moves.
"""

from __future__ import annotations

from pathlib import Path
from typing import Literal

import pytest

from quadtank_tui.core.parameters import PRESET
from quadtank_tui.engine.backend import Pair, ProcessBackend
from quadtank_tui.engine.commands import LogOn, LogSave, SetOperation, SetState
from quadtank_tui.engine.loop import ControlLoop
from quadtank_tui.files.log_reader import read_log

H = PRESET.tsamp  # 0.1 s


class Rig(ProcessBackend):
    kind = "Active"
    description = "rig"

    def read_levels(self):
        return (0.6, 0.6, 0.1, 0.1)

    def write_pumps(self, u: Pair) -> None:
        pass

    def safe_state(self) -> None:
        pass


def loop_on(tmp_path: Path, operation: Literal["Simul", "Active"]) -> ControlLoop:
    loop = ControlLoop(PRESET, daq=Rig(), logs_dir=tmp_path)
    for command in (SetOperation(operation), LogOn(), SetState("Run")):
        assert loop.apply(command).ok
    return loop


def sample(loop: ControlLoop, missed: int) -> None:
    loop.record_timing(0.0, missed, 0.0)
    loop.step()


def test_on_a_real_process_missed_slots_pass_and_the_log_says_so(tmp_path: Path) -> None:
    loop = loop_on(tmp_path, "Active")
    for missed in (0, 0, 2, 0, 1):
        sample(loop, missed)
    assert loop.history.last()["t"] == pytest.approx([0, H, 4 * H, 5 * H, 7 * H])
    assert loop.t == pytest.approx(8 * H) and loop.log.late_rows == 2
    assert loop.apply(LogSave("late")).ok
    text = (tmp_path / "late.log").read_text().splitlines()
    body = text[text.index("") + 1:]
    assert [ln.startswith("%") for ln in body] == [False, False, True, False, False, True, False]
    assert body[2] == "% late: the next row was sampled 0.3 s after the previous one, not TSamp 0.1 s"
    assert body[5] == "% late: the next row was sampled 0.2 s after the previous one, not TSamp 0.1 s"
    assert read_log(tmp_path / "late.log").rows == 5


def test_the_simulator_and_a_pause_have_no_late_samples(tmp_path: Path) -> None:
    sim = loop_on(tmp_path / "sim", "Simul")
    for missed in (0, 3, 1):
        sample(sim, missed)
    assert sim.history.last()["t"] == pytest.approx([0, H, 2 * H]) and sim.log.late_rows == 0

    rig = loop_on(tmp_path / "rig", "Active")
    sample(rig, 0)
    assert rig.apply(SetState("Pause")).ok
    sample(rig, 5)                                    # an idle tick, late: nothing was due
    assert rig.apply(SetState("Run")).ok
    sample(rig, 4)                                    # slots missed while paused are not late samples
    sample(rig, 0)
    assert rig.history.last()["t"] == pytest.approx([0, H, 2 * H]) and rig.log.late_rows == 0
