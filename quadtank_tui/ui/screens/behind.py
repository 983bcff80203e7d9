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
"""

from __future__ import annotations

from textual.screen import Screen


class QuietBehind(Screen[None]):
    """A screen whose changes behind a window repaint only what changed."""

    def _compositor_refresh(self) -> None:
        super()._compositor_refresh()
        try:
            behind = self.app.screen is not self
        except Exception:  # no screen stack: the app is closing
            return
        if behind:
            self._repaint_required = False
            self._repaint_regions.clear()
