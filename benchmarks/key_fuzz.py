"""Random keys through the TUI, every screen (issue 41): 20,000 keys with fixed seeds,
and no traceback.

Textual's pilot waits for the app to be idle after every key (`pilot.press`: about
90 ms a key on the shared machine, half an hour for 20,000).  Here a burst of
EVERY keys is handed to the app's driver at once, as a terminal would deliver a
fast typist's or a paste's keys, and the app is waited for (idle, its workers
done) only after each burst: the keys are still handled one after the other, in
order, by the app's own message loop.  Each round starts from one screen (Main,
Setup, Design, Identify, Help) opened by its key, so every screen gets its
share; an app that quits (a key that ends it, answered yes) is replaced by a new
one on the same engine's folder.  A failure is an exception the app caught and
ended on (Textual's `_exception`), a worker's error, or a "coroutine ... was never
awaited" warning at exit; the keys of the round so far are printed with it.

    .venv/bin/python benchmarks/key_fuzz.py                       # 20,000 keys, seeds 1..4
    .venv/bin/python benchmarks/key_fuzz.py --keys 2000 --seeds 7

tests/ui/test_key_fuzz.py runs a shorter seeded part of it in the suite.
"""

from __future__ import annotations

import argparse
import asyncio
import gc
import random
import sys
import tempfile
import time
import unicodedata
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

#: The keys drawn: letters, digits, the editing and moving keys, the function keys
#: and the shortcuts the screens bind.  Not ctrl+c / ctrl+q (they end the test's
#: app at once) nor ctrl+z (it suspends a real terminal's process).
KEYS = (list("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789")
        + ["enter", "escape", "tab", "shift+tab", "up", "down", "left", "right", "pageup", "pagedown", "home",
           "end", "backspace", "delete", "space", "f1", "f2", "question_mark", "plus", "minus",
           "left_square_bracket", "right_square_bracket", "left_curly_bracket", "right_curly_bracket",
           "full_stop", "comma", "slash", "ctrl+a", "ctrl+k", "ctrl+e", "ctrl+p", "ctrl+s", "ctrl+u"])
#: The keys that open each screen from Main (None: Main itself).
SCREENS: dict[str, str | None] = {"Main": None, "Setup": "S", "Design": "d", "Identify": "y", "Help": "f1"}
#: Keys handed to the app between two waits for it.
EVERY = 40


class FuzzFailure(AssertionError):
    """What the app failed on, and the keys that led there."""


@dataclass
class Tally:
    keys: int = 0
    apps: int = 0
    rounds: int = 0
    seconds: float = 0.0
    screens: dict[str, int] = field(default_factory=dict)  # keys sent while a round's screen was up


def key_event(app: Any, key: str) -> Any:
    """The Key event Textual's pilot would make of `key` (its _press_keys)."""
    from textual import events
    from textual.keys import REPLACED_KEYS, _character_to_key, _get_unicode_name_from_key

    if len(key) == 1 and not key.isalnum():
        key = _character_to_key(key)
    original = REPLACED_KEYS.get(key, key)
    char: str | None
    try:
        char = unicodedata.lookup(_get_unicode_name_from_key(original))
    except KeyError:
        char = key if len(key) == 1 else None
    event = events.Key(key, char)
    event.set_sender(app)
    return event


async def _settle(pilot: Any) -> None:
    app = pilot.app
    await pilot.pause()
    try:
        await app.workers.wait_for_complete()
    except Exception:  # noqa: BLE001 - a cancelled exclusive worker; a real error is app._exception
        pass
    await pilot.pause()


def _failed(app: Any) -> BaseException | None:
    exc = getattr(app, "_exception", None)
    return exc if isinstance(exc, BaseException) else None


