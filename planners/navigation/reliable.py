"""Plans chosen for reliability under turn noise (docs/model.md §14).

The exact planner (:mod:`planners.navigation.exact`, docs/model.md §13) returns the cheapest
plan; with rotation noise an open-loop plan misses its goal when the heading errors of its
turns carry the robot off course. This layer lists the near-optimal exact plans
(:meth:`ExactNavigator.plans`, every goal arrival within a cost ``slack`` of the cheapest),
estimates each one's success probability by propagating a seeded particle set through the
exact flights of the motion layer (:mod:`envs.motion`, vectorised over particles), and
returns the most reliable.

- :func:`rollout`: execute a plan for many particles at once, each with its own executed
  turns, as the executor (docs/model.md §21, §13) runs it on the kinematic twin: drive until a
  bump (or give up after the segment's limit), turn; then the final drive by the clock.
  Success is §21's: final position in the goal cell and heading within ±(Δ/2 + 1e-9°).
- :func:`draw_turns`: the executed turns of a particle set under a noise model (the twin's
  ``gauss:σ`` or §11 ``model:eps=E,r=R``, drawn exactly as the twin draws them).
- :func:`estimate`: successes of ``particles`` particles and the Wilson interval.
- :class:`ReliableNavigator`: candidates, selection on one particle set (common random
  numbers), and the reported ``p_success`` from a second, independent one.

Examples
--------
A 4 × 3 cell room (h = 0.34 m, K = 8), from cell (0, 0) facing east to cell (3, 2) facing
north: drive to the east wall, turn 90°, drive 0.68 m north by the clock. A turn error
δ < 0 points the robot into the wall it touches (it stays in the bottom row); δ > 0 succeeds
while the 0.68 m drive drifts west by less than half a cell, 0.68 sin δ <= 0.17 m. So
p = Φ(asin(¼)/σ) − ½, 0.4262 at σ = 10°:

>>> import numpy as np
>>> from envs import Environment
>>> from planners.cells import CellSpace
>>> from planners.noise import TurnNoise
>>> env = Environment.from_dict({"boundary": [[0, 0], [1.36, 0], [1.36, 1.02], [0, 1.02]],
...     "robot_radius": 0.17, "discretization": {"cell_size": 0.34, "orientations": 8}})
>>> cs = CellSpace(env)
>>> nav = ReliableNavigator(cs, [90, 135], TurnNoise.gauss(10.0), particles=4000,
...                         rng=np.random.default_rng(1))
>>> route = nav.plan(cs.z(0, 0), cs.z(11, 2))
>>> route.plan.exact_text(), route.chosen, route.candidates
('000 90° 00 | flights 1.019999999 m | final 0.679999999 m', 0, 6)
>>> lo, hi = route.p_success_ci
>>> bool(lo <= 0.4262 <= hi), round(hi - lo, 2)
(True, 0.03)
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, replace

import numpy as np
from scipy.stats import binomtest

from envs import UserError
from envs.contact import advance, contact_flights, glancing
from envs.motion import BUMP_RANGE, ContactParams, casters, drive_distance, unit

from ..cells import CellSpace
from ..measures import flight_limit, in_goal, step_flights
from ..noise import TurnNoise
from ..plan import Plan
from ..resources import MemoryEstimate
from .base import Route, check_config
from .exact import ExactNavigator

__all__ = ["DEFAULT_SLACK", "DEFAULT_PARTICLES", "MAX_CANDIDATES", "W2_FACTORS", "Estimate",
           "ReliableNavigator", "Rollout", "draw_turns", "estimate", "plan_cost", "rollout",
           "wilson"]

DEFAULT_SLACK = 150.0
"""Cost slack of the candidates (w1 units): at w2 = 100 one more change of angle and up to
50 step-equivalents of extra travel or same-angle bumps (docs/model.md §14)."""
W2_FACTORS = (1.0, 0.1, 0.01)
"""The candidates' searches weigh a change of angle by w2 times each factor (not below w1):
plans near-optimal at the user's weights and at tenfold and hundredfold cheaper changes."""
DEFAULT_PARTICLES = 1000
"""Particles per estimate (the Wilson 95 % half-width is at most 0.031)."""
MAX_CANDIDATES = 40
"""At most this many candidates (the cheapest) are ranked per query."""
CONFIDENCE = 0.95


