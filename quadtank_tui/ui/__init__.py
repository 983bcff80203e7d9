"""The terminal interface: the Main screen, its widgets and windows.

It renders engine snapshots and sends engine commands; it holds no control logic.
"""
