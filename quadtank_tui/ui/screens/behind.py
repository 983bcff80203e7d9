"""A screen that goes on changing behind a window without repainting the terminal.

Textual (8.2) handles a change on a screen behind a modal window by repainting
those regions of the window's screen, then marking them dirty again on the screen
behind and asking it for a repaint: on its next change the regions come back
together with the new ones.  They pile up while the window is open, and once a
whole-screen region is among them (it is, from the window's arrival) every sample
repaints the whole terminal: the Pump, Tank or Logging window over a running
loop wrote 150-330 KB/s at 120x40 instead of the few cells that changed.

What the screen behind looks like is rendered from its widgets each time the
window's screen is painted, and a screen coming back to the front is repainted
whole (Screen._on_screen_resume), so nothing needs the piled-up regions: they
are dropped once the window's screen has been told about them.

Even so each change of the screen behind makes Textual render all of it again,
dimmed, for the window's screen: a screen's timer redraws it at most once every
BEHIND_INTERVAL while a window covers it (`redraw_due`); it is dimmed, and the
window in front is what the user reads.
"""

from __future__ import annotations

import time

from textual.screen import Screen

#: How often a screen is redrawn on its timer while a window covers it, s (a
#: Pump window over Main at Ts 0.1 s cost 15 % of a core, redrawn each sample).
BEHIND_INTERVAL = 1.0


class QuietBehind(Screen[None]):
    """A screen whose changes behind a window repaint only what changed."""

    _behind_at = 0.0  # when the timer last redrew the screen under a window

    def redraw_due(self) -> bool:
        """Whether the screen's timer should redraw it now: always in front, at
        most once every BEHIND_INTERVAL behind a window."""
        if self.app.screen is self:
            return True
        now = time.monotonic()
        if now - self._behind_at < BEHIND_INTERVAL:
            return False
        self._behind_at = now
        return True

    def _compositor_refresh(self) -> None:
        super()._compositor_refresh()
        try:
            behind = self.app.screen is not self
        except Exception:  # no screen stack: the app is closing
            return
        if behind:
            self._repaint_required = False
            self._repaint_regions.clear()