# ============================================================================ statistics
def wilson(k: int, n: int, confidence: float = CONFIDENCE) -> tuple[float, float]:
    """Wilson score interval of a proportion k/n (``scipy.stats.binomtest``).

    >>> [round(v, 4) for v in wilson(8, 10)]
    [0.4902, 0.9433]
    >>> [round(v, 4) for v in wilson(20, 20)]
    [0.8389, 1.0]
    """
    if n < 1:
        raise UserError(f"a success estimate needs at least one particle, got {n}.")
    ci = binomtest(int(k), int(n)).proportion_ci(confidence_level=confidence, method="wilson")
    return float(ci.low), float(ci.high)


@dataclass(frozen=True)
class Estimate:
    """A plan's success probability estimated from ``n`` particles.

    Attributes
    ----------
    successes, n : int
    confidence : float   of the interval
    """

    successes: int
    n: int
    confidence: float = CONFIDENCE

    @property
    def p(self) -> float:
        """The estimate: successes / n."""
        return self.successes / self.n

    @property
    def ci(self) -> tuple[float, float]:
        """Wilson interval at ``confidence``."""
        return wilson(self.successes, self.n, self.confidence)


# ============================================================================ particles
@dataclass(frozen=True)
class Rollout:
    """Where a particle set's executions end (docs/model.md §21 outcome per particle).

    Attributes
    ----------
    poses : (n, 3) float      final pose (x [m], y [m], heading [deg])
    completed : (n,) bool     every segment ran (no segment ended without a bump)
    success : (n,) bool       completed, final position in the goal cell and heading within
                              ±(Δ/2 + 1e-9°) of the goal heading
    contacts : (n, b, 2) float  position [m] at each of the b bumps (nan after a failure)
    """

    poses: np.ndarray
    completed: np.ndarray
    success: np.ndarray
    contacts: np.ndarray


def _noise(noise) -> object:
    """A :class:`TurnNoise` for a spec string or None; other noise objects as given."""
    if noise is None:
        return TurnNoise()
    if isinstance(noise, str):
        return TurnNoise.from_spec(noise)
    return noise


def draw_turns(noise, plan: Plan, n: int, rng: np.random.Generator,
               delta_deg: float) -> np.ndarray:
    """(n, bumps) executed turns [deg] of the plan's turns under ``noise``, one column per
    turn in order, each column drawn as one array (as ``n`` twins draw them, turn by turn).

    ``noise``: a :class:`~planners.noise.TurnNoise` (§11 or §11a), a spec string
    (``gauss:σ``, ``model:eps=E,r=R``, ``none``), or any object with
    ``sample_many(rng, commanded)`` (the twin's noise models).
    """
    noise = _noise(noise)
    turns = np.asarray(plan.turns, dtype=float)
    out = np.empty((int(n), len(turns)))
    for j, a in enumerate(turns):
        cmd = np.full(int(n), a)
        if isinstance(noise, TurnNoise):
            out[:, j] = noise.sample(rng, cmd, delta_deg=delta_deg)
        else:
            out[:, j] = noise.sample_many(rng, cmd)
    return out


