"""`python -m quadtank_tui` is the `quadtank` command."""

from quadtank_tui.cli import main

raise SystemExit(main())
