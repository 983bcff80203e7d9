"""`python -m quadtank_tui` is the `quadtank` command."""

from quadtank_tui.cli import main

if __name__ == "__main__":
    raise SystemExit(main())
