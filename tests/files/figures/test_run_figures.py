"""Figures of logged runs (files/figures/runs.py): the SVG's structure read back
(axes, labels, lines by their ids, legend texts, the step figures written beside
each loop), the PNG the same bytes twice and compared pixel by pixel within a
tolerance that a changed curve exceeds, the PDF without dates."""

from __future__ import annotations

import io
import math
import re
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from quadtank_tui.core.parameters import PRESET
from quadtank_tui.files.figures import FigureError, figure_format, free_name
from quadtank_tui.files.figures.runs import Run, align, runs_figure, scales
from quadtank_tui.files.figures.style import render

SVG = "{http://www.w3.org/2000/svg}"
T = 20.0  # the first-order answer's time constant, s
STEP = 0.1


def first_order_run(label: str, tau: float = T, rows: int = 400) -> Run:
    """Loop 1 answers a 0.1 step of r1 at t = 10 s as 0.1 (1 - exp(-t/tau)) (no
    overshoot); loop 2 sits on its reference.  Sampled every second from t = 600."""
    t = 600.0 + np.arange(rows)
    k = np.maximum(t - 610.0, 0.0)
    r1 = np.where(t >= 610.0, 0.6 + STEP, 0.6)
    y1 = 0.6 + STEP * (1.0 - np.exp(-k / tau))
    flat = np.full(rows, 0.64)
    return Run(label, t, {"y1": y1, "r1": r1, "y2": flat, "r2": flat, "u1": 0.3 + 0 * t, "u2": 0.3 + 0 * t})


def svg_of(fig) -> ET.Element:
    return ET.fromstring(render(fig, "svg"))


def texts(svg_bytes: bytes) -> list[str]:
    """The texts drawn (matplotlib writes each one's string as a comment before its glyphs)."""
    return [t.strip() for t in re.findall(r"<!-- (.*?) -->", svg_bytes.decode(), flags=re.S)]


def figure(*runs: Run, names: tuple[str, ...] = ("y1", "r1", "y2", "r2")):
    aligned = [align(r, "step", r.label) for r in runs]
    return runs_figure(aligned, names, scales("cm", PRESET.process_plant()), xlabel="time since the step, s")


def test_the_svg_has_a_panel_per_loop_its_lines_labels_legend_and_step_figures() -> None:
    fig = figure(first_order_run("A"), first_order_run("B", tau=40.0))
    data = render(fig, "svg")
    root = ET.fromstring(data)
    groups = {g.get("id") for g in root.iter(f"{SVG}g")}
    assert {"axes_1", "axes_2"} <= groups and "axes_3" not in groups
    curves = sorted(g for g in groups if g and ":" in g)
    assert curves == ["A:r1", "A:r2", "A:y1", "A:y2", "B:r1", "B:r2", "B:y1", "B:y2"]
    words = texts(data)
    assert words.count("level (cm)") == 2 and "time since the step, s" in words
    assert {"A y1", "A r1", "B y1", "B r1", "A y2", "B y2"} <= set(words)  # the legends
    # The step figures, by hand: 10-90 % of 1 - exp(-t/20) sampled each second is
    # reached at 3 s and 47 s; within 2 % from 79 s (exp(-t/20) <= 0.02 at 78.2 s);
    # IAE = sum 0.1 exp(-k/20) = 0.1/(1 - e^-0.05) normalized s, x 20 cm at kc 0.5 V/cm.
    iae = 0.1 / (1.0 - math.exp(-1.0 / T)) * 20.0
    at = words.index("loop 1: y1, r1")  # the title's lines, one text each
    assert words[at + 1] == f"A y1: rise 44 s, overshoot 0.0 %, settling 79 s, IAE {iae:.3g} cm·s"
    assert words[at + 2].startswith("B y1: rise 88 s")  # twice the time constant, twice the rise
    assert words[words.index("loop 2: y2, r2") + 1] == "A y2"  # no step on loop 2: the legend follows


