"""A real browser (Debian's headless Chromium, through selenium and
chromium-driver) logs in as a user made for the test, sees Main, presses a key,
closes its tab, and a second login attaches to the same session (issue 44).
Screenshots go to $QUADTANK_SCREENSHOTS (else the test's temporary folder)."""

from __future__ import annotations

import os
import shutil
import tempfile
import time
from pathlib import Path
from typing import Any, Iterator

import pytest
from servekit import Serve, User, can_make_users, made_users, serving, wait_for

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
DRIVER = shutil.which("chromedriver")


def _missing() -> str | None:
    if can_make_users() is not None:
        return can_make_users()
    if CHROMIUM is None or DRIVER is None:
        return "needs Debian's chromium and chromium-driver (make browser-deps installs them as root)"
    try:
        import selenium  # noqa: F401
    except ImportError:
        return "needs selenium (the test extra: pip install -e '.[test]')"
    return None


pytestmark = [pytest.mark.wallclock, pytest.mark.skipif(_missing() is not None, reason=str(_missing()))]


@pytest.fixture(scope="module")
def world() -> Iterator[tuple[Serve, dict[str, User]]]:
    with serving() as server:
        homes = server.folder / "homes"
        homes.mkdir()
        with made_users(homes, "w") as users:
            yield server, users


@pytest.fixture
def shots(tmp_path: Path) -> Path:
    folder = Path(os.environ.get("QUADTANK_SCREENSHOTS") or tmp_path)
    folder.mkdir(parents=True, exist_ok=True)
    return folder


def browser(profile: Path) -> Any:
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    options.binary_location = str(CHROMIUM)
    for flag in ("--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                 "--disable-background-networking", "--disable-component-update", "--disable-sync",
                 "--disable-dev-shm-usage", "--window-size=1280,860", f"--user-data-dir={profile}"):
        options.add_argument(flag)
    return webdriver.Chrome(service=Service(executable_path=str(DRIVER)), options=options)


def log_in(driver: Any, server: Serve, user: User, shot: Path | None = None) -> None:
    from selenium.webdriver.common.by import By

    driver.get(f"{server.origin}/")  # no cookie: to the login form
    assert driver.current_url == f"{server.origin}/login"
    if shot is not None:
        driver.save_screenshot(str(shot))
    driver.find_element(By.NAME, "user").send_keys(user.name)
    driver.find_element(By.NAME, "password").send_keys(user.password)
    driver.find_element(By.CSS_SELECTOR, "button[type=submit]").click()


def screen_up(driver: Any) -> bool:
    return bool(driver.execute_script("return document.body.classList.contains('-first-byte')"))


def sessions_of(server: Serve, user: User) -> list[Any]:
    from quadtank_tui.session.runtime import list_sessions

    return [i for i in list_sessions(server.runtime, prune=False) if i.uid == user.uid]


def test_a_browser_logs_in_sees_main_types_closes_and_comes_back(world: tuple[Serve, dict[str, User]],
                                                                   shots: Path) -> None:
    from selenium.webdriver.common.by import By

    server, users = world
    student = users["w"]
    profiles = Path(tempfile.mkdtemp(prefix="qtr-chromium-"))
    t0 = time.monotonic()
    mark = lambda what: print(f"{time.monotonic() - t0:6.2f} {what}")  # noqa: E731
    driver = browser(profiles)
    mark("browser")
    try:
        log_in(driver, server, student, shots / "serve-0-login.png")
        assert wait_for(lambda: driver.current_url == f"{server.origin}/", 10), \
            (driver.current_url, driver.page_source[:3000], server.audit_lines())
        mark("logged in")
        assert wait_for(lambda: screen_up(driver), 40), "the tab's screen never drew"
        mark("screen")
        [session] = wait_for(lambda: [i for i in sessions_of(server, student) if i.operator == student.name], 20)
        assert (session.owner, session.state, session.clients) == (student.name, "Pause", 1)
        time.sleep(0.5)  # the first frames
        driver.save_screenshot(str(shots / "serve-1-main.png"))
        # every row of the terminal, its footer the last, inside the window
        bottom, height = driver.execute_script(
            "return [document.querySelector('.xterm-screen').getBoundingClientRect().bottom, window.innerHeight]")
        assert 0 < bottom <= height, (bottom, height)
        # keys go to xterm's input (a click on the screen would be a click in the TUI)
        driver.find_element(By.CSS_SELECTOR, ".xterm-helper-textarea").send_keys("r")
        running = wait_for(lambda: [i for i in sessions_of(server, student) if i.state == "Run"], 10)
        assert running, "r (Run) from the browser did not reach the session"
        mark("running")
        time.sleep(0.3)
        driver.save_screenshot(str(shots / "serve-2-running.png"))
        page = driver.page_source
        assert f"quadtank &middot; {student.name}" in page or f"quadtank · {student.name}" in page
        first = driver.current_window_handle
        driver.switch_to.new_window("tab")
        blank = driver.current_window_handle
        driver.switch_to.window(first)
        driver.close()  # the tab closes: it detaches
        driver.switch_to.window(blank)
        mark("closed")
        left = wait_for(lambda: [i for i in sessions_of(server, student) if i.clients == 0], 15)
        assert left and left[0].id == session.id and left[0].state == "Run", "closing the tab must detach, not stop"
        mark("detached")
        driver.get(f"{server.origin}/static/css/xterm.css")  # the site's cookies, without opening a tab
        driver.delete_all_cookies()  # a login of its own, as another browser would
        log_in(driver, server, student)
        assert wait_for(lambda: screen_up(driver), 40)
        back = wait_for(lambda: [i for i in sessions_of(server, student) if i.clients == 1], 20)
        mark("back")
        assert back and [i.id for i in sessions_of(server, student)] == [session.id]
        assert f'href="/?attach={session.id}"' in driver.page_source  # the way back, offered
        time.sleep(1.5)  # the history first, then the screen
        driver.save_screenshot(str(shots / "serve-3-attached-again.png"))
    finally:
        driver.quit()
        shutil.rmtree(profiles, ignore_errors=True)
    audit = server.audit_lines()
    assert sum(f"attach user={student.name} " in line for line in audit) == 2, audit
    assert sum(f"login user={student.name} " in line for line in audit) == 2
