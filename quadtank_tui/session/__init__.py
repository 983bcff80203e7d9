"""Lab sessions: the running experiment belongs to the lab machine, not to one
terminal.  This package holds the lab's rules (lab.py: the lab configuration;
roles.py: who is an administrator, who is connecting; policy.py: what an
unattended session does; lock.py: one program per DAQ) and the session process
with its protocol and clients.

Layers: above the DAQ (a session process may open a rig), below the UI and the
CLI.  Importing this package loads nothing.
"""
