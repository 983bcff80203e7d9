"""Lab sessions: the experiment runs in a session process that belongs to the lab
machine, not to a terminal; TUIs attach to it, detach, observe (issue 16)."""
