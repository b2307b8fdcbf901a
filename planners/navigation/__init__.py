"""Navigation: plans from a start pose to a goal pose, from a map alone (docs/model.md §12,
§13, §14, §15).

One protocol (:class:`Planner`), one record (:class:`Route`, one JSON form), one registry
(:data:`PLANNERS`, built by :func:`make_planner`); one module per planner:

- :mod:`.step`: the paper's step-model planner (:class:`Navigator`, Algorithms 1-2, over the
  layered roadmap of :mod:`.roadmap`), with all pairs (:class:`AllPairs`);
- :mod:`.exact`: plans over exact bump poses (:class:`ExactNavigator`), with all pairs;
- :mod:`.reliable`: the near-optimal exact plan most likely to succeed under turn noise
  (:class:`ReliableNavigator`);
- :mod:`.feedback`: a particle filter re-plans after every bump (:class:`FeedbackPlanner`;
  its policy runs in :func:`bouncesim.runs.execute.execute`).

Shared concepts live one floor down (:mod:`planners.cells`, :mod:`planners.boundary`,
:mod:`planners.noise`, :mod:`planners.measures`, :mod:`planners.plan`); nothing here imports
the coverage wing.
"""

from __future__ import annotations

from .base import NEEDS, Planner, Route
from .exact import ExactAllPairs, ExactNavigator
from .feedback import FeedbackPlanner, FeedbackPolicy
from .registry import PLANNERS, make_planner, planner_class
from .reliable import ReliableNavigator
from .step import AllPairs, Navigator

__all__ = ["AllPairs", "ExactAllPairs", "ExactNavigator", "FeedbackPlanner", "FeedbackPolicy",
           "NEEDS", "Navigator", "PLANNERS", "Planner", "ReliableNavigator", "Route",
           "make_planner", "planner_class"]
