"""Feedback navigation (docs/model.md §15): a particle filter over bump poses
(:mod:`.filter`), plans from a pose (:mod:`.search`), the decision rule (:mod:`.navigator`)
and the registry's planner with the policy that the run loop executes (:mod:`.planner`).
"""

from __future__ import annotations

from .config import DEFAULT_MAX_BUMPS
from .filter import SIDES, FeedbackConfig, FlightUpdate, ParticleFilter, side_of
from .navigator import Candidate, FeedbackNavigator, final_drive, goal_intervals
from .planner import FeedbackPlanner, FeedbackPolicy, declared_sigma

__all__ = ["Candidate", "DEFAULT_MAX_BUMPS", "FeedbackConfig", "FeedbackNavigator",
           "FeedbackPlanner", "FeedbackPolicy", "FlightUpdate", "ParticleFilter", "SIDES",
           "declared_sigma", "final_drive", "goal_intervals", "side_of"]
