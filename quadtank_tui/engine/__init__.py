"""The engine: the sampled control loop, its modes and clocks, process backends.

The original's real-time kernel (Nunes 1998, 5.5) as one loop that the TUI, the CLI
and the tests all drive.  It imports core and files, never the UI.
"""
