"""Figures of an identification and of a design (files/figures/identification.py,
design.py), read back from their SVG and from the figure's own artists: an axes per
plot, the curves by their ids, the titles' figures, and the Nyquist curve touching
the 1/Ms circle of an Ms-constrained design."""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from quadtank_tui.core.design.expr import parse_model
from quadtank_tui.core.design.frequency import margins
from quadtank_tui.core.design.optimize import pi_ms
from quadtank_tui.core.identify.experiment import Options, Record, identify
from quadtank_tui.core.identify.sampling import simulate
from quadtank_tui.files.figures.design import DesignedLoop, design_figure
from quadtank_tui.files.figures.identification import identification_figure
from quadtank_tui.files.figures.style import render

SVG = "{http://www.w3.org/2000/svg}"


def ids(svg: bytes) -> set[str]:
    return {g.get("id") or "" for g in ET.fromstring(svg).iter(f"{SVG}g")}


def texts(svg: bytes) -> list[str]:
    return [t.strip() for t in re.findall(r"<!-- (.*?) -->", svg.decode(), flags=re.S)]


def test_an_identification_draws_validation_residuals_and_coherence_per_element() -> None:
    """A first-order process 2/(1 + 30 s) under a PRBS, read with white noise: the fit's
    residuals are that noise, so most lags are inside the band."""
    rows = 1200
    rng = np.random.default_rng(3)
    du = np.r_[0.0, np.repeat(rng.choice([-0.02, 0.02], rows // 30 + 1), 30)[: rows - 1]]
    y = 0.5 + simulate(np.array([2.0]), np.array([30.0, 1.0]), 1.0, du) + 0.001 * rng.standard_normal(rows)
    ident = identify([Record("prbs.log", 1.0, {"u1": 0.3 + du, "y1": y})], Options(method="oe", outputs=("y1",)))
    (e,) = ident.elements.values()
    svg = render(identification_figure(ident), "svg")
    groups = ids(svg)
    assert {"axes_1", "axes_2", "axes_3"} <= groups and "axes_4" not in groups
    assert {"G11:measured", "G11:model", "G11:band", "G11:autocorrelation", "G11:coherence"} <= groups
    words = texts(svg)
    assert f"validation part: fit {e.fit_percent:.1f} %" in words and e.fit_percent > 80
    assert f"{100 * e.whiteness:.0f} % of lags in the 99 % band" in words and e.whiteness > 0.8
    assert {"y1 measured", "y1 model", "t (s)", "lag (samples)", "f (Hz)"} <= set(words)
    assert "coherence u1 → y1" in words


def test_a_design_draws_the_step_s_and_t_with_ms_and_nyquist_with_the_circle() -> None:
    g = parse_model("1.6592*exp(-2.4*s)/(1.07*s+1)^3")  # Andersson's process 1
    c = pi_ms(g, 1.4)
    fig = design_figure([DesignedLoop("loop 1", g, c)], "pi-ms")
    svg = render(fig, "svg")
    assert {"step:y", "step:r", "bode:S", "bode:T", "bode:Ms", "nyquist:L", "nyquist:circle"} <= ids(svg)
    assert "Ms = 1.40" in texts(svg)
    lines = {ln.get_gid(): ln for ax in fig.axes for ln in ax.get_lines()}
    circle = np.asarray(lines["nyquist:circle"].get_xydata())
    radius = np.hypot(circle[:, 0] + 1.0, circle[:, 1])
    assert radius == pytest.approx(1.0 / 1.4, rel=1e-3)
    curve = np.asarray(lines["nyquist:L"].get_xydata())
    closest = np.nanmin(np.hypot(curve[:, 0] + 1.0, curve[:, 1]))
    assert closest == pytest.approx(1.0 / 1.4, rel=0.01)  # max |S| = Ms: the curve touches the circle
    s = np.asarray(lines["bode:S"].get_ydata())
    assert s.max() == pytest.approx(margins(c.loop(g)).Ms, rel=0.01)
    step = np.asarray(lines["step:y"].get_ydata())
    assert step[-1] == pytest.approx(1.0, abs=0.02)  # integral action: y reaches r


def test_the_design_figure_says_what_the_text_says_for_the_sampled_loop(tmp_path, capsys) -> None:
    """`quadtank design --par params/minphase.par --figure F`: the figure's Ms, phase
    margin and gain margin are the printed ones (the sampled loop's evaluation, not
    the continuous loop's: the figure said Ms 1.01 / 90 deg where the text said
    1.04 / 87), the titles are whole, and the circle is where the curve's closest
    point to -1 is."""
    from pathlib import Path

    from quadtank_tui.cli import main

    par = Path(__file__).resolve().parents[3] / "params" / "minphase.par"
    out = tmp_path / "d.svg"
    assert main(["design", "--par", str(par), "--no-step", "--spread", "0", "--sampling", "1",
                 "--figure", str(out)]) == 0
    printed = re.findall(r"loop (\d) on \S+: .*?Ms (\S+)\s+phi_m (\d+) deg", capsys.readouterr().out)
    assert len(printed) == 2
    svg = out.read_bytes()
    said = texts(svg)
    for loop, ms, pm in printed:
        assert f"Ms = {ms}" in said
        assert any(t.startswith(f"phase margin {pm}°") for t in said)
    assert not any(re.search(r"\de$", t) for t in said)  # no title cut inside a number
    from quadtank_tui.core.design.mimo import design_2x2, model_in_use
    from quadtank_tui.files.par import read_par

    d = design_2x2(model_in_use(read_par(par).params), h=1.0).loops[0]
    fig = design_figure([DesignedLoop("loop 1", d.model, d.controller, 1.0, d.evaluation)])
    lines = {ln.get_gid(): ln for ax in fig.axes for ln in ax.get_lines()}
    curve = np.asarray(lines["nyquist:L"].get_xydata())
    assert np.nanmin(np.hypot(curve[:, 0] + 1.0, curve[:, 1])) == pytest.approx(1.0 / d.evaluation.Ms, rel=1e-3)
    legend = fig.axes[2].get_legend()
    assert legend is not None and legend.get_bbox_to_anchor().y0 < fig.axes[2].get_window_extent().y0