def rollout(cells: CellSpace, plan: Plan, start: int, goal: int, turns: np.ndarray, *,
            speed: float = 0.2, max_factor: float = 2.0,
            contact: ContactParams | None = None) -> Rollout:
    """Execute ``plan`` from configuration ``start`` for every row of ``turns`` (the executed
    turns [deg], ``draw_turns``), vectorised over the rows, as docs/model.md §21 and §13 run it
    on the kinematic twin (front-half bumper, no back-off).

    Every segment drives until a bump along the exact cast (no motion when the bumper is
    already closed, else the cast less ``CONTACT_GAP``); a segment that finds no wall within
    its limit, min(max_factor·(flight + 2h), bounding-box diagonal + h) for an exact plan,
    min(max_factor·(n + 2)·h, …) for a step plan of n zeros, ends that particle's run as
    failed. The final drive (exact plans: ``final_m``; step plans: the trailing run's length)
    goes by the clock and stops early at a wall. ``speed`` [m/s] only enters through the
    clock's rounding (distance = speed · (length / speed)), as in the executor.

    ``contact`` (docs/model.md §9): the executing robot's contact rule. A flight whose
    contact lies outside the bumper arc slides on to its bump
    (:func:`envs.contact.contact_flights`, as the exact planner and the twin fly it); a slide
    whose clock exceeds the segment's limit fails, as the twin times out mid-slide. The
    final drive slides on a glancing wall for the rest of its clock
    (:func:`envs.contact.advance`). None (default): every front contact bumps (bitwise the
    computation without a rule).
    """
    turns = np.asarray(turns, dtype=float)
    n = turns.shape[0]
    if turns.shape[1:] != (plan.bumps,):
        raise ValueError(f"turns must have shape (n, {plan.bumps}), got {turns.shape}.")
    caster = casters(cells.env)[0]
    sx, sy, sh = cells.pose(int(start))
    pos = np.tile([sx, sy], (n, 1))
    head = np.full(n, sh)
    alive = np.ones(n, dtype=bool)
    contacts = np.full((n, plan.bumps, 2), np.nan)
    k = int(cells.orientation_of(sh))
    if plan.is_exact:
        limits = [flight_limit(cells, max_factor, flight_m=f) for f in plan.flights_m]
        final = float(plan.final_m)
    else:
        limits = [flight_limit(cells, max_factor, zeros=zeros)
                  for zeros, angle in plan.segments() if angle is not None]
        final = step_flights(cells, plan, k)[1]
    for j, limit in enumerate(limits):
        u = unit(head)
        t = caster.cast(pos, u)
        D = np.where(t <= BUMP_RANGE, 0.0, drive_distance(t))
        reach = speed * (limit / speed)
        if contact is None:
            # the twin's timeout: it stops at the limit, a bump only when the wall is that close
            alive &= (D <= reach) | (D - reach <= BUMP_RANGE)
            pos = pos + np.minimum(D, reach)[:, None] * u
        else:
            pos, alive = _ruled_flight(caster, pos, u, D, reach, alive, contact)
        contacts[alive, j] = pos[alive]
        head = np.mod(head + turns[:, j], 360.0)
    if final > 0:
        u = unit(head)
        t = caster.cast(pos, u)
        D = np.where(t <= BUMP_RANGE, 0.0, drive_distance(t))
        budget = speed * (final / speed)
        pos = pos + np.minimum(D, budget)[:, None] * u
        if contact is not None:
            pos = _ruled_final(caster, pos, u, D, budget, alive, contact)
    poses = np.column_stack([pos, head])
    return Rollout(poses, alive, alive & in_goal(cells, goal, pos, head), contacts)


def _ruled_flight(caster, pos, u, D, reach, alive, contact):
    """One segment's flights under the contact rule: (new positions, still alive)."""
    hit = alive & (D <= reach)
    near = alive & ~hit & (D - reach <= BUMP_RANGE)
    start = pos
    pos = pos + np.minimum(D, reach)[:, None] * u
    out = alive & hit
    idx = np.flatnonzero(hit)
    if idx.size:
        fl = contact_flights(caster, start[idx], u[idx], D[idx], contact)
        pos[idx] = fl.end
        out[idx] = fl.clock <= reach        # a slide past the limit: the twin times out
    jdx = np.flatnonzero(near)              # stopped at the limit touching a wall: a bump
    if jdx.size:                            # only when that contact closes the bumper
        out[jdx] = ~glancing(caster, pos[jdx] + (D[jdx] - reach)[:, None] * u[jdx], u[jdx],
                             contact)
    return pos, out


def _ruled_final(caster, pos, u, D, budget, alive, contact):
    """The final drive's glancing stops slide on for the rest of the clock."""
    idx = np.flatnonzero(alive & (D < budget))
    if idx.size:
        idx = idx[glancing(caster, pos[idx], u[idx], contact)]
    for i in idx.tolist():
        x, y, _, _, _, _ = advance(caster, float(pos[i, 0]), float(pos[i, 1]),
                                   float(u[i, 0]), float(u[i, 1]), contact,
                                   budget - float(D[i]))
        pos[i] = (x, y)
    return pos


