"""`python -m quadtank_tui.daq rig ...` (see quadtank_tui.daq.cli.main)."""

from quadtank_tui.daq.cli import main

raise SystemExit(main())
