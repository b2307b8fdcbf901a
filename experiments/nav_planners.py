"""Navigation planners as pluggable drivers, and the maps the navigation experiments use.

A *planner factory* takes ``(env, start, goal, config, rng)`` and returns a *driver*: an
object that, called with a :class:`bouncesim.robots.Robot` placed nowhere in particular,
drives that robot from configuration ``start`` towards ``goal`` and returns the
:class:`bouncesim.runs.results.PlanRun` of the run. Drivers also expose

- ``plan`` : the open-loop :class:`planners.plan.Plan` (None for a closed-loop driver, or
  when the planner found no plan: calling the driver then raises :class:`NoPlan`);
- ``decisions`` : how many decisions the driver has taken (an open-loop planner takes one,
  the whole plan; a feedback driver one per bump);
- ``decision_s`` : the wall time [s] spent on them in total (the time per decision is
  ``decision_s / decisions``).

Adding a planner is one line: ``PLANNERS["reliable"] = reliable_driver``, where
``reliable_driver(env, start, goal, config, rng)`` returns such a driver.

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
import time
from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

import envs
from bouncesim.navigate import navigate_feedback
from bouncesim.robots.noise import parse_noise
from bouncesim.runs.execute import execute
from envs import Environment
from envs.generated import PENTAGON, random_polygon_room, random_rectilinear_room
from envs.motion import PYBULLET_CONTACT, ContactParams
from planners.cells import CellSpace
from planners.navigation.exact import ExactNavigator
from planners.navigation import Navigator
from planners.plan import Plan
from planners.navigation.reliable import ReliableNavigator

__all__ = ["PLANNERS", "PYBULLET_TURN_SIGMA", "FeedbackDriver", "NavConfig", "NoPlan",
           "OpenLoopDriver", "cells_of", "declared_noise", "exact_driver", "feedback_driver",
           "heading_class", "plan_headings", "register", "reliable_driver", "step_driver",
           "world"]


class NoPlan(RuntimeError):
    """The planner found no plan for the pair (the driver cannot drive)."""


@dataclass(frozen=True)
class NavConfig:
    """What every planner is given besides the map and the pair.

    Attributes
    ----------
    angles : tuple of float   bouncing angles Φ [deg]
    w1, w2 : float            cost per step (or same-angle bump) and per angle change (§6)
    noise : str               the declared turn noise (``parse_noise`` spec); open-loop
                              planners ignore it, reliable and feedback planners use it
    speed : float             drive speed [m/s]
    contact : ContactParams or None
        The executing robot's contact rule (docs/model.md §23): the exact and reliable
        planners plan their flights under it (§15, §21); the other planners ignore it. None:
        every contact bumps.
    """

    angles: tuple = (45.0, 90.0, 135.0)
    w1: float = 1.0
    w2: float = 100.0
    noise: str = "gauss:0"
    speed: float = 0.2
    contact: ContactParams | None = None


@lru_cache(maxsize=16)
def cells_of(env: Environment) -> CellSpace:
    """The cell space of ``env``, built once per environment object."""
    return CellSpace(env)


@lru_cache(maxsize=16)
def _navigator(kind: str, env: Environment, angles: tuple, w1: float, w2: float,
               contact: ContactParams | None = None):
    if kind == "exact":
        nav = ExactNavigator(cells_of(env), angles, w1, w2, contact=contact)
    else:
        nav = Navigator(cells_of(env), angles, w1, w2)
    nav.plan(0, min(1, nav.cells.N - 1))     # warm-up: lazy tables are not a query's time
    return nav


@dataclass
class OpenLoopDriver:
    """Runs one open-loop plan with :func:`bouncesim.runs.execute.execute`.

    Attributes
    ----------
    plan : Plan or None      None when the planner found none
    start, goal : int        configuration indices
    cells : CellSpace
    speed : float            [m/s]
    decisions : int          1 (the plan is the one decision)
    decision_s : float       planning wall time [s]
    """

    plan: Plan | None
    start: int
    goal: int
    cells: CellSpace
    speed: float
    decisions: int
    decision_s: float

    def __call__(self, robot):
        """Place the robot at the start and run the plan (a :class:`PlanRun`)."""
        if self.plan is None:
            raise NoPlan(f"no plan from {self.start} to {self.goal}.")
        return execute(self.plan, robot, start=self.start, goal=self.goal, cells=self.cells,
                       speed=self.speed)


@lru_cache(maxsize=4096)
def _planned(kind: str, env: Environment, start: int, goal: int, angles: tuple, w1: float,
             w2: float, contact: ContactParams | None = None):
    nav = _navigator(kind, env, angles, w1, w2, contact)
    t0 = time.perf_counter()
    route = nav.plan(int(start), int(goal))
    return (None if route is None else route.plan), time.perf_counter() - t0


def _open_loop(kind: str, env, start, goal, config: NavConfig) -> OpenLoopDriver:
    # the plan is cached per (map, pair, config): repetitions of a pair time its first query
    plan, seconds = _planned(kind, env, int(start), int(goal), tuple(config.angles),
                             float(config.w1), float(config.w2),
                             config.contact if kind == "exact" else None)
    return OpenLoopDriver(plan, int(start), int(goal), cells_of(env), config.speed, 1, seconds)


def step_driver(env, start, goal, config: NavConfig, rng: np.random.Generator):
    """The paper's step-model plan (docs/model.md §6), executed open loop (§8)."""
    return _open_loop("step", env, start, goal, config)


