"""A screen is drawn once when it starts: what depends on a widget's size is in the
first frame (ui/widgets/sized.py), and so are the footer's keys
(ui/widgets/key_footer.py).  Drawn twice, the Main screen's start cost 30-40 ms
more CPU at 120x40 and sent the terminal a second frame.
"""

from __future__ import annotations

from typing import Any

import pytest
from textual.widgets._footer import FooterKey
from uikit import Recording, Wire, make_app

from quadtank_tui.ui.widgets.key_footer import KeyFooter
from quadtank_tui.ui.widgets.process_image import ProcessImage
from quadtank_tui.ui.widgets.trends import Trend


@pytest.mark.parametrize("size", [(120, 40), (80, 24)])
async def test_the_main_screen_is_drawn_once_at_start(engine: Recording, size: tuple[int, int],
                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    drawn: list[str] = []
    for cls in (Trend, ProcessImage):
        render = cls.render

        def counted(self: Any, render: Any = render) -> Any:
            drawn.append(type(self).__name__)
            return render(self)
        monkeypatch.setattr(cls, "render", counted)
    rebuilt: list[KeyFooter] = []
    recompose = KeyFooter.recompose

    async def counted_recompose(self: KeyFooter) -> None:
        rebuilt.append(self)
        await recompose(self)
    monkeypatch.setattr(KeyFooter, "recompose", counted_recompose)
    app = make_app(engine)
    wire = Wire(app)
    async with app.run_test(size=size) as pilot:
        for _ in range(5):
            await pilot.pause()
        footer = app.screen.query_one(KeyFooter)
        keys = [key.key for key in footer.query(FooterKey)]
    # Each trend and the process image drawn once, the footer never rebuilt.
    assert sorted(drawn) == ["ProcessImage", "Trend", "Trend"], drawn
    assert rebuilt == []
    assert "S" in keys and "question_mark" in keys, keys  # the keys were there from the first frame
    # What reaches the terminal is that one picture (Textual writes it whole more
    # than once as the screen comes up: its resume and its timer repaint it whole).
    assert len(set(wire.updates)) == 1, [len(u) for u in wire.updates]
