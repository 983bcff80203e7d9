"""Two real users and a virtual rig (issue 44): bob's booking refuses alice's
booking over it, her cancelling it and her session on the rig in his slot; his
own run on the rig is warned before the slot's end, then handed over: pumps at 0
(read from the rig), his log saved with its rows, the session stopped, the rig
free.  1 s slots; his slot is made short (an administrator books it again) once
his run drives the rig, so a loaded machine's slow starts cannot outlast it; the
lab drains the tanks under 0.55 after the hand-over (a few seconds)."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from datetime import datetime, timedelta
from pathlib import Path
from typing import Iterator

import pytest
from servekit import ROOT, User, can_make_users, made_users, wait_for

pytestmark = [pytest.mark.wallclock, pytest.mark.skipif(can_make_users() is not None or not Path(
    "/usr/sbin/runuser").exists() and not Path("/sbin/runuser").exists(), reason=str(can_make_users() or "runuser"))]

DAC = 1000  # the pump registers of params/virtual-rig.yaml's map
DRAIN = 0.55  # the lab's drain_below: the tanks sink from about 0.62 to it in a few seconds


@pytest.fixture(scope="module")
def lab(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[Path, dict[str, User]]]:
    import tempfile

    folder = Path(tempfile.mkdtemp(prefix="qtr-book-"))
    os.chmod(folder, 0o755)
    from quadtank_tui.session.folders import init_lab_folder

    init_lab_folder(folder / "rt")  # as `quadtank lab init` makes it (issue 41)
    (folder / "lab.yaml").write_text(f"runtime_dir: {folder / 'rt'}\nbookings:\n  slot_minutes: {1 / 60!r}\n"
                                     "  warn_minutes: [0.04]\n  weekly_quota_minutes: 60\n"
                                     f"  drain_below: {DRAIN}\n  drain_max_minutes: 0.5\n")
    homes = folder / "homes"
    homes.mkdir()
    with made_users(homes, "alice", "bob") as users:
        yield folder, users
    import shutil

    shutil.rmtree(folder, ignore_errors=True)


def quadtank(user: User, folder: Path, *args: str, timeout: float = 60.0) -> subprocess.CompletedProcess[str]:
    env = {"PATH": os.environ.get("PATH", ""), "PYTHONPATH": str(ROOT), "HOME": str(user.home),
           "QUADTANK_LAB": str(folder / "lab.yaml"), "PYTHONDONTWRITEBYTECODE": "1"}
    return subprocess.run(["runuser", "-u", user.name, "--", sys.executable, "-m", "quadtank_tui", *args],
                          cwd=user.home, env=env, capture_output=True, text=True, timeout=timeout)


def said(t: datetime) -> str:
    """A time as the messages write it: 14:30 on the minute, else 14:30:05."""
    return f"{t:%H:%M:%S}" if t.second else f"{t:%H:%M}"


def dacs(port: int) -> list[int]:
    from pymodbus.client import ModbusTcpClient

    client = ModbusTcpClient("127.0.0.1", port=port, timeout=2.0)
    try:
        rr = client.read_holding_registers(DAC, count=4, device_id=1)
        assert not rr.isError(), rr
        return list(rr.registers)
    finally:
        client.close()


def test_bobs_booking_refuses_alice_and_his_slot_ends_in_a_hand_over(lab: tuple[Path, dict[str, User]]) -> None:
    folder, users = lab
    alice, bob = users["alice"], users["bob"]
    rig = subprocess.Popen([sys.executable, "-m", "quadtank_tui", "rig", "--port", "0", "--map",
                            str(ROOT / "params" / "virtual-rig.yaml")], stdout=subprocess.PIPE, text=True,
                           env={**os.environ, "PYTHONPATH": str(ROOT)})
    try:
        assert rig.stdout is not None
        line = rig.stdout.readline()
        port = int(re.search(r"serving on [\d.]+:(\d+)", line).group(1))  # type: ignore[union-attr]
        daq = folder / "rig.yaml"
        daq.write_text((ROOT / "params" / "virtual-rig.yaml").read_text().replace("port: 5020", f"port: {port}"))
        start = datetime.now().astimezone().replace(microsecond=0)  # bob's slot holds now already
        long_end = start + timedelta(seconds=120)  # shortened below, once bob's run drives the rig
        hms = "%H:%M:%S"
        made = quadtank(bob, folder, "book", str(daq), f"{start:{hms}}", f"{long_end:{hms}}")
        assert made.returncode == 0, made.stderr
        booking = made.stdout.split()[1].rstrip(":")
        from concurrent.futures import ThreadPoolExecutor

        with ThreadPoolExecutor(5) as pool:  # alice's four tries only read bob's booking: beside his run's start
            tries = [pool.submit(quadtank, user, folder, *args) for user, args in (
                (alice, ("book", str(daq), f"{start + timedelta(seconds=2):{hms}}",
                         f"{long_end + timedelta(seconds=5):{hms}}")),
                (alice, ("bookings", "--cancel", booking)),
                (alice, ("bookings",)),
                # in bob's slot: alice's run on the rig is refused, with whose slot it is and until when
                (alice, ("run", "--daq", str(daq), "--realtime", "--duration", "30", "--log", "alice.log",
                         "--detach")),
                # bob's own run: Active on the rig, then handed over at his slot's end
                (bob, ("run", "--daq", str(daq), "--realtime", "--duration", "60", "--log", "bob.log", "--detach")))]
            over, cancel, listed, refused, run = (t.result() for t in tries)
        assert over.returncode == 2 and f"the rig is booked then: {bob.name} " in over.stderr, over.stderr
        assert cancel.returncode == 2 and "cancelling it needs an administrator" in cancel.stderr, cancel.stderr
        assert booking in listed.stdout and bob.name in listed.stdout
        assert refused.returncode == 2, (refused.stdout, refused.stderr)
        assert f"the rig is booked by {bob.name} until {said(long_end)}" in refused.stderr, refused.stderr
        assert run.returncode == 0, run.stderr
        assert wait_for(lambda: dacs(port) != [0, 0, 0, 0], 5), "bob's run never drove the pumps"
        # an administrator (root) shortens his slot to end in 4 s: cancelled, booked again for him
        env = {**os.environ, "PYTHONPATH": str(ROOT), "QUADTANK_LAB": str(folder / "lab.yaml")}
        q = [sys.executable, "-m", "quadtank_tui"]
        from quadtank_tui.session.bookings import cancel as cancel_booking
        from quadtank_tui.session.lab import load_lab_config

        assert cancel_booking(load_lab_config(folder / "lab.yaml"), booking).id == booking  # as root: in this process
        end = datetime.now().astimezone().replace(microsecond=0) + timedelta(seconds=3)
        again = subprocess.run([*q, "book", "--for", bob.name, str(daq), f"{start:{hms}}", f"{end:{hms}}"], env=env,
                               capture_output=True, text=True)
        assert again.returncode == 0 and f"{bob.name} " in again.stdout, again.stderr
        sid = f"{bob.name}-1"
        out = folder / "rt" / "users" / str(bob.uid) / f"{sid}.out"  # bob's folder of sessions
        text = wait_for(lambda: out.read_text() if "stopped:" in out.read_text() else "",
                        (end - datetime.now().astimezone()).total_seconds() + 8 + 30)  # the drain: 30 s at most
        assert text, (out.read_text(), quadtank(bob, folder, "sessions").stdout, sorted(p.name for p in (folder / "rt").iterdir()), datetime.now(), end)
        stamps = {what: datetime.strptime(m.group(1), hms).time() for what, pattern in (
            ("warned", r"(\d\d:\d\d:\d\d) slot: your slot ends at"),
            ("pumps", r"(\d\d:\d\d:\d\d) slot: your slot on the rig ended at .*: pumps at 0"),
            ("saved", r"(\d\d:\d\d:\d\d) slot: log saved"),
            ("drained", rf"(\d\d:\d\d:\d\d) slot: drained: every tank under {DRAIN:g} \(")) if (m := re.search(pattern, text))}
        assert set(stamps) == {"warned", "pumps", "saved", "drained"}, text
        assert stamps["warned"] < stamps["pumps"] <= stamps["saved"] <= stamps["drained"]
        drained = re.search(rf"drained: every tank under {DRAIN:g} \(([^)]*)\)", text)
        assert drained is not None
        levels = [float(v) for v in drained.group(1).split(", ")]
        assert len(levels) == 4 and max(levels) <= DRAIN, levels  # printed to 3 decimals: 0.5496 reads 0.55
        assert end.time() <= stamps["pumps"] <= (end + timedelta(seconds=3)).time(), (stamps, end)
        assert dacs(port) == [0, 0, 0, 0]  # the pumps at 0, read from the rig
        log = bob.home / "bob.log"
        rows = [r for r in log.read_text().splitlines() if r and not r.startswith("%")]
        assert len(rows) >= 25, len(rows)  # the 3 s and more of his run at 0.1 s
        assert log.stat().st_uid == bob.uid
        from quadtank_tui.session.runtime import ended_sessions

        [ended] = [i.ended for i in ended_sessions(folder / "rt") if i.uid == bob.uid]  # as `sessions` lists it
        assert ended.startswith(f"your slot on the rig ended at {said(end)}: pumps at 0, the log saved"), ended
        # the rig is free: no lock record of bob's live
        locks = list((folder / "rt" / "locks").glob("*.lock"))
        assert all(p.stat().st_uid != bob.uid for p in locks), locks
    finally:
        rig.terminate()
        rig.wait(timeout=10)
