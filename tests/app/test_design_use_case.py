"""The design use case (app.design) at P- and P+ with the shipped files: one default,
the CLI's answer, and a suggested row only where the 2x2 loop with the other
loop's controller is stable."""

from __future__ import annotations

from pathlib import Path

import pytest

from quadtank_tui.app.design import design_pair, loop1_must_close, loop_table
from quadtank_tui.core.design.mimo import model_in_use, slowest_pole
from quadtank_tui.files.par import read_par

PARAMS = Path(__file__).resolve().parents[2] / "params"


def _setting(name: str):
    params = read_par(PARAMS / name).params
    return model_in_use(params), params.tsamp


@pytest.mark.parametrize("name, kc, ti, closed", [
    ("minphase.par", (1.908, 1.758), (62.7, 90.34), False),
    ("nonminphase.par", (3.268, -0.09612), (63.21, 111.2), True),
])
def test_default_pair_and_each_loops_suggested_row_are_the_clis(name: str, kc: tuple[float, float],
                                                                ti: tuple[float, float], closed: bool) -> None:
    G, h = _setting(name)
    chk = design_pair(G, h)
    c1, c2 = chk.pid_pair()
    # the numbers `quadtank design --par params/NAME` prints (tests/cli pins them too)
    assert (c1.Kc, c2.Kc) == pytest.approx(kc, rel=1e-3) and (c1.Ti, c2.Ti) == pytest.approx(ti, rel=1e-3)
    assert chk.stable and loop1_must_close(G) is closed
    t1 = loop_table(1, G[0][0], h, G=G, other=c2, first=c1)
    t2 = loop_table(2, G[1][1], h, G=G, other=c1, first=c1)
    assert t2.how == ("g22 with loop 1 closed" if closed else "g22")
    for t, c in ((t1, c1), (t2, c2)):
        # the suggested row is the default design, the same controller the CLI gives
        assert t.best is not None and t.best == t.default
        row = t.rows[t.best]
        assert row.controller is not None and row.controller.rounded() == c
        assert row.problem is None
    # no row a table suggests or passes makes an unstable pair with the other loop's choice
    for t, other, loop in ((t1, c2, 1), (t2, c1, 2)):
        for r in t.rows:
            if r.problem is None and r.controller is not None:
                pair = (r.controller.rounded(), other) if loop == 1 else (other, r.controller.rounded())
                assert slowest_pole(G, *pair, h) < 0.0, r.label


def test_at_p_plus_loop_2_on_its_own_g22_is_never_suggested() -> None:
    """What the screen did: lambda on g22 for loop 2 with loop 1's PI, marked "best"
    while the pair is unstable (slowest pole 0.00815 1/s).  On g22 itself (no
    loop 1 to close around) every lambda row now says the 2x2 loop is unstable."""
    G, h = _setting("nonminphase.par")
    c1 = design_pair(G, h).pid_pair()[0]
    t = loop_table(2, G[1][1], h, G=G, other=c1, ms_values=(1.4,))  # first=None: designed on g22 alone
    assert t.how == "g22"
    lam = [(r, r.controller) for r in t.rows if r.method == "lambda" and r.controller is not None]
    assert lam and all(c.Kc > 0 and r.pair is not None and "unstable" in r.pair for r, c in lam)
    assert slowest_pole(G, c1, lam[0][1].rounded(), h) > 0.005
    assert t.best is None or t.rows[t.best].pair is None
