"""The UI tests' fixtures; the helpers they import live in uikit.py (a name of its
own: pytest's importlib mode and the other folders' `conftest` modules).

The engine only moves when a test calls `run_for`, commands apply at once, and
the wall clock the status line uses is fixed, so screens are reproducible.
"""

from __future__ import annotations

import gc
import inspect
import sys
from pathlib import Path
from typing import Any, Callable, Iterable, Iterator

import pytest
import textual._wait as textual_wait
from textual.css.model import RuleSet
from textual.css.stylesheet import Stylesheet

# The tests import uikit and bursts from this folder (pytest's importlib mode
# does not put the test folder on sys.path).
sys.path.insert(0, str(Path(__file__).parent))

from quadtank_tui.core.parameters import PRESET, Parameters  # noqa: E402
from quadtank_tui.engine.runner import build_engine  # noqa: E402
from quadtank_tui.files.shipped import write_shipped  # noqa: E402
from quadtank_tui.ui import keyorder  # noqa: E402
from quadtank_tui.ui.app import QuadTankApp  # noqa: E402
from quadtank_tui.ui.widgets.analysis_panel import warm_up  # noqa: E402
from uikit import EPOCH, Recording, make_app, manual_engine, presses_shown, write_params  # noqa: E402

# The analysis stack loaded once, up front: the Setup screen then shows its
# analysis at once, as it does after the Main screen's warm-up in a terminal
# (test_help_and_keys.py checks the path where it is not loaded yet).
warm_up()


@pytest.fixture(autouse=True)
def _keys_wait_as_long_as_a_loaded_machine_needs(monkeypatch: pytest.MonkeyPatch) -> None:
    """A key that opens a window is waited for until the window is up, not at most
    KEY_CAP (2 s): on a loaded CI machine mounting a window took longer and the
    next key of a burst went to the window behind (test_trust's logging burst).  The
    tests check where keys go, not the cap for a key lost on the way."""
    monkeypatch.setattr(keyorder, "KEY_CAP", 30.0)


@pytest.fixture(autouse=True)
def _collector_runs_between_tests() -> Iterator[None]:
    """The cyclic garbage collector runs between tests, not during them: what the
    previous test left is collected, what survives (modules, Textual's caches, the
    analysis stack) is frozen out of later collections, as the CLI does after the
    first frame (ui.app.resume_gc), and the collector pauses for the test (a UI test
    leaves some 30,000 objects in cycles, which the next one's start collects).
    It took 40 % of the UI tests' CPU time: 31 s of 77 s for test_main_keys.py and
    test_setup_pilot.py.  A test about the collector sets it up itself
    (test_start_gc.py)."""
    gc.collect()
    gc.freeze()
    gc.disable()
    yield
    gc.enable()


@pytest.fixture(autouse=True)
def _idle_is_seen_in_5_ms_windows(monkeypatch: pytest.MonkeyPatch) -> None:
    """Textual's pilot waits, after each key and in `pause()`, until a window of
    its process's CPU time shows it idle: windows of 20 ms at least, with under
    1 ms of CPU in them, twice a key (textual._wait.wait_for_idle).  Windows of
    5 ms with under 0.25 ms of CPU still see the app's work, which runs in this
    process (its refresh timer ticks every 50 ms in the tests, its workers'
    threads count too), and halve what a typed key costs (from about 90 ms).
    Below about 2 ms the wait's own polling reads as work and a key waits the
    1 s maximum."""
    monkeypatch.setattr(textual_wait, "SLEEP_GRANULARITY", 0.005)
    monkeypatch.setattr(textual_wait, "SLEEP_IDLE", 0.005 / 20)


#: Parsed stylesheets, for every app of the session (see _stylesheets_parsed_once).
_PARSED: dict[tuple[object, ...], list[RuleSet]] = {}


@pytest.fixture(autouse=True, scope="session")
def _stylesheets_parsed_once() -> Iterator[None]:
    """Each test builds a new app, and Textual parses every stylesheet again for
    it (the app's files, each widget's DEFAULT_CSS; its cache is the app's): here
    what was parsed once, for the same CSS text, origin and variables (the theme),
    is reused by the later apps, as one app reuses it.  The tests still check the
    app's own stylesheet: the first app of each worker parses it, and a CSS error
    fails there.  About 3 % of the UI tests' CPU time."""
    parse_rules = Stylesheet._parse_rules

    def parsed_once(self: Stylesheet, css: str, read_from: Any, is_default_rules: bool = False,
                    tie_breaker: int = 0, scope: str = "") -> list[RuleSet]:
        key = (css, read_from, is_default_rules, tie_breaker, scope, tuple(sorted(self._variables.items())))
        rules = _PARSED.get(key)
        if rules is None:
            rules = _PARSED[key] = parse_rules(self, css, read_from, is_default_rules, tie_breaker, scope)
        return rules

    Stylesheet._parse_rules = parsed_once  # type: ignore[method-assign]
    yield
    Stylesheet._parse_rules = parse_rules  # type: ignore[method-assign]


@pytest.fixture
def snap_compare(snap_compare: Callable[..., bool]) -> Callable[..., bool]:
    """pytest-textual-snapshot's snap_compare, whose picture is taken once no button
    shows its last press (uikit.presses_shown): the run_before and the keys, then
    that wait.  A click or an Enter 0.2 s or less before the picture drew the
    button pressed or not depending on the machine's speed (the calibration
    window's fit failed in CI that way: same text, other colours)."""
    def compare(app: Any, *, press: Iterable[str] = (), run_before: Callable[[Any], Any] | None = None,
                **kwargs: Any) -> bool:
        async def before(pilot: Any) -> None:
            if run_before is not None:
                result = run_before(pilot)
                if inspect.isawaitable(result):
                    await result
            await pilot.pause()
            await pilot.press(*press)
            await presses_shown(pilot)
        return snap_compare(app, run_before=before, **kwargs)
    return compare


@pytest.fixture
def make_engine(tmp_path: Path) -> Callable[..., Recording]:
    def make(params: Parameters = PRESET, **kwargs: Any) -> Recording:
        options: dict[str, Any] = dict(clock="manual", seed=1, epoch=EPOCH,
                                       params_dir=write_params(tmp_path / "params", params),
                                       logs_dir=tmp_path / "logs")
        options.update(kwargs)
        (tmp_path / "logs").mkdir(exist_ok=True)
        return Recording(build_engine(**options))
    return make


@pytest.fixture
def engine(make_engine: Callable[..., Recording]) -> Recording:
    return make_engine()


# --- the Setup screen's tests ----------------------------------------------------------------

@pytest.fixture
def setup_engine(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[Recording]:
    """The engine on ./params (the shipped files) and ./logs, in a private folder:
    relative folders, so a message reads "params/x.par" whatever tmp_path is."""
    monkeypatch.chdir(tmp_path)
    write_shipped("params")
    engine = Recording(manual_engine())
    yield engine
    engine.stop()


@pytest.fixture
def setup_app(setup_engine: Recording) -> QuadTankApp:
    """The app as the CLI builds it; `await open_setup(pilot)` goes to Setup."""
    return make_app(setup_engine)
