"""Feedback navigation: a particle Bayes filter over bump poses, and a decision rule that
re-plans from the belief after every bump (docs/model.md §15).

The robot senses only what a bump-and-clock robot has: the duration of every flight
(distance = commanded speed × time) and which side of the bumper closed. This module turns
those readings into a belief over the robot's pose and the belief into the next bouncing
angle and the final drive. It is pure (numpy, scipy, the motion layer and the exact planner);
the loop that drives a robot is :func:`bouncesim.runs.execute.navigate_feedback`.

- :class:`ParticleFilter` (in :mod:`planners.navigation.feedback.filter`, re-exported): n weighted
  poses (x [m], y [m], heading [deg]). A turn by φ adds φ plus a draw of the declared turn
  noise N(0, σ² + σ_floor²) to every heading; a flight moves every particle along its exact
  ray cast (:mod:`envs.motion`) to its contact and weighs it by the measured distance
  (Gaussian, σ_d = ``dist_sigma_m`` + ``dist_sigma_rel`` · d) and by the bumper side its
  contact bearing predicts. Systematic resampling when the effective sample size drops
  below ``resample_ess`` · n. When no particle is consistent with a reading (distance more
  than ``consistent_z`` σ_d off, or the wrong side), the belief is re-initialised: first
  around the previous belief with headings widened by ``reinit_sigma_deg``, then, if still
  nothing fits, globally (poses uniform over the free space and headings, kept when their
  flight matches the reading).
- :class:`FeedbackNavigator`: after every bump, plans exactly (the §13 search, started from
  the pose of a particle with its heading's offset from the Δ grid kept) from the most likely
  particle and ``votes`` − 1 more drawn by weight; every distinct plan is scored by its
  success under the belief (the belief's particles pushed through the plan's turns and
  flights with the declared noise, then the best final drive); the best score wins and its
  first angle is turned. The final drive is the length that puts the most belief mass in the
  goal cell (:func:`final_drive`); it is made when at least ``final_min`` of the belief ends
  there (:meth:`FeedbackNavigator.stops`), else the robot flies on to the next bump.
  The search itself lives in :mod:`planners.navigation.feedback.search`
  (a fast one, the plain reference it is checked against, and the guided one, off by
  default).

Examples
--------
A 2 m × 2 m room; the robot at (0.5, 1) facing east bumps the east wall after
2 − 0.17 − 0.5 = 1.33 m, on both switches. A belief split between heading 0° and heading 30°
learns which it was (at 30° the flight is 1.33 / cos 30° = 1.536 m, and the wall is met 30°
to the right of the heading: the right switch only):

>>> import numpy as np
>>> from envs import Environment
>>> env = Environment.from_dict({"boundary": [[0, 0], [2, 0], [2, 2], [0, 2]],
...     "robot_radius": 0.17, "discretization": {"cell_size": 0.25, "orientations": 8}})
>>> pf = ParticleFilter(env, FeedbackConfig(particles=4), np.random.default_rng(0),
...                     poses=[[0.5, 1.0, 0.0]] * 2 + [[0.5, 1.0, 30.0]] * 2)
>>> up = pf.flight(1.33, left=True, right=True)
>>> pf.weights.round(3).tolist(), up.reinit
([0.5, 0.5, 0.0, 0.0], 0)
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...cells import CellSpace
from ..base import check_config
from ..exact import ExactNavigator
from ..exact.planner import refuse_turn_in
from .filter import (
    SIDES,
    FeedbackConfig,
    FlightUpdate,
    ParticleFilter,
    landings,
    side_of,
    side_probs,
)
from .final import final_drive, goal_intervals
from .search import ScalarWalls, cost_to_go, search, search_reference
from .value import ValueTable

__all__ = ["FeedbackConfig", "FlightUpdate", "ParticleFilter", "Candidate", "FeedbackNavigator",
           "goal_intervals", "final_drive", "side_of", "SIDES"]


# ============================================================================ decisions
def turned(head, angle: float, gain, bias, sigma: float, rng: np.random.Generator):
    """Headings (n,) [deg] turned by a commanded ``angle`` [deg]: each turns gain·φ + bias
    (its own turn factor and offset against the ones the commands correct for; None: 1 and
    0) plus a draw of N(0, sigma²).
    """
    turn = angle if gain is None else gain * angle + bias
    return head + turn + (rng.normal(0.0, sigma, len(head)) if sigma > 0 else 0.0)


@dataclass(frozen=True)
class Candidate:
    """A plan from one particle's pose: fly, then turn by each angle and fly, then the
    final drive on the last flight (docs/model.md §15).

    Attributes
    ----------
    angles : tuple of float    bouncing angles in order [deg]
    flights : tuple of float   expected flights from the planned-from pose [m] (the first
                               is the current flight: 0 right after a bump)
    final_m : float            the plan's own final drive [m]
    cost : float               §13's cost
    p_success : float          estimated success under the belief (nan: not scored)
    stop_min : float           after the last angle the final drive is made when the belief
                               puts at least this much mass in the goal cell (nan: the
                               config's ``final_min``; a value decision's: the value of
                               flying on)
    """

    angles: tuple
    flights: tuple
    final_m: float
    cost: float
    p_success: float = float("nan")
    stop_min: float = float("nan")


class FeedbackNavigator:
    """Chooses bouncing angles and the final drive from a :class:`ParticleFilter`'s belief
    (docs/model.md §15).

    Parameters
    ----------
    cells : CellSpace
    angles : sequence of float   bouncing angles Φ [deg]
    goal : int                   goal configuration z
    config : FeedbackConfig
    w1, w2 : float               §13's weights
    """

    def __init__(self, cells: CellSpace, angles, goal: int, config: FeedbackConfig | None = None,
                 w1: float = 1.0, w2: float = 100.0) -> None:
        self.cells, self.cfg = cells, config if config is not None else FeedbackConfig()
        self.nav = ExactNavigator(cells, angles, w1, w2, contact=self.cfg.contact)
        self.goal = check_config(cells, goal, "goal")
        gp, self.gk = (int(v) for v in cells.pk(self.goal))
        lo = np.asarray(cells.env.origin, dtype=float) + cells.cells_ij[gp] * cells.h
        self.box = (float(lo[0]), float(lo[1]), float(lo[0] + cells.h), float(lo[1] + cells.h))
        self.goal_heading = self.gk * cells.delta_deg
        _ = self.nav.scalar_boundary            # build the contact bins now, not at a bump
        self.walls = ScalarWalls(self.nav.caster)
        self.guide = cost_to_go(self).tolist() if self.cfg.guided and not self.cfg.reference \
            else None
        self._value = None

    @property
    def by_value(self) -> bool:
        """Whether decisions are made by the closed-loop value (``decision`` "value", or
        "auto" with a declared turn error or a contact rule that turns the body in, which the
        plan search does not follow) rather than by scored plans.
        """
        d, rule = self.cfg.decision, self.cfg.contact
        return d == "value" or (d == "auto" and (self.cfg.value_sigma_deg > 0 or (
            rule is not None and bool(rule.turn_in))))

    @property
    def value(self) -> ValueTable:
        """The closed-loop value table of this goal (:mod:`.value`), built on first use."""
        if self._value is None:
            cfg = self.cfg
            self._value = ValueTable(self, cfg.value_sigma_deg, cfg.value_horizon, cfg.gamma,
                                     cfg.heading_step_deg, cfg.value_nodes,
                                     cfg.stop_extra * cfg.value_sigma_deg,
                                     cfg.stop_at_bump)
        return self._value

    # ------------------------------------------------------------------ planning
    def plan_from(self, x: float, y: float, heading_deg: float) -> Candidate | None:
        """§13's cheapest plan from a pose whose heading may lie off the Δ grid: the offset
        ε = heading − kΔ is kept on every later heading (turns are multiples of Δ), so the
        flights are cast at kΔ + ε. The first flight is the current one (0 right after a
        bump). None when the goal is not reached.

        With turn noise (``edge_guard`` · turn spread = g > 0), a flight after a turn is not
        taken when the same flight at heading ± g bumps at once: it runs along a wall the
        robot touches, a knife edge (§10) that a few degrees of turn error close.
        """
        plans = self.plans_from(x, y, heading_deg, 0.0)
        return plans[0] if plans else None

    def plans_from(self, x: float, y: float, heading_deg: float, slack: float,
                   bumped: bool = False, guided: bool = True) -> list[Candidate]:
        """Like :meth:`plan_from`, every goal arrival within ``slack`` of the cheapest
        (one per settled state whose flight reaches the goal, distinct angle sequences
        only), cheapest first. ``bumped``: the robot is at a contact, the first flight is 0.
        With ``config.guided`` (and ``guided``) the search is guided by the cost to go
        (§15) and its plans need not be the cheapest.
        """
        refuse_turn_in(self.cfg.contact)
        if self.cfg.reference:
            plans = search_reference(self, x, y, heading_deg, slack, bumped)
        else:
            plans = search(self, x, y, heading_deg, slack, bumped,
                           self.guide if guided else None)
        return [Candidate(*plan) for plan in plans]

    # ------------------------------------------------------------------ scoring
    def score(self, pos, heading, angles, rng: np.random.Generator,
              bumped: bool = False, gain=None, bias=None) -> float:
        """Estimated success of flying (not when ``bumped``: at a contact), then turning by
        each angle and flying, then the best final drive, for equally weighted particles
        (pos (n, 2), heading (n,) [deg]) under the declared noise. ``gain`` and ``bias``
        (n,): each particle turns gain·φ + bias for a turn meant as φ (its turn factor and
        offset against the ones the commands correct for; default 1 and 0).
        """
        caster, contact = self.nav.caster, self.cfg.contact
        pos, head = np.array(pos, dtype=float), np.array(heading, dtype=float)
        s = self.cfg.turn_spread_deg
        for j, a in enumerate(angles):
            if not (bumped and j == 0):
                _, pos, _, _, _, head = landings(caster, pos, head, contact, bearings=False)
            turn = a if gain is None else gain * a + bias
            head = head + turn + (rng.normal(0.0, s, len(head)) if s > 0 else 0.0)
        return self.final(pos, head, np.full(len(head), 1.0 / len(head)))[1]

    def scores(self, pos, heading, plans, rng: np.random.Generator,
               bumped: bool = False, gain=None, bias=None) -> list[float]:
        """:meth:`score` of every angle sequence of ``plans`` in turn, computed together:
        the noise is drawn in the same order and every flight is cast for all plans at once,
        so the numbers are the same as one :meth:`score` after another.
        """
        if self.cfg.reference or not plans:
            return [self.score(pos, heading, a, rng, bumped, gain, bias) for a in plans]
        pos0, head0 = np.array(pos, dtype=float), np.array(heading, dtype=float)
        n, lens = len(head0), np.array([len(a) for a in plans])
        s = self.cfg.turn_spread_deg
        noise = np.zeros((len(plans), int(lens.max()), n))
        if s > 0:
            for c, a in enumerate(plans):
                noise[c, :len(a)] = rng.normal(0.0, s, (len(a), n))
        pos = np.repeat(pos0[None], len(plans), axis=0)              # (C, n, 2)
        head = np.repeat(head0[None], len(plans), axis=0)            # (C, n)
        caster = self.nav.caster
        for j in range(int(lens.max())):
            act = np.flatnonzero(lens > j)
            if not (bumped and j == 0):
                p, th = pos[act].reshape(-1, 2), head[act].reshape(-1)
                _, p, _, _, _, th = landings(caster, p, th, self.cfg.contact, bearings=False)
                pos[act], head[act] = p.reshape(len(act), n, 2), th.reshape(len(act), n)
            turn = np.array([plans[c][j] for c in act], dtype=float)[:, None]
            if gain is not None:
                turn = gain[None] * turn + bias[None]
            head[act] = head[act] + turn + noise[act, j] if s > 0 else head[act] + turn
        _, _, _, sl, D, _ = landings(caster, pos.reshape(-1, 2), head.reshape(-1),
                                     self.cfg.contact, bearings=False)
        D, w = D.reshape(len(plans), n), np.full(n, 1.0 / n)
        sl = None if sl is None else sl.reshape(len(plans), n)
        return [final_drive(pos[c], head[c], D[c], w, self.box, self.goal_heading,
                            self.cells.delta_deg, self.cfg.margin_m,
                            None if sl is None else sl[c])[1]
                for c in range(len(plans))]

    def final(self, pos, heading, w) -> tuple[float, float]:
        """(drive [m], belief mass in the goal cell) of the best final drive on the current
        flight of weighted particles.
        """
        pos, heading = np.asarray(pos, dtype=float), np.asarray(heading, dtype=float)
        _, _, _, slides, D, _ = landings(self.nav.caster, pos, heading, self.cfg.contact,
                                      bearings=False)
        return final_drive(pos, heading, D, w, self.box, self.goal_heading,
                           self.cells.delta_deg, self.cfg.margin_m, slides)

    def stops(self, mass: float, last: bool = False, need: float = math.nan) -> bool:
        """Whether, after the plan's last turn, the robot makes the final drive (the belief
        puts ``mass`` in the goal cell, :meth:`final`) or flies on to the next bump and
        decides again: it stops when ``mass`` > 0 and ``mass`` >= ``need`` (nan: the config's
        ``final_min``; a candidate's ``stop_min``), or when ``last`` (the bump budget allows
        no other try) and ``mass`` > 0 (§15).
        """
        need = self.cfg.final_min if math.isnan(need) else need
        return mass > 0 and (mass >= need or last)

    def localizing_angle(self, belief: ParticleFilter, n: int = 400,
                         bin_m: float = 0.05) -> float:
        """The bouncing angle whose next reading tells most about where the robot is (an
        unknown start, §15): ``n`` particles drawn by weight each predict the reading after
        turning by each angle (the flight's distance in bins of ``bin_m`` [m] and the side
        it closes); the angle whose predicted readings are the most spread (the largest
        entropy, i.e. the most information for a nearly exact sensor) wins; ties: the first.
        """
        pos, head = belief.sample(n)
        best, best_h = self.nav.angles[0], -1.0
        for a in self.nav.angles:
            D, _, beta, _, _, _ = landings(self.nav.caster, pos, head + a, self.cfg.contact)
            side = np.argmax(side_probs(beta, self.cfg), axis=1)
            # a ray that meets no wall (a particle off the free space): a reading of its own
            key = np.where(np.isfinite(D), np.floor(np.nan_to_num(D, posinf=0.0) / bin_m), -1)
            _, counts = np.unique(key.astype(np.int64) * 3 + side, return_counts=True)
            p = counts / counts.sum()
            h = float(-(p * np.log(p)).sum())
            if h > best_h + 1e-12:
                best, best_h = a, h
        return float(best)

    def heading_offset(self, belief: ParticleFilter) -> float:
        """[deg] the belief's mean heading offset ε̄ from the Δ grid (the weighted circular
        mean of θ − kΔ on the circle of period Δ), in [−Δ/2, Δ/2].
        """
        d = self.cells.delta_deg
        a = np.radians(belief.heading * (360.0 / d))
        m = math.atan2(float(belief.weights @ np.sin(a)), float(belief.weights @ np.cos(a)))
        return math.degrees(m) * d / 360.0

    def choose_value(self, belief: ParticleFilter, rng: np.random.Generator,
                     bumped: bool, left: int) -> list[Candidate]:
        """The decision by closed-loop value (§15 "Deciding by value"; QMDP): every angle
        φ turns ``value_particles`` drawn from the belief by weight (default: as many as it
        has) by φ with the declared noise; the
        final drive's mass in the goal cell (:func:`final_drive`) is the value of stopping
        after φ, γ times the mean of :attr:`value`'s V over the particles' bumps (with
        ``left`` − 1 flights left) the value of flying on; the best of the two over φ wins
        (ties: stopping, then the first angle). Returns one candidate: ``(φ,)`` with
        ``stop_min`` the value of flying on, or, before the first bump (``bumped`` False:
        the robot is on its first flight), ``()`` when the final drive on this flight is
        worth more than the next bump.
        """
        cfg, vt = self.cfg, self.value
        n = cfg.value_particles or belief.size
        pos, head, ef, eb = belief.sample(n, turns=True)
        w = np.full(n, 1.0 / n)
        caster, contact, s = self.nav.caster, cfg.contact, cfg.turn_spread_deg

        def worth(h):
            _, end, _, slid, D, h_end = landings(caster, pos, h, contact, bearings=False)
            final_m, mass = final_drive(pos, h, D, w, self.box, self.goal_heading,
                                        self.cells.delta_deg, cfg.margin_m, slid)
            cont = vt.gamma * float(vt.values(end, h_end, left - 1).mean()) if left > 0 \
                else 0.0
            return final_m, mass, cont

        if not bumped:
            final_m, mass, cont = worth(head)
            if mass > 0 and mass >= cont:
                return [Candidate((), (), final_m, math.nan, mass, cont)]
            return [Candidate((float(self.nav.angles[0]),), (), final_m, math.nan, cont, cont)]
        gain = bias = None
        if belief.turns_uncertain:          # commands correct for the estimate (f̂, b̂)
            f_hat, _, b_hat, _ = belief.turn_estimate()
            gain, bias = ef / f_hat, eb - ef * b_hat / f_hat
        best = None
        for a in self.nav.angles:
            final_m, mass, cont = worth(turned(head, a, gain, bias, s, rng))
            q = max(mass, cont)
            if best is None or q > best.p_success + 1e-12:
                best = Candidate((float(a),), (), final_m, math.nan, q, cont)
        return [best]

    def choose(self, belief: ParticleFilter, rng: np.random.Generator,
               keep: tuple = (), bumped: bool = False, shift: float = 0.0,
               left: int | None = None) -> list[Candidate]:
        """Scored candidate plans from the belief, best first (empty: no particle planned
        from reaches the goal). Planned from the heaviest particle and ``votes`` − 1 drawn by
        weight (distinct poses only); ``keep``, the rest of the previous choice's angles, is
        a candidate too (cost +inf: it loses ties). Each distinct angle sequence is scored by
        :meth:`score` on ``eval_particles`` drawn from the belief (all at once,
        :meth:`scores`). Ties keep the cheaper plan.
        ``bumped``: the robot is at a contact (plans start with a turn); ``shift`` [deg]: the
        next turn is commanded ``shift`` short of its angle (heading correction, §15), so
        plans and scores see every heading less ``shift``. ``left``: the flights the bump
        budget leaves; given, a navigator that decides by value (:attr:`by_value`) returns
        :meth:`choose_value`'s one candidate instead (``keep`` and ``shift`` do not apply).
        """
        cfg = self.cfg
        if self.by_value and left is not None:
            return self.choose_value(belief, rng, bumped, left)
        top = int(np.argmax(belief.weights))
        pos, head = belief.sample(max(cfg.votes - 1, 0))
        pos = np.vstack([belief.pos[top:top + 1], pos])
        head = np.concatenate([belief.heading[top:top + 1], head])
        seen_pose, plans = set(), {}
        for (x, y), th in zip(pos.tolist(), head.tolist()):
            key = (round(x, 2), round(y, 2), round(th * 2) / 2)   # 1 cm, 0.5°
            if key in seen_pose:
                continue
            seen_pose.add(key)
            for cand in self.plans_from(x, y, th - shift, cfg.slack, bumped)[:cfg.per_pose]:
                if cand.angles not in plans or cand.cost < plans[cand.angles].cost:
                    plans[cand.angles] = cand
        if not plans and not bumped and self.guide is not None:
            # at the start (before the robot moves) the guided searches found nothing: the
            # full search from the heaviest particle (a hard start; after a bump, the rest of
            # the plan found here stays a candidate)
            x, y, th = float(pos[0, 0]), float(pos[0, 1]), float(head[0])
            for cand in self.plans_from(x, y, th - shift, cfg.slack, bumped,
                                        guided=False)[:cfg.per_pose]:
                plans[cand.angles] = cand
        if keep and tuple(keep) not in plans:
            plans[tuple(keep)] = Candidate(tuple(keep), (), float("nan"), math.inf)
        if not plans:
            return []
        epos, ehead, ef, eb = belief.sample(cfg.eval_particles, turns=True)
        gain = bias = None
        if belief.turns_uncertain:          # commands correct for the estimate (f̂, b̂)
            f_hat, _, b_hat, _ = belief.turn_estimate()
            gain, bias = ef / f_hat, eb - ef * b_hat / f_hat
        cands = list(plans.values())
        p = self.scores(epos, ehead - shift, [c.angles for c in cands], rng, bumped, gain,
                        bias)
        scored = [Candidate(c.angles, c.flights, c.final_m, c.cost, ps)
                  for c, ps in zip(cands, p)]
        scored.sort(key=lambda c: (-round(c.p_success, 9), c.cost))
        return scored
