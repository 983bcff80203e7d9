"""Limits and names every part of the parameter model shares.

Kept apart from the dataclasses and the key table so that both can import them
without importing each other.  The names of files and screens (log columns, plot
types, file names) are not here: they belong to files (quadtank_tui.files.names).
"""

from __future__ import annotations

from enum import Enum


class ControlMode(str, Enum):
    """Manual: the generators drive u1, u2; Automatic: they drive the references."""

    MANUAL = "Manual"
    AUTOMATIC = "Automatic"


#: Sampling time range, ms (thesis 5.4: "50 ms ... a few seconds").
TSAMP_MIN_MS = 50.0
TSAMP_MAX_MS = 10_000.0
#: The original's LogOn collected at most 5000 points.  We allow more because a P+
#: step settles in ~800 s, longer than 5000 samples at 100 ms; files of the
#: original never exceed 5000, so reading them is unaffected.
POINTS_MAX_ORIGINAL = 5000
POINTS_MAX = 100_000
#: Smallest operating point (normalized level): 0.2 mm at kc = 0.5 V/cm.  Any
#: positive number used to pass, and 4.9e-324 then failed in plant() with no file,
#: line or key (its outlet area underflowed to 0).
OP_POINT_MIN = 0.001
#: Largest magnitude accepted for a number without a narrower range (General
#: coefficients): beyond it a value is a typo or junk, not a controller.
MAX_ABS = 1e9

# --- section names of the `.par` file ----------------------------------------------

TSAMP = "SAMPLING TIME.TSamp"
REFERENCE_SECTIONS = ("REFERENCE ONE", "REFERENCE TWO")
CONTROLLER_SECTIONS = ("CONTROLLER ONE", "CONTROLLER TWO", "CONTROLLER THREE", "CONTROLLER FOUR")
STATEFB_SECTION = "STATE FEEDBACK"
MPC_SECTION = "MPC"
