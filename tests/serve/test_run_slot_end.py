"""A foreground `quadtank run --daq` (no --detach) ends at its user's booked slot's
end (issue 44): warned on stderr before it, then paused (the pumps at 0, read
from the rig), its log saved with the rows it has, the summary's last line
saying why, exit status 4.  The virtual rig, 1 s slots, a slot of 3 s booked by
this test's own user (no other user is needed: the slot is theirs)."""

from __future__ import annotations

import os
import re
import subprocess
import sys
import tempfile
from datetime import datetime, timedelta
from pathlib import Path

import pytest
from servekit import ROOT

pytestmark = [pytest.mark.wallclock, pytest.mark.skipif(os.geteuid() != 0, reason="the lab's runtime folder as "
                                                        "`quadtank lab init` makes it is root's")]

DAC = 1000  # the pump registers of params/virtual-rig.yaml's map


def dacs(port: int) -> list[int]:
    from pymodbus.client import ModbusTcpClient

    client = ModbusTcpClient("127.0.0.1", port=port, timeout=2.0)
    try:
        rr = client.read_holding_registers(DAC, count=4, device_id=1)
        assert not rr.isError(), rr
        return list(rr.registers)
    finally:
        client.close()


def test_a_foreground_run_on_the_rig_stops_at_its_slots_end() -> None:
    from quadtank_tui.session.folders import init_lab_folder

    folder = Path(tempfile.mkdtemp(prefix="qtr-slotrun-"))
    os.chmod(folder, 0o755)
    init_lab_folder(folder / "rt")
    lab = folder / "lab.yaml"
    lab.write_text(f"runtime_dir: {folder / 'rt'}\nbookings:\n  slot_minutes: {1 / 60!r}\n  warn_minutes: [0.03]\n")
    env = {**os.environ, "PYTHONPATH": str(ROOT), "QUADTANK_LAB": str(lab)}
    env.pop("QUADTANK_RUNTIME", None)
    rig = subprocess.Popen([sys.executable, "-m", "quadtank_tui", "rig", "--port", "0", "--map",
                            str(ROOT / "params" / "virtual-rig.yaml")], stdout=subprocess.PIPE, text=True, env=env)
    try:
        assert rig.stdout is not None
        port = int(re.search(r"serving on [\d.]+:(\d+)", rig.stdout.readline()).group(1))  # type: ignore[union-attr]
        daq = folder / "rig.yaml"
        daq.write_text((ROOT / "params" / "virtual-rig.yaml").read_text().replace("port: 5020", f"port: {port}"))
        from quadtank_tui.session.bookings import book
        from quadtank_tui.session.lab import load_lab_config
        from quadtank_tui.session.riglock import rig_keys
        from quadtank_tui.daq.open import load_rig_config

        now = datetime.now().astimezone().replace(microsecond=0)
        end = now + timedelta(seconds=5)  # the run's start (1-2 s) and then some 3 s on the rig
        book(load_lab_config(lab), rig_keys(load_rig_config(str(daq))), now, end)
        run = subprocess.run([sys.executable, "-m", "quadtank_tui", "run", "--daq", str(daq), "--realtime",
                              "--duration", "60", "--log", str(folder / "mine.log")],
                             env=env, cwd=folder, capture_output=True, text=True, timeout=60)
        stopped = datetime.now().astimezone()
        assert run.returncode == 4, (run.returncode, run.stdout, run.stderr)
        assert stopped < end + timedelta(seconds=8)  # not its 60 s: its slot's end, and its way out
        hms = f"{end:%H:%M:%S}".removesuffix(":00") if end.second == 0 else f"{end:%H:%M:%S}"
        said = [line for line in run.stderr.splitlines() if " slot: " in line]
        assert len(said) == 2, run.stderr
        assert said[0].endswith(f"slot: your slot ends at {hms} (in {said[0].split('(in ')[1].split(')')[0]}): "
                                "then the pumps go to 0, the log is saved and this run stops"), said
        assert said[1].endswith(f"slot: your slot on the rig ended at {hms}: pumps at 0, the log is saved, "
                                "this run stops"), said
        last = run.stdout.splitlines()[-1]
        m = re.fullmatch(rf"STOPPED    at t = ([\d.]+) s of 60: your slot on the rig ended at {hms}; pumps at 0, "
                         rf"the log saved as (\S+)", last)
        assert m is not None, run.stdout
        at, saved = float(m.group(1)), Path(m.group(2))
        assert saved == folder / "mine.log"
        rows = [r for r in saved.read_text().splitlines() if r and not r.startswith("%")]
        assert 1.0 <= at <= 6.0 and abs(len(rows) - at / 0.1) <= 2, (at, len(rows))  # every row up to the stop
        assert f"log        {saved} ({len(rows)} rows)" in run.stdout
        assert dacs(port) == [0, 0, 0, 0]  # the pumps at 0, read from the rig
    finally:
        rig.terminate()
        rig.wait(timeout=10)
        import shutil

        shutil.rmtree(folder, ignore_errors=True)