async def fuzz(make_app: Callable[[], Any], n: int, seed: int, *, every: int = EVERY,
               size: tuple[int, int] = (120, 40), per_round: int = 200) -> Tally:
    """`n` random keys of seed `seed` through apps `make_app` builds, round after
    round from each screen in turn; FuzzFailure on the first failure."""
    rng = random.Random(seed)
    tally = Tally()
    start = time.monotonic()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        while tally.keys < n:
            app = make_app()
            tally.apps += 1
            trail: list[str] = []
            try:
                async with app.run_test(size=size) as pilot:
                    await _rounds(pilot, n, rng, tally, every, per_round, trail)
            except FuzzFailure:
                raise
            except Exception as exc:  # noqa: BLE001 - what the app ended on, raised as it closed
                raise FuzzFailure(_said(seed, tally, exc, trail)) from exc
            ended = _failed(app)
            if ended is not None:
                raise FuzzFailure(_said(seed, tally, ended, trail)) from ended
            gc.collect()
            never = [w for w in caught if issubclass(w.category, RuntimeWarning) and "never awaited" in str(w.message)]
            if never:
                raise FuzzFailure(f"seed {seed}, key {tally.keys}: {never[0].message} (at the exit of app "
                                  f"{tally.apps})\nkeys: {' '.join(trail[-200:])}")
    tally.seconds = time.monotonic() - start
    return tally


def _said(seed: int, tally: Tally, exc: BaseException, trail: list[str]) -> str:
    return f"seed {seed}, key {tally.keys}: {type(exc).__name__}: {exc}\nkeys: {' '.join(trail[-200:])}"


async def _rounds(pilot: Any, n: int, rng: random.Random, tally: Tally, every: int, per_round: int,
                  trail: list[str]) -> None:
    """Rounds on one app until `n` keys in all or the app ends (a key quit it)."""
    app = pilot.app
    names = list(SCREENS)
    while tally.keys < n and app.is_running:
        name = names[tally.rounds % len(names)]
        tally.rounds += 1
        trail[:] = [f"[round {tally.rounds}: {name}]"]
        while len(app.screen_stack) > 1 and app.is_running:  # back to Main
            app.pop_screen()
            await _settle(pilot)
        opener = SCREENS[name]
        if opener is not None and app.is_running:
            trail.append(opener)
            await pilot.press(opener)
            await _settle(pilot)
        sent = 0
        while sent < per_round and tally.keys < n and app.is_running:
            burst = [rng.choice(KEYS) for _ in range(min(every, per_round - sent, n - tally.keys))]
            driver = app._driver
            if driver is None:
                return
            for key in burst:
                driver.send_message(key_event(app, key))
            trail.extend(burst)
            sent += len(burst)
            tally.keys += len(burst)
            tally.screens[name] = tally.screens.get(name, 0) + len(burst)
            await _settle(pilot)
            if _failed(app) is not None:
                return


def _make_app(folder: Path) -> Callable[[], Any]:
    """Apps on one manual-clock engine each, on `folder`'s params/ and logs/."""
    from quadtank_tui.engine.runner import build_engine
    from quadtank_tui.ui.app import build_app

    def make() -> Any:
        engine = build_engine(clock="manual", params_dir=folder / "params", logs_dir=folder / "logs")
        return build_app(engine, refresh_interval=0.05, wall_clock=lambda: 0.0)
    return make


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--keys", type=int, default=20_000, help="keys in all, shared among the seeds")
    ap.add_argument("--seeds", default="1,2,3,4")
    ap.add_argument("--every", type=int, default=EVERY, help="keys handed to the app between two waits")
    a = ap.parse_args(argv)
    seeds = [int(s) for s in a.seeds.split(",")]
    status = 0
    total = 0
    t0 = time.monotonic()
    with tempfile.TemporaryDirectory(prefix="keyfuzz-") as tmp:
        for seed in seeds:
            folder = Path(tmp) / f"seed{seed}"
            (folder / "params").mkdir(parents=True)
            (folder / "logs").mkdir()
            try:
                t = asyncio.run(fuzz(_make_app(folder), a.keys // len(seeds), seed, every=a.every))
            except FuzzFailure as exc:
                print(f"FAILED: {exc}", flush=True)
                status = 1
                continue
            total += t.keys
            print(f"seed {seed}: {t.keys} keys in {t.seconds:.1f} s ({1000 * t.seconds / max(1, t.keys):.1f} ms a key), "
                  f"{t.apps} app(s), {t.rounds} rounds; keys per screen "
                  + ", ".join(f"{k} {v}" for k, v in t.screens.items()), flush=True)
    print(f"{total} keys, {'no failure' if status == 0 else 'FAILURES'} in {time.monotonic() - t0:.0f} s", flush=True)
    return status


if __name__ == "__main__":
    raise SystemExit(main())
