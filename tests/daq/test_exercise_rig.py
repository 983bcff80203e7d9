"""An exercise attempt on the virtual rig (Active over Modbus TCP on loopback) is
recorded with what the program knows of the rig, and graded as read, not
reproduced; an edited rig log is named.

The rig's model runs in this process behind our Modbus server, on a clock the
test moves one sampling time before each read (as tests/daq/test_active_end_to_end.py),
so the run does not depend on the machine's load."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Callable

from daqkit import VIRTUAL_RIG

from quadtank_tui.app.exercise import run_attempt
from quadtank_tui.app.grade import grade_record, load_exercises
from quadtank_tui.daq.config import load_daq_config
from quadtank_tui.daq.modbus import ModbusBackend
from quadtank_tui.daq.rig import VirtualRig
from quadtank_tui.files.exercise import read_exercise
from quadtank_tui.files.par import read_par

ROOT = Path(__file__).parents[2]
EXERCISES = ROOT / "params" / "exercises"
H = 1.0  # the exercise's sampling time, s

EXERCISE = """\
title: "P-: a step on the rig"
text: A short step on the rig.
par: {par}
runs_on: rig
may_change:
  keys: ["CONTROLLER ONE.K", "CONTROLLER ONE.Ti"]
experiment:
  script: rig-step.yaml
  duration: 60
requirements:
  - overshoot: {{loop: 1, max: 20}}
  - max_level: {{tank: 1, max: 0.95}}
"""
SCRIPT = """\
- {at: 0, state: Run}
- {at: 0, log: on}
- {at: 0, mode: Automatic}
- {at: 20, step: {"REFERENCE ONE.Mean": 0.05}}
"""


class Lockstep(ModbusBackend):
    """Active mode's Modbus backend, moving the rig's clock one sampling time before each read."""

    def __init__(self, config: object, clock: list[float]) -> None:
        super().__init__(config)  # type: ignore[arg-type]
        self.clock, self.reads = clock, 0

    def read_levels(self):
        self.clock[0] = self.reads * H
        self.reads += 1
        return super().read_levels()


def test_a_rig_attempt_is_recorded_with_the_rig_and_graded_as_read(device: Callable, tmp_path: Path) -> None:
    (tmp_path / "rig-step.yaml").write_text(SCRIPT)
    (tmp_path / "rig-step-ex.yaml").write_text(EXERCISE.format(par=EXERCISES / "reference" / "pminus-pi.par"))
    ex = read_exercise(tmp_path / "rig-step-ex.yaml")
    params = read_par(ex.par).params
    clock = [0.0]
    model = VirtualRig(load_daq_config(VIRTUAL_RIG, params.process_plant()), params.quadtank_constants(),
                       params.process_levels(), watchdog=0.0, clock=lambda: clock[0])
    rig = device((0.0,) * 4, bank=model)
    backend = Lockstep(rig.config(), clock)
    attempt = run_attempt(ex, ex.par, record=tmp_path / "rec", daq=backend, daq_config=str(VIRTUAL_RIG))
    assert attempt.status == 0 and backend.reads >= int(60 / H)
    result = json.loads((tmp_path / "rec" / "result.json").read_text())
    plant = result["plant"]
    assert plant["kind"] == "rig" and plant["backend"] == "Lockstep"
    assert plant["daq_file"] == str(VIRTUAL_RIG.resolve())
    assert plant["daq_sha256"] == hashlib.sha256(VIRTUAL_RIG.read_bytes()).hexdigest()
    assert plant["host"] == "127.0.0.1" and plant["port"] == rig.port and plant["device_id"] == 1
    served = plant["device_identity"]  # the virtual rig's identity block, as it served it
    assert served["pump_gains"] == [1.0, 1.0] and len(served["tank_gains"]) == 4
    assert plant["identity_mismatches"] == []
    overshoot = {r["name"]: r for r in result["requirements"]}["overshoot 1"]
    assert overshoot["met"] is True and overshoot["figure"] is not None

    exercises = load_exercises([tmp_path / "rig-step-ex.yaml"])
    digest = hashlib.sha256(VIRTUAL_RIG.read_bytes()).hexdigest()
    graded = grade_record(tmp_path / "rec", exercises, daq_digests=[digest])
    assert graded.reproduced == "read" and graded.passed
    assert all(r.reproduced == "read" for r in graded.requirements)
    assert graded.notes == []  # its DAQ file is the one given and the rig said what it is
    other = grade_record(tmp_path / "rec", exercises, daq_digests=["0" * 64])
    assert any("not the one given (--daq)" in n for n in other.notes)

    # the same record graded against a simulator-only version of the exercise
    (tmp_path / "sim").mkdir()
    (tmp_path / "sim" / "rig-step.yaml").write_text(SCRIPT)
    (tmp_path / "sim" / "rig-step-ex.yaml").write_text(
        EXERCISE.format(par=EXERCISES / "reference" / "pminus-pi.par").replace("runs_on: rig", "runs_on: simulator"))
    elsewhere = grade_record(tmp_path / "rec", load_exercises([tmp_path / "sim" / "rig-step-ex.yaml"]))
    assert not elsewhere.passed and "rig-step-ex runs on the simulator; this attempt ran on the rig" in elsewhere.notes

    log = tmp_path / "rec" / "run.log"
    log.write_text(log.read_text().replace("0.6", "0.5", 3))
    edited = grade_record(tmp_path / "rec", exercises, daq_digests=[digest])
    assert edited.reproduced is False and not edited.passed
    assert "run.log edited: its sha256 is not the one result.json records" in edited.notes
