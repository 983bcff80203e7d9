"""One program at a time drives a rig: `quadtank run --daq`, the TUI with --daq and
`quadtank daq calibrate` take the rig's lock before writing a pump.  A second one is
refused with one line naming the holder (exit 2, nothing written); a SIGKILLed
holder's lock is taken over; an administrator may take a rig over (the program that
held it stops, pumps at 0, its log kept), a student may not.  Users are simulated by
standing in for the role look-ups (session.roles)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
from datetime import datetime
from pathlib import Path
from typing import Callable

import pytest

from quadtank_tui.commands import tui as tui_command
from quadtank_tui.cli import main
from quadtank_tui.files.log_reader import read_log
from quadtank_tui.session import roles
from quadtank_tui.session.lab import load_lab_config
from quadtank_tui.session.lock import DaqLock, device_key, holder_of
from daqkit import missed_before_the_last_row, missed_slots, rig_yaml

ROOT = Path(__file__).parents[2]
PAR = str(ROOT / "params" / "default.par")
ME = roles.user_name(os.getuid())


def config_for(tmp_path: Path, port: int) -> Path:
    """params/virtual-rig.yaml pointed at `port`."""
    text = rig_yaml(port)
    path = tmp_path / "rig.yaml"
    path.write_text(text)
    return path


def logged(partial: Path, rows: int) -> bool:
    """Whether the run's partial log holds `rows` rows yet (not there yet, or its
    header half-written: not yet)."""
    try:
        return read_log(partial).rows >= rows
    except (OSError, ValueError):
        return False


def holder_pid(port: int) -> int | None:
    held = holder_of(device_key("127.0.0.1", port, 1), load_lab_config())
    return None if held is None else held.pid


@pytest.fixture
def holding(tmp_path: Path):
    """holding(port): another program holding the rig's lock (it waits on stdin)."""
    children: list[subprocess.Popen[str]] = []

    def start(port: int) -> subprocess.Popen[str]:
        code = textwrap.dedent(f"""
            import sys
            from quadtank_tui.session.lab import load_lab_config
            from quadtank_tui.session.lock import DaqLock, device_key
            DaqLock.acquire(device_key("127.0.0.1", {port}, 1), load_lab_config())
            print("held", flush=True)
            sys.stdin.readline()
        """)
        child = subprocess.Popen([sys.executable, "-c", code], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                 text=True)
        children.append(child)
        assert child.stdout is not None and child.stdout.readline() == "held\n"
        return child

    yield start
    for child in children:
        child.kill()
        child.wait()


@pytest.mark.parametrize("argv", [
    ["run", "--daq", "{cfg}", "--duration", "1", "--log", "{log}", "--par", PAR],
    ["--daq", "{cfg}", "run", "--duration", "1", "--log", "{log}", "--par", PAR],
    ["--daq", "{cfg}"],                     # the TUI
    ["daq", "calibrate", "{cfg}"],          # holds the pumps at each voltage
], ids=["run", "global-daq-run", "tui", "calibrate"])
def test_a_second_program_is_refused_naming_the_holder(argv: list[str], tmp_path: Path, holding: Callable,
                                                       monkeypatch: pytest.MonkeyPatch,
                                                       capsys: pytest.CaptureFixture[str], unused_port: int) -> None:
    from quadtank_tui.daq import modbus

    port = unused_port
    child = holding(port)
    since = datetime.now()
    opened: list[object] = []
    monkeypatch.setattr(modbus.ModbusBackend, "__init__", lambda self, *a, **k: opened.append(a))
    monkeypatch.setattr(tui_command, "build_tui", lambda *a: opened.append(a))
    log = tmp_path / "x.log"
    args = [a.format(cfg=config_for(tmp_path, port), log=log) for a in argv]
    assert main(args) == 2
    out = capsys.readouterr()
    assert out.out == ""
    assert out.err == (f"quadtank: error: the rig at 127.0.0.1:{port}/1 is driven by {ME} (pid {child.pid}) "
                       f"since {since:%H:%M}; ask them to stop it, or an administrator may take it over "
                       "(--take-over)\n")
    assert opened == [] and not log.exists()  # no backend opened, no pump written, no log
    assert holder_pid(port) == child.pid


def test_calibrate_from_pairs_takes_no_lock(tmp_path: Path, holding: Callable,
                                            capsys: pytest.CaptureFixture[str], unused_port: int) -> None:
    """Fitting pairs from a file drives nothing: the rig may be in use meanwhile."""
    port = unused_port
    holding(port)
    pairs = tmp_path / "pairs.txt"
    pairs.write_text("u1 volts1 level1\n4 0.5864 3.5\n5 1.3422 7.5\n6 2.2396 12.25\n")
    assert main(["daq", "calibrate", str(config_for(tmp_path, port)), "--pairs", str(pairs)]) == 0
    assert capsys.readouterr().out.startswith("tank 1  gain ")