def estimate(cells: CellSpace, plan: Plan, start: int, goal: int, noise, particles: int,
             rng: np.random.Generator, confidence: float = CONFIDENCE,
             contact: ContactParams | None = None) -> Estimate:
    """Success probability of ``plan`` under ``noise`` from ``particles`` seeded particles
    (:func:`draw_turns` then :func:`rollout`, flown under ``contact``), with its Wilson
    interval.
    """
    particles = int(particles)
    if particles < 1:
        raise UserError(f"--particles must be at least 1, got {particles}.")
    turns = draw_turns(noise, plan, particles, rng, cells.delta_deg)
    ok = rollout(cells, plan, start, goal, turns, contact=contact).success
    return Estimate(int(ok.sum()), particles, confidence)


# ============================================================================ the planner
def plan_cost(plan: Plan, h: float, w1: float, w2: float) -> float:
    """The exact planner's cost of an exact plan (docs/model.md §13): w1 per step-equivalent
    of travel (flights and final drive over h), min(w1, w2) for the first bump (w1 with one
    angle), then w1 per bump that repeats the previous angle and w2 per change.

    >>> plan_cost(Plan.exact([90, 90, 135], [0.68, 0.0, 0.34], 0.34, h=0.34), 0.34, 1, 100)
    106.0
    """
    turns = plan.turns
    travel = (sum(plan.flights_m) + plan.final_m) / h
    bumps = [min(w1, w2) if j == 0 else (w1 if a == turns[j - 1] else w2)
             for j, a in enumerate(turns)]
    return w1 * travel + sum(bumps)