def test_aligned_at_the_step_the_runs_start_at_minus_ten_seconds() -> None:
    run = align(first_order_run("A"), "step", "A")
    assert run.t[0] == -10.0 and run.t[10] == 0.0
    assert align(first_order_run("A"), "logon", "A").t[0] == 0.0
    flat = Run("F", np.arange(5.0), {"y1": np.zeros(5), "r1": np.zeros(5)})
    with pytest.raises(FigureError, match="F: no reference step in r1"):
        align(flat, "step", "F")
    with pytest.raises(FigureError, match="needs r1 or r2 logged"):
        align(Run("G", np.arange(5.0), {"y1": np.zeros(5)}), "step", "G")


def test_units_scale_levels_by_the_sensor_and_pumps_to_volts() -> None:
    plant = PRESET.process_plant()
    cm, volts, norm = (scales(u, plant) for u in ("cm", "V", "norm"))
    assert (cm["y1"].factor, cm["y1"].unit) == (20.0, "cm")  # 10 V at 0.5 V/cm
    assert (cm["u1"].factor, cm["u1"].unit) == (10.0, "V")
    assert (volts["y3"].factor, volts["y3"].unit) == (10.0, "V")
    assert norm["r2"].factor == 1.0
    with pytest.raises(FigureError):
        scales("mm", plant)


def pixels(png: bytes) -> np.ndarray:
    from matplotlib.image import imread

    return imread(io.BytesIO(png), format="png")


def one_panel(run: Run):
    return figure(run, names=("y1", "r1"))


def test_the_png_is_the_same_bytes_twice_and_a_changed_curve_shows() -> None:
    first = render(one_panel(first_order_run("A")), "png")
    again = render(one_panel(first_order_run("A")), "png")
    assert first == again
    assert first[:8] == b"\x89PNG\r\n\x1a\n" and b"quadtank-tui" in first  # Software, no date
    a, b = pixels(first), pixels(again)
    assert a.shape == (round(150 * (0.8 + 2.3)), 1200, 4)  # 8 x 3.1 in at 150 dpi
    tolerance = 1e-3
    assert np.sqrt(np.mean((a - b) ** 2)) <= tolerance
    slower = pixels(render(one_panel(first_order_run("A", tau=25.0)), "png"))
    assert np.sqrt(np.mean((a - slower) ** 2)) > tolerance  # the comparison can fail


def test_the_pdf_and_svg_have_no_dates() -> None:
    pdf = render(one_panel(first_order_run("A")), "pdf")
    assert pdf.startswith(b"%PDF")
    assert b"CreationDate" not in pdf and b"ModDate" not in pdf
    assert b"/Creator (quadtank-tui)" in pdf
    svg = render(one_panel(first_order_run("A")), "svg")
    assert b"<dc:date>" not in svg and b"quadtank-tui" in svg


def test_formats_and_free_names(tmp_path) -> None:
    assert figure_format("a/b.PDF") == "pdf"
    for bad in ("x.jpg", "x", "x.png.txt"):
        with pytest.raises(FigureError, match=r"\.png, \.svg or \.pdf"):
            figure_format(bad)
    assert free_name(tmp_path, "trends", "png").name == "trends.png"
    (tmp_path / "trends.png").touch()
    (tmp_path / "trends-2.png").touch()
    assert free_name(tmp_path, "trends", "png").name == "trends-3.png"


def test_two_figures_made_at_once_are_each_as_if_made_alone() -> None:
    """rcParams are global: without one figure at a time, the first to finish put
    matplotlib's defaults back under the other (the E key pressed twice)."""
    from concurrent.futures import ThreadPoolExecutor

    alone = render(one_panel(first_order_run("A")), "svg")
    with ThreadPoolExecutor(2) as pool:
        both = list(pool.map(lambda _: render(one_panel(first_order_run("A")), "svg"), range(2)))
    assert both == [alone, alone]