def exact_driver(env, start, goal, config: NavConfig, rng: np.random.Generator):
    """The exact planner's plan (docs/model.md §15) for ``config.contact``, executed open
    loop by its angles.
    """
    return _open_loop("exact", env, start, goal, config)


PYBULLET_TURN_SIGMA = 0.3
"""Gaussian turn noise σ [deg] the reliable planner declares at least for PyBullet's body
(contact rule ``PYBULLET_CONTACT``): its turns land 0.1–0.7° off even noise-free, and the twin
with that rule and σ = 0.3° predicts which exact plans fail there (a corner passed within
millimetres, a run along a touched wall); at σ = 0 every candidate scores 1 and the reliable
plan would be the exact one."""


def declared_noise(config: NavConfig) -> str:
    """The noise spec the reliable planner plans for: ``config.noise``, raised to Gaussian
    σ = :data:`PYBULLET_TURN_SIGMA` for PyBullet's contact rule when it is Gaussian and smaller.

    >>> declared_noise(NavConfig(noise="gauss:0", contact=PYBULLET_CONTACT))
    'gauss:0.3'
    >>> declared_noise(NavConfig(noise="gauss:2", contact=PYBULLET_CONTACT))
    'gauss:2'
    >>> declared_noise(NavConfig(noise="gauss:0"))
    'gauss:0'
    """
    spec = str(config.noise)
    if config.contact != PYBULLET_CONTACT or spec.strip().lower().startswith(("model",
                                                                             "stepped")):
        return spec
    noise = parse_noise(spec)                   # none or Gaussian: their σ
    if getattr(noise, "sigma_deg", 0.0) < PYBULLET_TURN_SIGMA:
        return f"gauss:{PYBULLET_TURN_SIGMA:g}"
    return spec


@lru_cache(maxsize=4096)
def _reliable_plan(env: Environment, start: int, goal: int, angles: tuple, w1: float,
                   w2: float, noise: str, contact: ContactParams | None = None):
    # particles seeded by the pair: one plan per (map, pair, config), as open-loop plans are
    nav = ReliableNavigator(cells_of(env), angles, noise, w1, w2,
                            rng=np.random.default_rng([start, goal]), contact=contact)
    t0 = time.perf_counter()
    route = nav.plan(start, goal)
    return (None if route is None else route.plan), time.perf_counter() - t0


def reliable_driver(env, start, goal, config: NavConfig, rng: np.random.Generator):
    """The most reliable near-optimal exact plan (docs/model.md §21) for the declared noise
    (:func:`declared_noise`) and the body's contact rule ``config.contact``, executed open
    loop by its angles.
    """
    plan, seconds = _reliable_plan(env, int(start), int(goal), tuple(config.angles),
                                   float(config.w1), float(config.w2), declared_noise(config),
                                   config.contact)
    return OpenLoopDriver(plan, int(start), int(goal), cells_of(env), config.speed, 1, seconds)


@dataclass
class FeedbackDriver:
    """Drives by feedback (docs/model.md §22): a particle filter re-plans after every bump.

    Attributes
    ----------
    plan : None              closed loop: no plan before the run
    decisions : int          decisions of the last run (one per bump)
    decision_s : float       their wall time [s]
    """

    env: Environment
    start: int
    goal: int
    config: NavConfig
    rng: np.random.Generator
    plan: Plan | None = None
    decisions: int = 0
    decision_s: float = 0.0

    def __call__(self, robot):
        """Run :func:`bouncesim.navigate.navigate_feedback` with ``config.noise`` declared."""
        cells = cells_of(self.env)
        c = self.config
        run = navigate_feedback(robot, self.env, self.start, self.goal,
                                parse_noise(c.noise, cells.delta_deg), self.rng,
                                angles=tuple(c.angles), cells=cells, speed=c.speed,
                                w1=c.w1, w2=c.w2)
        self.decisions, self.decision_s = len(run.decision_ms), sum(run.decision_ms) / 1e3
        return run


def feedback_driver(env, start, goal, config: NavConfig, rng: np.random.Generator):
    """Feedback navigation (docs/model.md §22); its filter draws from a child of ``rng``."""
    return FeedbackDriver(env, int(start), int(goal), config, rng.spawn(1)[0])


PLANNERS: dict[str, Callable] = {
    "step": step_driver,
    "exact": exact_driver,
    "reliable": reliable_driver,
    "feedback": feedback_driver,
}
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
