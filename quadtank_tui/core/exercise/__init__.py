"""Lab exercises: the requirements a teacher sets and their figures (issue 45).

Pure numbers: a requirement is a kind, a limit and where it applies (a loop, a
tank, a model element); its figure comes from sampled signals (figures.py) or
from a model or a design the use case computes (app/exercise.py) and hands in.
"""

from quadtank_tui.core.exercise.requirements import (
    KINDS, Requirement, RequirementError, Verdict, judge, live_state, signal_figure,
)

__all__ = ["KINDS", "Requirement", "RequirementError", "Verdict", "judge", "live_state", "signal_figure"]
