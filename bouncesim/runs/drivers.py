"""Drive one (start, goal) pair with any registered planner: what navigation experiments
sweep (``experiments.nav_montecarlo``, ``nav_feedback``, ``nav_reliable``).

:func:`driver` takes ``(name, env, start, goal, config, rng)`` and returns a :class:`Driver`:
called with a :class:`bouncesim.robots.Robot` placed nowhere in particular, it runs the
planner's policy from ``start`` towards ``goal`` in the one run loop
(:func:`bouncesim.runs.execute.execute`) and returns the run. An open-loop planner's plan is
computed once per map, pair and configuration (and cached); a closed-loop planner decides
after every bump.

>>> import envs
>>> import numpy as np
>>> from bouncesim.robots import make_robot
>>> env = envs.load("lab")
>>> d = driver("exact", env, 8, 0, NavConfig(), np.random.default_rng(0))
>>> run = d(make_robot("kinematic", env))
>>> run.success, d.decisions
(True, 1)
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from envs import Environment
from envs.motion import PYBULLET_CONTACT, ContactParams
from planners.cells import CellSpace
from planners.navigation import make_planner, planner_class
from planners.noise import parse_noise_spec
from planners.plan import Plan

from ..robots.noise import parse_noise
from .execute import execute

__all__ = ["Driver", "NavConfig", "NoPlan", "PYBULLET_TURN_SIGMA", "cells_of",
           "declared_noise", "driver"]


class NoPlan(RuntimeError):
    """The planner found no plan for the pair (the driver cannot drive)."""


@dataclass(frozen=True)
class NavConfig:
    """What every planner is given besides the map and the pair.

    Attributes
    ----------
    angles : tuple of float   bouncing angles Φ [deg]
    w1, w2 : float            cost per step (or same-angle bump) and per angle change (§12)
    noise : str               the declared turn noise (a noise spec); planners that do not
                              need noise ignore it, reliable and feedback planners use it
    speed : float             drive speed [m/s]
    contact : ContactParams or None
        The executing robot's contact rule (docs/model.md §9): open-loop planners that need
        one plan their flights under it (§13, §14); None: every contact bumps. Closed-loop
        planners take the body's own rule.
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


PYBULLET_TURN_SIGMA = 0.3
"""Gaussian turn noise σ [deg] a noise-needing open-loop planner declares at least for
PyBullet's body (contact rule ``PYBULLET_CONTACT``): its turns land 0.1–0.7° off even
noise-free, and the twin with that rule and σ = 0.3° predicts which exact plans fail there (a
corner passed within millimetres, a run along a touched wall); at σ = 0 every candidate of
the reliable planner scores 1 and its plan would be the exact one."""


def declared_noise(config: NavConfig) -> str:
    """The noise spec an open-loop planner plans for: ``config.noise``, raised to Gaussian
    σ = :data:`PYBULLET_TURN_SIGMA` for PyBullet's contact rule when it is Gaussian (or none)
    and smaller.

    >>> declared_noise(NavConfig(noise="gauss:0", contact=PYBULLET_CONTACT))
    'gauss:0.3'
    >>> declared_noise(NavConfig(noise="gauss:2", contact=PYBULLET_CONTACT))
    'gauss:2'
    >>> declared_noise(NavConfig(noise="gauss:0"))
    'gauss:0'
    """
    spec = str(config.noise)
    parsed = parse_noise_spec(spec)
    if config.contact != PYBULLET_CONTACT or parsed.kind == "model":
        return spec
    if parsed.noise.sigma_deg < PYBULLET_TURN_SIGMA:
        return f"gauss:{PYBULLET_TURN_SIGMA:g}"
    return spec


@dataclass
class Driver:
    """Runs one planner's policy for one pair (see the module).

    Attributes
    ----------
    name : str               the planner's registry name
    plan : Plan or None      an open-loop planner's plan (None: none found, or closed loop)
    start, goal : int        configuration indices
    decisions : int          decisions of the last run (an open-loop plan is one decision,
                             a closed-loop planner takes one per bump)
    decision_s : float       their wall time [s] (an open-loop plan: its planning time)
    """

    name: str
    env: Environment
    start: int
    goal: int
    config: NavConfig
    rng: np.random.Generator | None = None
    plan: Plan | None = None
    decisions: int = 1
    decision_s: float = 0.0

    def __call__(self, robot):
        """Place the robot at the start and run the policy (a ``PlanRun``)."""
        cells, c = cells_of(self.env), self.config
        if self.rng is None:                                  # open loop: the cached plan
            if self.plan is None:
                raise NoPlan(f"no plan from {self.start} to {self.goal}.")
            return execute(self.plan, robot, start=self.start, goal=self.goal, cells=cells,
                           speed=c.speed)
        planner = make_planner(self.name, cells, tuple(c.angles), w1=c.w1, w2=c.w2,
                               noise=parse_noise(c.noise, cells.delta_deg), rng=self.rng,
                               contact="auto")
        run = execute(planner.policy(self.start, self.goal), robot, cells=cells,
                      speed=c.speed)
        self.decisions, self.decision_s = len(run.decision_ms), sum(run.decision_ms) / 1e3
        return run


def driver(name: str, env: Environment, start, goal, config: NavConfig,
           rng: np.random.Generator) -> Driver:
    """The :class:`Driver` of planner ``name`` for the pair (``start``, ``goal``).

    Open-loop planners plan once per (map, pair, config): a planner that draws (its
    ``needs`` has ``rng``) from particles seeded by the pair, under :func:`declared_noise`;
    the others from one planner per map and config (built and warmed up once, so lazy
    tables are not a query's time). A closed-loop planner draws from a child of ``rng``.
    """
    cls = planner_class(name)
    if cls.closed_loop:
        return Driver(name, env, int(start), int(goal), config, rng.spawn(1)[0], None, 0)
    c = config
    contact = c.contact if "contact" in cls.needs else None
    plan, seconds = _planned(name, env, int(start), int(goal), tuple(c.angles), float(c.w1),
                             float(c.w2), declared_noise(c) if "noise" in cls.needs else None,
                             contact)
    return Driver(name, env, int(start), int(goal), c, None, plan, 1, seconds)


@lru_cache(maxsize=16)
def _planner(name: str, env: Environment, angles: tuple, w1: float, w2: float,
             contact: ContactParams | None):
    nav = make_planner(name, cells_of(env), angles, w1=w1, w2=w2, contact=contact)
    nav.plan(0, min(1, nav.cells.N - 1))     # warm-up: lazy tables are not a query's time
    return nav


@lru_cache(maxsize=4096)
def _planned(name: str, env: Environment, start: int, goal: int, angles: tuple, w1: float,
             w2: float, noise: str | None, contact: ContactParams | None):
    if "rng" in planner_class(name).needs:
        # particles seeded by the pair: one plan per (map, pair, config), as open-loop plans
        nav = make_planner(name, cells_of(env), angles, w1=w1, w2=w2, noise=noise,
                           rng=np.random.default_rng([start, goal]), contact=contact)
    else:
        nav = _planner(name, env, angles, w1, w2, contact)
    t0 = time.perf_counter()
    route = nav.plan(start, goal)
    return (None if route is None else route.plan), time.perf_counter() - t0
