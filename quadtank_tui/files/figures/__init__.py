"""Publication figures (PNG, SVG, PDF) of runs, identifications and designs: what a
student puts in a lab report instead of redrawing the data in MATLAB.

Figures are exports, so they live with the other files a run produces: this package
reads logs and the core's results and writes image files; the core never imports
it (nor matplotlib).  Every module here imports matplotlib at its top, so the TUI
and the CLI import them only inside the action or handler that writes a figure:
matplotlib takes about a second to load, which the TUI's first frame must not pay.

- style.py: colours, line styles and fonts, and `save`, which writes a figure the
  same bytes every time (bundled DejaVu fonts, no dates in the metadata);
- runs.py: logged runs overlaid, aligned at their LogOn or at their last reference
  step, with each loop's step figures (`quadtank plot`), and the Main screen's trends;
- identification.py: measured against model output on the validation part, the
  residual autocorrelation with its 99 % band, the coherence;
- design.py: a designed loop's reference step, |S| and |T| with the Ms line, and
  the Nyquist curve with the 1/Ms circle.
"""

from __future__ import annotations

from pathlib import Path

#: File formats by suffix (the suffix of the name given chooses the format).
FORMATS = ("png", "svg", "pdf")


class FigureError(ValueError):
    """A figure that cannot be made as asked: the message says what and where."""


def figure_format(path: str | Path) -> str:
    """The format a file name asks for, from its suffix; anything else is refused.

    >>> figure_format("run.SVG")
    'svg'
    """
    suffix = Path(path).suffix.lower().lstrip(".")
    if suffix not in FORMATS:
        raise FigureError(f"{path}: a figure is written as .png, .svg or .pdf (by its suffix), "
                          f"not {'.' + suffix if suffix else 'a name without a suffix'}")
    return suffix


def free_name(folder: Path, stem: str, suffix: str) -> Path:
    """`folder/stem.suffix`, or `stem-2.suffix`, `-3` ... if taken: an export never
    replaces an earlier one.

    >>> import tempfile; d = Path(tempfile.mkdtemp()); (d / "a.png").touch()
    >>> free_name(d, "a", "png").name
    'a-2.png'
    """
    path = folder / f"{stem}.{suffix}"
    n = 2
    while path.exists():
        path = folder / f"{stem}-{n}.{suffix}"
        n += 1
    return path
