"""Feedback navigation (docs/model.md §22): a particle filter over bump poses
(:mod:`.filter`), plans from a pose (:mod:`.search`) and the decision rule
(:mod:`.navigator`).
"""

from __future__ import annotations

from .filter import SIDES, FeedbackConfig, FlightUpdate, ParticleFilter, side_of
from .navigator import Candidate, FeedbackNavigator, final_drive, goal_intervals

__all__ = ["Candidate", "FeedbackConfig", "FeedbackNavigator", "FlightUpdate",
           "ParticleFilter", "SIDES", "final_drive", "goal_intervals", "side_of"]