class ReliableNavigator:
    """The most reliable of the near-optimal exact plans (``"reliable"``, docs/model.md §14).

    Its :class:`~planners.navigation.base.Route` has the exact plan's fields (``cost`` at the
    user's weights) and these extras: ``p_success`` (success probability from an independent
    particle set), ``p_success_ci`` (its Wilson interval), ``candidates`` (candidates
    ranked), ``chosen`` (the chosen plan's rank by cost among them, 0: the cheapest),
    ``p_exact`` (the exact planner's own plan's estimate on the selection set),
    ``exact_cost`` (its cost), ``particles`` (per estimate) and ``noise`` (the noise planned
    for).

    Parameters
    ----------
    cells : CellSpace
    angles : sequence of float     bouncing angles Φ [deg]
    noise : TurnNoise, str or noise model
        The turn noise to plan for (``gauss:σ``, §11 ``model:eps=E,r=R``, ``none``).
    w1, w2 : float                 the exact planner's weights
    slack : float                  [w1 units] a candidate costs at most this more than the
                                   cheapest plan of its search
    w2_factors : tuple of float    one search per factor, changes of angle weighing
                                   max(w2 · factor, w1)
    particles : int                particles per estimate (selection and report each)
    max_candidates : int           at most this many candidates, the cheapest at the user's
                                   weights (the exact planner's own plan always)
    rng : numpy.random.Generator   source of every particle draw
    confidence : float             of the reported Wilson interval
    contact : ContactParams, optional
        The executing robot's contact rule (docs/model.md §9): the candidate searches plan
        slid flights under it (``ExactNavigator(contact=...)``, §13) and the particles fly
        through it (:func:`rollout`). Default None: every front contact bumps.
    """

    def __init__(self, cells: CellSpace, angles: Iterable[float], noise, w1: float = 1.0,
                 w2: float = 100.0, slack: float = DEFAULT_SLACK,
                 w2_factors: Iterable[float] = W2_FACTORS,
                 particles: int = DEFAULT_PARTICLES, max_candidates: int = MAX_CANDIDATES,
                 rng: np.random.Generator | None = None, confidence: float = CONFIDENCE,
                 contact: ContactParams | None = None) -> None:
        self.contact = contact
        self.exact = ExactNavigator(cells, angles, w1, w2, contact=contact)
        self.cells, self.w1, self.w2 = cells, self.exact.w1, self.exact.w2
        self.noise = _noise(noise)
        if not (math.isfinite(float(slack)) and float(slack) >= 0):
            raise UserError(f"the candidate slack must be a non-negative cost, got {slack}.")
        if int(particles) < 1:
            raise UserError(f"--particles must be at least 1, got {particles}.")
        if int(max_candidates) < 1:
            raise UserError(f"max_candidates must be at least 1, got {max_candidates}.")
        if rng is None:
            raise UserError("the reliable planner needs an rng (a numpy Generator).")
        weights = sorted({max(self.w2 * float(f), self.w1) for f in w2_factors} - {self.w2},
                         reverse=True)
        self.searches = [self.exact] + [ExactNavigator(cells, angles, w1, w, contact=contact)
                                        for w in weights]
        self.slack, self.particles = float(slack), int(particles)
        self.max_candidates, self.rng, self.confidence = int(max_candidates), rng, confidence

    name = "reliable"
    needs = frozenset({"noise", "rng", "contact"})
    closed_loop = False

    @property
    def angles(self) -> tuple:
        """Bouncing angles Φ [deg]."""
        return self.exact.angles

    def candidates(self, start: int, goal: int) -> list[Route]:
        """The exact planner's plan first, then every plan within ``slack`` of the cheapest
        of each search (:meth:`ExactNavigator.plans`), by cost at the user's weights,
        duplicates dropped, at most ``max_candidates``; costs are at the user's weights.
        """
        first = self.exact.plan(start, goal)
        if first is None:
            return []
        pool = {}
        for nav in self.searches:
            for r in nav.plans(start, goal, self.slack):
                pool.setdefault(r.plan, r)
        pool.pop(first.plan, None)
        h = self.cells.h
        rest = sorted((plan_cost(p, h, self.w1, self.w2), i, r)
                      for i, (p, r) in enumerate(pool.items()))
        out = [first] + [replace(r, cost=c) for c, _, r in rest]
        return out[:self.max_candidates]

    def rank(self, routes: list, start: int, goal: int) -> np.ndarray:
        """Successes of every route on one particle set (the same turn errors for all: common
        random numbers, so the comparison is not blurred by independent draws).
        """
        seed = int(self.rng.integers(2 ** 63))
        return np.array([estimate(self.cells, r.plan, start, goal, self.noise,
                                  self.particles, np.random.default_rng(seed),
                                  contact=self.contact).successes
                         for r in routes])

    def plan(self, start: int, goal: int) -> Route | None:
        """The most reliable candidate from ``start`` to ``goal`` (None when the exact
        planner has no plan); ties go to the cheaper plan. Its ``p_success`` is estimated
        again on an independent particle set (the selection's maximum is biased upward).
        """
        s = check_config(self.cells, start, "start")
        g = check_config(self.cells, goal, "goal")
        routes = self.candidates(s, g)
        if not routes:
            return None
        wins = self.rank(routes, s, g)
        best = int(np.argmax(wins))                       # first maximum: the cheapest
        r = routes[best]
        est = estimate(self.cells, r.plan, s, g, self.noise, self.particles, self.rng,
                       self.confidence, contact=self.contact)
        extras = {"p_success": est.p, "p_success_ci": est.ci, "candidates": len(routes),
                  "chosen": best, "p_exact": float(wins[0]) / self.particles,
                  "exact_cost": float(routes[0].cost), "particles": self.particles,
                  "noise": str(self.noise)}
        return replace(r, plan=replace(r.plan, planner=self.name), planner=self.name,
                       extras=extras)

    def policy(self, start: int, goal: int) -> Plan | None:
        """The plan :func:`bouncesim.runs.execute.execute` runs (None: no plan)."""
        route = self.plan(start, goal)
        return None if route is None else route.plan

    @classmethod
    def memory_estimate(cls, cells: CellSpace, angles, particles: int = DEFAULT_PARTICLES,
                        max_candidates: int = MAX_CANDIDATES) -> MemoryEstimate:
        """Peak memory of one query: the exact planner's single query (one search per
        weight factor, one after another) and the particle rollouts of the candidates (a
        few float arrays per particle and bump).
        """
        base = ExactNavigator.memory_estimate(cells, angles)
        return MemoryEstimate("the reliable planner's search and particles",
                              base.traced + 64.0 * particles * (max_candidates + 8))
