"""The login's slowing, the login store's expiry, the tab's packets and the lab
file's serve: section, without a server (issue 44)."""

from __future__ import annotations

from pathlib import Path

import pytest

from quadtank_tui.serve.auth import FREE_FAILURES, MAX_WAIT, WINDOW, Account, Throttle
from quadtank_tui.serve.web_config import serve_settings
from quadtank_tui.serve.web import InFlight
from quadtank_tui.serve.websessions import LoginStore
from quadtank_tui.session.lab import LabConfigError, parse_lab_config


class Clock:
    def __init__(self) -> None:
        self.now = 1000.0

    def __call__(self) -> float:
        return self.now


def test_failures_wait_twice_as_long_each_time_up_to_a_minute_then_are_forgotten() -> None:
    clock = Clock()
    t = Throttle(clock=clock)
    keys = ("user:bob", "addr:10.0.0.5")
    waits = []
    for _ in range(FREE_FAILURES + 8):
        waits.append(t.wait(keys))
        t.failed(keys)
    assert waits[:FREE_FAILURES + 1] == [0.0] * (FREE_FAILURES + 1)
    assert waits[FREE_FAILURES + 1:] == [2.0, 4.0, 8.0, 16.0, 32.0, 60.0, 60.0]
    assert t.wait(("user:alice", "addr:10.0.0.6")) == 0.0  # others are not slowed
    assert t.wait(("user:alice", "addr:10.0.0.5")) == MAX_WAIT  # the same address is
    clock.now += 30.0
    assert t.wait(keys) == MAX_WAIT - 30.0
    clock.now += WINDOW
    assert t.wait(keys) == 0.0 and t.failures("user:bob") == 0
    t.failed(keys)
    t.succeeded(keys)
    assert t.failures("user:bob") == 0


def test_one_check_per_name_and_four_per_address_at_once() -> None:
    f = InFlight()
    assert f.enter(("user:bob", "addr:a"))
    assert not f.enter(("user:bob", "addr:b"))
    assert all(f.enter((f"user:u{i}", "addr:a")) for i in range(3))
    assert not f.enter(("user:u9", "addr:a"))
    f.leave(("user:bob", "addr:a"))
    assert f.enter(("user:bob", "addr:c")) and f.enter(("user:u9", "addr:a"))


def test_a_login_ends_when_idle_at_its_maximum_and_at_logout() -> None:
    clock = Clock()
    store = LoginStore(idle=600.0, maximum=3600.0, clock=clock)
    who = Account("alice", 1001, 1001, "/home/alice", "pam")
    a = store.open(who, "127.0.0.1")
    clock.now += 599.0
    assert store.find(a) is not None
    clock.now += 599.0
    assert store.find(a) is not None  # used: idle time starts again
    clock.now += 601.0
    assert store.find(a) is None
    b = store.open(who, "127.0.0.1")
    for _ in range(7):
        clock.now += 500.0
        assert store.find(b) is not None
    clock.now += 200.0  # 3700 s after the login, never idle
    assert store.find(b) is None
    c = store.open(who, "127.0.0.1")
    assert store.close(c) is not None and store.find(c) is None and store.close(c) is None
    assert store.find("forged") is None and store.find("x" * 5000) is None


def test_the_lab_files_serve_section() -> None:
    lab = parse_lab_config("serve:\n  idle_minutes: 10\n  accounts:\n    alice: '$argon2id$v=19$x'\n"
                           "  trusted_proxy: 127.0.0.1\n  public_url: https://rig7.example.org/\n", name="lab.yaml",
                           source=Path("lab.yaml"))
    s = serve_settings(lab)
    assert (s.idle_minutes, s.max_hours, dict(s.accounts), s.trusted_proxy, s.public_url) == \
        (10.0, 12.0, {"alice": "$argon2id$v=19$x"}, "127.0.0.1", "https://rig7.example.org")
    for text, message in (
            ("serve:\n  idle: 3\n", "lab.yaml:2: serve.idle: unknown key"),
            ("serve:\n  max_hours: 0\n", "lab.yaml:2: serve.max_hours: must be a number 0.05..168, got 0"),
            ("serve:\n  accounts:\n    bob: plain\n", "lab.yaml:3: serve.accounts.bob: must be a user name and an "
                                                      "argon2 hash"),
            ("serve:\n  trusted_proxy: proxy.lab\n", "lab.yaml:2: serve.trusted_proxy: must be the proxy's IP"),
            ("serve: 3\n", "lab.yaml:1: serve: must be a mapping of keys")):
        with pytest.raises(LabConfigError) as exc:
            serve_settings(parse_lab_config(text, name="lab.yaml", source=Path("lab.yaml")))
        assert str(exc.value).startswith(message), (text, str(exc.value))


@pytest.mark.parametrize("sid", ["--take-over", "-h", "bob-1\n", "..", "bob-1/../x", "bob"])
def test_a_tab_runs_no_session_id_that_is_an_option_a_path_or_a_line(sid: str) -> None:
    """`?attach=--take-over` became `quadtank attach --take-over` in the tab; `bob-1\\n`
    passed the old `^...$` pattern: each is refused (400) before a tab starts."""
    from aiohttp import web

    from quadtank_tui.serve.web import Server

    with pytest.raises(web.HTTPBadRequest):
        Server._mode(None, {"attach": sid})  # type: ignore[arg-type]
    assert Server._mode(None, {"observe": "qtr1a-12"}) == ("observe", "qtr1a-12")  # type: ignore[arg-type]


def test_a_tabs_interpreter_runs_nothing_of_the_users_home_as_root(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The tab's Python starts as root with HOME the user's: with a system Python
    (user site-packages on) a student's ~/.local/lib/pythonX.Y/site-packages/
    usercustomize.py ran as root at each of their logins (uid=0 written, by hand
    with /usr/bin/python3).  The tab's flags keep it out; a start uses them."""
    import asyncio
    import subprocess
    import sys

    from quadtank_tui.serve.tab import PYTHON_FLAGS, Tab, TabUser

    site = tmp_path / ".local" / "lib" / f"python{sys.version_info[0]}.{sys.version_info[1]}" / "site-packages"
    site.mkdir(parents=True)
    (site / "usercustomize.py").write_text(f"open({str(tmp_path / 'ran')!r}, 'w').close()\n")
    env = {"HOME": str(tmp_path), "PATH": "/usr/bin:/bin"}
    probe = "import site; print(site.ENABLE_USER_SITE)"
    python = "/usr/bin/python3" if Path("/usr/bin/python3").exists() else sys.executable
    plain = subprocess.run([python, "-c", probe], env=env, capture_output=True, text=True)
    if plain.stdout.strip() == "True":  # a Python whose user site is on: the attack works without the flags
        assert (tmp_path / "ran").exists()
        (tmp_path / "ran").unlink()
    flagged = subprocess.run([python, *PYTHON_FLAGS, "-c", probe], env=env, capture_output=True, text=True)
    assert flagged.stdout.strip() == "False" and not (tmp_path / "ran").exists()
    seen: list[tuple[str, ...]] = []

    async def fake_exec(*argv: str, **kw: object) -> object:
        seen.append(argv)
        raise OSError("not started")

    monkeypatch.setattr(asyncio, "create_subprocess_exec", fake_exec)
    tab = Tab(TabUser("u", 1000, 1000, (), str(tmp_path)), [], width=80, height=24,
              to_browser=lambda b: asyncio.sleep(0), passed_env={}, python=python)
    with pytest.raises(OSError):
        asyncio.run(tab.start())
    assert seen[0][:3] == (python, *PYTHON_FLAGS, "-m")
