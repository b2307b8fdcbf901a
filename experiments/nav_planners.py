"""The navigation experiments' planners and maps.

:data:`PLANNERS`: planner name → driver factory ``(env, start, goal, config, rng) -> driver``,
one per planner of the library's registry (:func:`bouncesim.runs.drivers.driver`). A driver,
called with a :class:`bouncesim.robots.Robot`, drives it from ``start`` towards ``goal`` and
returns the run (:class:`NoPlan` when the planner has none); it exposes ``plan`` (the
open-loop plan, None for a closed-loop planner), ``decisions`` and ``decision_s``. Adding
a planner to an experiment is one line: ``register("mine", factory)``.

Maps (:func:`world`): catalogue names, ``pentagon`` (a pentagon room with a hexagonal
pillar), ``rectN`` (random rectilinear rooms, :func:`envs.generated.random_rectilinear_room`)
and ``polyN`` (random pentagon or hexagon rooms with a polygonal hole,
:func:`envs.generated.random_polygon_room`).

>>> import envs
>>> import numpy as np
>>> from bouncesim.robots import make_robot
>>> env = envs.load("lab")
>>> d = PLANNERS["exact"](env, 8, 0, NavConfig(), np.random.default_rng(0))
>>> run = d(make_robot("kinematic", env))
>>> run.success, d.decisions
(True, 1)
"""

from __future__ import annotations

import re
from collections.abc import Callable
from functools import lru_cache, partial

import numpy as np

import envs
from bouncesim.runs.drivers import (
    PYBULLET_TURN_SIGMA,
    NavConfig,
    NoPlan,
    cells_of,
    declared_noise,
    driver,
)
from envs import Environment
from envs.generated import PENTAGON, random_polygon_room, random_rectilinear_room
from planners import navigation

__all__ = ["PLANNERS", "PYBULLET_TURN_SIGMA", "NavConfig", "NoPlan", "cells_of",
           "declared_noise", "heading_class", "plan_headings", "register", "world"]


PLANNERS: dict[str, Callable] = {name: partial(driver, name) for name in navigation.PLANNERS}
"""Planner name → factory ``(env, start, goal, config, rng) -> driver``."""


def register(name: str, factory: Callable) -> None:
    """Add (or replace) a planner factory under ``name``."""
    PLANNERS[name] = factory


# ----------------------------------------------------------------------------- maps
@lru_cache(maxsize=32)
def world(name: str, seed: int = 0) -> Environment:
    """The map ``name``: a catalogue name, ``pentagon``, ``rectN`` or ``polyN`` (random room
    number N of root seed ``seed``: pentagons and hexagons for ``polyN``).
    """
    if name == "pentagon":
        return Environment.from_dict(PENTAGON)
    m = re.fullmatch(r"(rect|poly)(\d+)", name)
    if m is None:
        return envs.load(name)
    kind = 0 if m.group(1) == "rect" else 1
    rng = np.random.default_rng(np.random.SeedSequence([seed, 3, kind, int(m.group(2))]))
    if kind == 0:
        return random_rectilinear_room(rng, orientations=8, name=name)
    return random_polygon_room(rng, name, sides=(5, 7))


# ----------------------------------------------------------------------------- plans
def plan_headings(start_heading: float, plan) -> list[float]:
    """The headings [deg, in [0, 360)] the robot takes along ``plan``: the start heading, then
    the heading after every turn, in order (``Plan.turns``: repeated angles turn again).

    >>> from planners.plan import Plan
    >>> plan_headings(0.0, Plan.parse("0 90° 90° 0"))
    [0.0, 90.0, 180.0]
    """
    h = float(start_heading) % 360.0
    heads = [h]
    for a in plan.turns:
        h = (h + float(a)) % 360.0
        heads.append(h)
    return heads


def heading_class(start_heading: float, plan) -> str:
    """'axis' when every heading along the plan (:func:`plan_headings`) is a multiple of
    90°, else 'diagonal'.

    In a room with walls on the grid lines an axis-aligned plan stays on cell centres; a
    diagonal heading does not always (see docs/readme_montecarlo.md).
    """
    heads = plan_headings(start_heading, plan)
    return "axis" if all(abs(x / 90.0 - round(x / 90.0)) < 1e-9 for x in heads) else "diagonal"
