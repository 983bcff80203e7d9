"""`python -m quadtank_tui` is the `quadtank` command."""

from quadtank_tui.cli import main

if __name__ == "__main__":  # the loop process (spawn) imports this module again
    raise SystemExit(main())
