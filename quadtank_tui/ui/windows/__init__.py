"""Modal windows.  Each returns a typed value through `dismiss` (the commands to
send, a choice, a yes/no); the screen that opened it sends the commands."""
