"""Esc followed at once by a key is Esc, then that key.

A terminal sends Alt+key as ESC and the key, and Textual's parser reads any ESC
that the next byte follows within its escape delay (0.1 s) as Alt: over SSH a
user's Esc (close the window) and `r` (Run) arrive in one packet and became
`alt+r`, which nothing binds; Esc then Enter became a bare Enter (Set instead of
Cancel), Esc then `1` the character `¡`, Esc then `?` a bare `?`.  This program
binds no Alt key, so an ESC before a key always means the Esc key: the parser
below reports the two keys, in order, and the app's ordered keys (keyorder.py)
let the window close before the key acts on the screen behind it.

Kept as they are: escape sequences (ESC [ and ESC O: arrows, function keys,
mouse, focus, paste; ESC ], ESC P, ESC _: the terminal's replies).  ESC b and
ESC f, which some terminals send for Option+arrow (a word left or right in a
field), are Esc then `b` (Ghost runs, on Main) or `f` (Files, on Setup): closing
a window and going on matters more than a word jump in a field of a few digits
(ctrl+left/right and the arrows still move there).
"""

from __future__ import annotations

from typing import Iterable

from textual import events
from textual._xterm_parser import XTermParser
from textual.drivers import linux_driver

ESC = "\x1b"
#: Bytes that after ESC start a sequence the terminal sends (not a key typed after Esc).
SEQUENCE_STARTS = frozenset("[O]P_" + ESC)


class EscapeThenKeyParser(XTermParser):
    """Textual's terminal parser, except that ESC + a key is two keys."""

    def _sequence_to_key_events(self, sequence: str, alt: bool = False) -> Iterable[events.Key]:
        if alt:
            # The parser gave up on a sequence and replays it: the ESC before
            # this key was the Esc key.
            yield events.Key("escape", ESC)
            yield from super()._sequence_to_key_events(sequence)
            return
        if len(sequence) == 2 and sequence[0] == ESC and sequence[1] not in SEQUENCE_STARTS:
            yield events.Key("escape", ESC)
            yield from super()._sequence_to_key_events(sequence[1])
            return
        yield from super()._sequence_to_key_events(sequence)


def install() -> None:
    """Make the terminal driver read keys with EscapeThenKeyParser.  The Linux
    driver builds its parser from its module's name for it, and offers no other
    hook; a later Textual that renames it keeps its own reading (Esc+key as Alt)."""
    if getattr(linux_driver, "XTermParser", None) in (XTermParser, EscapeThenKeyParser):
        linux_driver.XTermParser = EscapeThenKeyParser  # type: ignore[misc]  # replacing a class Textual imported
