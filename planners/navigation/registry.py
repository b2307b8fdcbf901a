"""One front door to the navigation planners: :data:`PLANNERS` and :func:`make_planner`.

Every planner is a class with the :class:`~planners.navigation.base.Planner` shape; the
front door checks the name once (with "did you mean"), refuses an option the planner does not
use (turn noise, a random source, a contact rule: its ``needs``) and an estimated peak memory
above ``max_memory``, before anything is built.

>>> import envs
>>> from planners.cells import CellSpace
>>> cs = CellSpace(envs.load("lab"))
>>> sorted(PLANNERS)
['exact', 'feedback', 'reliable', 'step']
>>> str(make_planner("exact", cs, [90, 135]).plan(8, 0).plan)
'90° 90° 00000000 90° 90°'
>>> make_planner("step", cs, [90, 135], noise="gauss:2")
Traceback (most recent call last):
...
envs.errors.UserError: the step planner does not use turn noise (reliable and feedback do).
"""

from __future__ import annotations

import inspect

from envs import UserError

from ..cells import CellSpace
from ..registry import check_name
from ..resources import DEFAULT_MAX_MEMORY, check
from .base import NEEDS, Planner
from .exact import ExactNavigator
from .feedback.planner import FeedbackPlanner
from .reliable import ReliableNavigator
from .step import Navigator

__all__ = ["PLANNERS", "make_planner", "planner_class"]

PLANNERS: dict = {cls.name: cls for cls in (Navigator, ExactNavigator, ReliableNavigator,
                                            FeedbackPlanner)}
"""Planner name → class: ``step`` (the paper's roadmap, docs/model.md §12), ``exact`` (exact
bump poses, §13), ``reliable`` (the near-optimal exact plan most likely to succeed under
turn noise, §14), ``feedback`` (a particle filter re-plans after every bump, §15)."""

_WORDS = {"noise": "turn noise", "rng": "a random source", "contact": "a contact rule"}


def planner_class(name: str) -> type:
    """The class registered as ``name`` (a one-sentence error with a suggestion else)."""
    return PLANNERS[check_name("planner", name, PLANNERS)]


def make_planner(name: str, cells: CellSpace, angles, *, w1: float = 1.0, w2: float = 100.0,
                 noise=None, rng=None, contact=None, max_memory=DEFAULT_MAX_MEMORY,
                 **options) -> Planner:
    """The planner ``name`` of ``cells`` with bouncing angles ``angles`` [deg].

    Parameters
    ----------
    name : str                 a key of :data:`PLANNERS`
    cells : CellSpace
    angles : sequence of float bouncing angles Φ [deg]
    w1, w2 : float             weights of a step (or same-angle bump) and of an angle change
    noise, rng, contact        what the planner needs (its ``needs``): the turn noise to plan
                               for, the random source of its particles, the executing body's
                               contact rule (docs/model.md §9); giving one it does not use
                               is an error
    max_memory : int, str or None
        Refuse (:class:`envs.UserError`) when the planner's estimated peak memory exceeds
        this many bytes (or a size such as ``"2G"``; None: no limit).
    **options                  the planner's own settings (e.g. ``particles`` and ``slack``
                               of the reliable planner, ``config`` of feedback)
    """
    cls = planner_class(name)
    given = {"noise": noise, "rng": rng, "contact": contact}
    for need in NEEDS:
        if given[need] is not None and need not in cls.needs:
            users = [n for n, c in PLANNERS.items() if need in c.needs]
            raise UserError(f"the {name} planner does not use {_WORDS[need]} "
                            f"({' and '.join(users)} do).")
    params = inspect.signature(cls).parameters
    if "max_memory" in params:
        options["max_memory"] = max_memory
    else:
        est = cls.memory_estimate(cells, angles) if hasattr(cls, "memory_estimate") else None
        if est is not None:
            check(est, max_memory, f"the {name} planner in {cells.env.name} with "
                  f"N = {cells.N} configurations")
    unknown = sorted(set(options) - set(params))
    if unknown:
        own = [p for p in params if p not in ("self", "cells", "angles", "w1", "w2",
                                              *NEEDS)]
        raise UserError(f"the {name} planner has no option {', '.join(unknown)} "
                        f"(its options: {', '.join(own) or 'none'}).")
    kwargs = {need: given[need] for need in cls.needs if given[need] is not None}
    return cls(cells, angles, w1=w1, w2=w2, **kwargs, **options)
