"""Trajectory generation: the canonical references (Fink & Stump Table V) and the planner."""

from ._planning import *  # noqa: F401,F403  (split into references and planner: issue 13)
