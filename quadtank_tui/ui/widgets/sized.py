"""Content that depends on a widget's size, made before the frame that shows it.

Textual lays a screen out, renders the frame, and only then delivers each widget
its Resize event.  A widget that fits its text to its width in `on_resize` (a
trend's key line, the process image's valves on its border, a channel's bar) was
therefore drawn twice at every start and after every resize: once with the text
made for no size, then again with the right one.  At 120x40 the second drawing
of the Main screen cost 30 ms of the start's 150-300 ms of CPU (the trends' plots
drawn again), and sent a second frame to the terminal.

A :class:`FitsItsSize` widget is told its size while the layout is made
(Textual's `_size_updated`, which sets the size the frame is drawn at): what
`fit_to_size` changes is in that frame.  tests/ui/test_start_frame.py counts the
drawings, so a Textual whose layout no longer calls it fails there.

A screen that packs tighter on a small terminal (a class its CSS reads) is a
:class:`PacksForSize`: packed on its mount, from the app's size, so its first
frame is laid out packed; set on the first Resize instead, the whole screen was
drawn again at 80x24.
"""

from __future__ import annotations

from typing import Any

from textual.geometry import Size
from textual.screen import Screen
from textual.widget import Widget


class FitsItsSize(Widget):
    """A widget whose content depends on its size: :meth:`fit_to_size` runs when the
    layout gives it a new size, before the frame is drawn."""

    def fit_to_size(self) -> None:
        """Make what depends on the size (`self.size`, `self.content_size`)."""

    def _size_updated(self, size: Size, virtual_size: Size, container_size: Size, layout: bool = True) -> bool:
        changed = super()._size_updated(size, virtual_size, container_size, layout)
        if changed:
            self.fit_to_size()
        return changed


class PacksForSize(Screen[Any]):
    """A screen (or window) whose classes depend on the terminal's size: :meth:`pack`
    on its mount, from the app's size, and on each resize.  (Textual runs each
    class's `on_mount` and `on_resize`: a subclass's own run beside these.)"""

    def on_mount(self) -> None:
        self.pack(self.app.size)

    def on_resize(self) -> None:
        self.pack(self.size)

    def pack(self, size: Size) -> None:
        """Set the classes for a terminal of `size`."""
