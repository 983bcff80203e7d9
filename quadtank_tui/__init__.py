"""quadtank-tui: a terminal interface for the Lund quadruple-tank laboratory process."""

__version__ = "0.1.0"
