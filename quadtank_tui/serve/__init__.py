"""`quadtank serve`: the TUI in a browser, behind real logins, each tab run as its user."""