def logged_its_ten_slots(log: Path) -> bool:
    """Whether a `--realtime --duration 1` run at TSamp 0.1 s logged its ten sampling
    slots: a row each, except the slots a busy machine let go by, which the log notes
    (on an idle machine, ten rows)."""
    rows, covered = read_log(log).rows, read_log(log).rows + sum(missed_slots(log, 0.1))
    return rows >= 1 and covered - missed_before_the_last_row(log, 0.1) <= 10 <= covered


def run_in_child(cfg: Path, log: Path) -> subprocess.Popen[str]:
    """`quadtank run --daq` in real time for a minute, as another terminal would."""
    return subprocess.Popen([sys.executable, "-m", "quadtank_tui", "run", "--daq", str(cfg), "--realtime",
                             "--duration", "60", "--log", str(log), "--par", PAR],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def test_a_sigkilled_holders_lock_is_taken_over(rig: Callable, poll: Callable, tmp_path: Path,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    r = rig()
    cfg = config_for(tmp_path, r.port)
    child = run_in_child(cfg, tmp_path / "first.log")
    try:
        assert poll(lambda: holder_pid(r.port) == child.pid, 60.0)
        os.kill(child.pid, signal.SIGKILL)
        child.wait(60)
    finally:
        child.kill()
        child.communicate()
    assert holder_pid(r.port) is None  # its record is there, its pid is gone: stale
    out = tmp_path / "second.log"
    assert main(["run", "--daq", str(cfg), "--realtime", "--duration", "1", "--log", str(out), "--par", PAR]) == 0
    assert logged_its_ten_slots(out)
    assert holder_pid(r.port) is None  # released on the way out
    assert r.dacs() == (0.0, 0.0)


def be(monkeypatch: pytest.MonkeyPatch, tmp_path: Path, user: str) -> None:
    """This test process is `user` to the role checks; the lab's admin group is teachers."""
    uid = {"alice": 50001, "bob": 50002}[user]
    lab = tmp_path / "lab.yaml"
    lab.write_text("admin_group: teachers\n")
    monkeypatch.setenv("QUADTANK_LAB", str(lab))
    monkeypatch.setattr(roles, "group_id", {"teachers": 60001}.get)
    monkeypatch.setattr(roles, "groups_of", lambda u: {60001} if u == 50001 else {60002})
    monkeypatch.setattr(roles, "user_name", lambda u: {50001: "alice", 50002: "bob"}.get(u, ME))
    monkeypatch.setattr(roles, "current_user", lambda: roles.Peer(uid, 60002, os.getpid(), user))


def test_a_student_may_not_take_over_an_administrator_may(rig: Callable, poll: Callable, tmp_path: Path,
                                                          monkeypatch: pytest.MonkeyPatch,
                                                          capsys: pytest.CaptureFixture[str]) -> None:
    r = rig()
    cfg = config_for(tmp_path, r.port)
    first_log = tmp_path / "first.log"
    child = run_in_child(cfg, first_log)
    partial = first_log.with_name("first.log.partial")
    try:
        assert poll(lambda: holder_pid(r.port) == child.pid, 60.0)
        assert poll(lambda: logged(partial, 5), 60.0)  # it drives the rig
        out = tmp_path / "second.log"
        argv = ["run", "--daq", str(cfg), "--realtime", "--duration", "1", "--log", str(out), "--par", PAR,
                "--take-over"]
        be(monkeypatch, tmp_path, "bob")
        assert main(argv) == 2
        assert capsys.readouterr().err == (
            f"quadtank: error: taking over the rig at 127.0.0.1:{r.port}/1 from {ME} needs an administrator "
            "(member of group teachers); you are bob\n")
        assert child.poll() is None and holder_pid(r.port) == child.pid and not out.exists()

        be(monkeypatch, tmp_path, "alice")
        # The first program looks at its lock every 0.5 s (LockWatch); this run of 1 s
        # keeps the rig until it has stopped, or on a loaded machine it may look only
        # after this one released the lock and read "removed", not who took it.
        release = DaqLock.release
        monkeypatch.setattr(DaqLock, "release", lambda lock: (child.wait(60), release(lock))[-1])
        assert main(argv) == 0
        err = capsys.readouterr().err
        assert f"took the rig at 127.0.0.1:{r.port}/1 over from {ME} (pid {child.pid})" in err
        # the first program stopped before this one drove the rig: pumps at 0, its rows kept
        assert child.wait(60) == 1
    finally:
        child.kill()
        _, child_err = child.communicate()
    assert f"the rig at 127.0.0.1:{r.port}/1 was taken over by {ME} (pid {os.getpid()})" in child_err
    assert child_err.startswith("quadtank: stopped (pumps at 0, rows kept): the rig at")
    assert logged_its_ten_slots(out)
    kept = read_log(partial)
    assert kept.rows >= 5 and kept.columns()["u1"][-1] == 0.3
    assert holder_pid(r.port) is None
    assert r.dacs() == (0.0, 0.0)


class FakeEngine:
    warnings: tuple[str, ...] = ()

    def __init__(self) -> None:
        self.stopped = 0

    def start(self) -> None:
        pass

    def stop(self) -> None:
        self.stopped += 1


class FakeApp:
    """Runs until asked to exit (as QuadTankApp.exit_soon does, from any thread)."""

    def __init__(self) -> None:
        import threading

        self.return_code: int | None = None
        self._exit = threading.Event()

    def exit_soon(self, code: int) -> None:
        self.return_code = code
        self._exit.set()

    def run(self) -> None:
        assert self._exit.wait(60.0), "the TUI was not told its rig was taken over"


def test_the_tui_ends_when_its_rig_is_taken_over(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                 capsys: pytest.CaptureFixture[str], unused_port: int) -> None:
    """The TUI holds the lock for its whole run; taken over, it exits (status 1), its
    engine stopped (pumps at 0), saying who took the rig; the new holder keeps it."""
    import threading

    port = unused_port
    engine, app = FakeEngine(), FakeApp()
    running = threading.Event()

    def build_tui(args: object) -> tuple[FakeEngine, FakeApp]:
        running.set()
        return engine, app

    monkeypatch.setattr(tui_command, "build_tui", build_tui)
    taker: list[DaqLock] = []

    def take() -> None:
        assert running.wait(60.0)
        assert holder_pid(port) == os.getpid()  # the TUI holds it while it runs
        taker.append(DaqLock.acquire(device_key("127.0.0.1", port, 1), load_lab_config(), take_over=True))

    thread = threading.Thread(target=take)
    thread.start()
    assert main(["--no-session", "--daq", str(config_for(tmp_path, port))]) == 1
    thread.join()
    assert engine.stopped >= 1
    err = capsys.readouterr().err
    assert err.startswith(f"quadtank: stopped (pumps at 0): the rig at 127.0.0.1:{port}/1 was taken over by {ME}")
    assert taker[0].held  # the TUI's release on the way out left the new holder's lock alone
    taker[0].release()


def test_a_terminated_run_gives_the_rig_back(rig: Callable, poll: Callable, tmp_path: Path) -> None:
    """SIGTERM (systemd, kill): pumps at 0, rows kept, and the lock released, not left stale."""
    r = rig()
    cfg = config_for(tmp_path, r.port)
    child = run_in_child(cfg, tmp_path / "first.log")
    partial = tmp_path / "first.log.partial"
    try:
        assert poll(lambda: logged(partial, 3), 60.0)  # under way
        assert holder_pid(r.port) == child.pid
        child.terminate()
        assert child.wait(60) == 143
    finally:
        child.kill()
        child.communicate()
    lock_file = load_lab_config().locks_dir / f"127.0.0.1_{r.port}_1~{os.getuid()}.lock"
    assert child.pid and not lock_file.exists()  # released (removed), not merely stale
    assert r.dacs() == (0.0, 0.0)


def test_one_rig_under_two_names_is_refused(rig: Callable, poll: Callable, tmp_path: Path,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    """A run drives the virtual rig as `localhost`: the same rig typed `127.0.0.1` or
    `::1` is refused naming it (one lock for the loopback family), and a host name
    that does not resolve is refused before anything is locked or written."""
    r = rig()
    named = config_for(tmp_path, r.port)
    named.write_text(named.read_text().replace("host: 127.0.0.1", "host: localhost"))
    child = run_in_child(named, tmp_path / "first.log")
    try:
        assert poll(lambda: holder_pid(r.port) == child.pid, 20.0)
        held = holder_of(device_key("127.0.0.1", r.port, 1), load_lab_config())
        assert held is not None
        since = held.since
        for host, shown in (("127.0.0.1", f"127.0.0.1:{r.port}/1"),
                            ("::1", f"[::1]:{r.port}/1 (127.0.0.1:{r.port}/1)"),
                            ("no-such-rig.invalid", None)):
            cfg = tmp_path / f"as-{host}.yaml"
            cfg.write_text(named.read_text().replace("host: localhost", f"host: '{host}'"))
            out = tmp_path / "second.log"
            assert main(["run", "--daq", str(cfg), "--duration", "1", "--log", str(out), "--par", PAR]) == 2
            err = capsys.readouterr().err
            if shown is None:
                assert err.startswith("quadtank: error: the rig's host 'no-such-rig.invalid' does not resolve (")
            else:
                assert err == (f"quadtank: error: the rig at {shown} is driven by {ME} (pid {child.pid}) "
                               f"since {since:%H:%M}; ask them to stop it, or an administrator may take it over "
                               "(--take-over)\n")
            assert not out.exists() and holder_pid(r.port) == child.pid
        assert child.poll() is None  # the first run drives on
    finally:
        child.kill()
        child.communicate()
