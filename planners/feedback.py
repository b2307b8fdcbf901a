"""Feedback navigation: a particle Bayes filter over bump poses, and a decision rule that
re-plans from the belief after every bump (docs/model.md §20).

The robot senses only what a bump-and-clock robot has: the duration of every flight
(distance = commanded speed × time) and which side of the bumper closed. This module turns
those readings into a belief over the robot's pose and the belief into the next bouncing
angle and the final drive. It is pure (numpy, scipy, the motion layer and the exact planner);
the loop that drives a robot is :func:`bouncesim.navigate.navigate_feedback`.

- :class:`ParticleFilter`: n weighted poses (x [m], y [m], heading [deg]). A turn by φ adds
  φ plus a draw of the declared turn noise N(0, σ² + σ_floor²) to every heading; a flight
  moves every particle along its exact ray cast (:mod:`envs.motion`) to its contact and
  weighs it by the measured distance (Gaussian, σ_d = ``dist_sigma_m`` + ``dist_sigma_rel``
  · d) and by the bumper side its contact bearing predicts. Systematic resampling when the
  effective sample size drops below ``resample_ess`` · n. When no particle is consistent with
  a reading (distance more than ``consistent_z`` σ_d off, or the wrong side), the belief is
  re-initialised: first around the previous belief with headings widened by
  ``reinit_sigma_deg``, then, if still nothing fits, globally (poses uniform over the free
  space and headings, kept when their flight matches the reading).
- :class:`FeedbackNavigator`: after every bump, plans exactly (the §15 search, started from
  the pose of a particle with its heading's offset from the Δ grid kept) from the most likely
  particle and ``votes`` − 1 more drawn by weight; every distinct plan is scored by its
  success under the belief (the belief's particles pushed through the plan's turns and
  flights with the declared noise, then the best final drive); the best score wins and its
  first angle is turned. The final drive is the length that puts the most belief mass in the
  goal cell (:func:`final_drive`).

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

import heapq
import math
from dataclasses import dataclass

import numpy as np
from scipy.special import ndtr

from envs import Environment, UserError
from envs.motion import BUMP_RANGE, casters, drive_distance, unit

from .cells import CellSpace
from .exact import ExactNavigator, chords

__all__ = ["FeedbackConfig", "FlightUpdate", "ParticleFilter", "Candidate", "FeedbackNavigator",
           "goal_intervals", "final_drive", "side_of", "SIDES"]

SIDES = ("both", "left", "right")
"""Bumper readings: both switches, the left one only, the right one only."""
_MAX_SETTLED = 3000      # a plan search from one pose gives up after this many states
_MAX_FINAL_CANDIDATES = 128   # final drive lengths tried


# ============================================================================ configuration
@dataclass(frozen=True)
class FeedbackConfig:
    """Parameters of the filter and the decision rule (docs/model.md §20).

    Attributes
    ----------
    particles : int            n, particles of the belief
    turn_sigma_deg : float     declared turn noise σ [deg] (Gaussian per turn)
    sigma_floor_deg : float    [deg] added in quadrature to σ, so that resampled copies
                               spread and small unmodelled turn errors stay covered
    dist_sigma_m, dist_sigma_rel : float
        distance reading error σ_d = dist_sigma_m + dist_sigma_rel · d [m]
    centre_zone_deg : float    [deg] contacts within ± this of the heading close both
                               switches (the twin's ``CENTRE_ZONE_DEG``)
    side_blur_deg : float      [deg] width of the soft side boundary
    side_floor : float         probability of any reading whatever the bearing
    consistent_z : float       a particle fits a reading within this many σ_d
    resample_ess : float       resample when ESS < this · n
    reinit_sigma_deg : float   [deg] heading spread of the local re-initialisation
    votes : int                poses planned from after every bump
    slack : float              plans within this of the cheapest (§15's cost) are candidates
    per_pose : int             at most this many candidates (cheapest first) per pose
    eval_particles : int       particles pushed through each candidate plan
    margin_m : float           [m] the final stop prefers points this deep in the goal cell
    correct_heading : bool     extension, off by default: command each turn as its angle
                               less the belief's mean heading offset from the Δ grid
    """

    particles: int = 300
    turn_sigma_deg: float = 0.0
    sigma_floor_deg: float = 0.0
    dist_sigma_m: float = 0.01
    dist_sigma_rel: float = 0.01
    centre_zone_deg: float = 10.0
    side_blur_deg: float = 1.0
    side_floor: float = 0.02
    consistent_z: float = 5.0
    resample_ess: float = 0.5
    reinit_sigma_deg: float = 10.0
    votes: int = 2
    slack: float = 0.0
    per_pose: int = 1
    eval_particles: int = 64
    margin_m: float = 0.02
    correct_heading: bool = False

    def __post_init__(self) -> None:
        for name in ("particles", "votes", "per_pose", "eval_particles"):
            v = getattr(self, name)
            if int(v) != v or v < 1:
                raise UserError(f"feedback {name} must be a positive whole number, got {v}.")
        for name in ("turn_sigma_deg", "sigma_floor_deg", "dist_sigma_m", "dist_sigma_rel", "slack",
                     "centre_zone_deg", "side_blur_deg", "side_floor", "reinit_sigma_deg",
                     "margin_m"):
            v = float(getattr(self, name))
            if not (math.isfinite(v) and v >= 0):
                raise UserError(f"feedback {name} must be a non-negative number, got {v}.")
        if self.dist_sigma_m <= 0:
            raise UserError("feedback dist_sigma_m must be positive.")
        if not 0 < self.resample_ess <= 1:
            raise UserError("feedback resample_ess must lie in (0, 1].")

    @property
    def turn_spread_deg(self) -> float:
        """[deg] the heading spread the filter adds per turn: √(σ² + σ_floor²)."""
        return math.hypot(self.turn_sigma_deg, self.sigma_floor_deg)


# ============================================================================ flights
def side_of(left: bool, right: bool) -> int:
    """Index into :data:`SIDES` of a bumper reading (both, left only, right only)."""
    if left and right:
        return 0
    if left:
        return 1
    if right:
        return 2
    raise UserError("a bump needs at least one closed bumper switch.")


def _flights(caster, pos, heading_deg, bearings: bool = True):
    """Exact flights of poses: (drive [m], unit headings, contact bearings [deg] or None).

    The bearings (n, F) are those of every wall feature (side or corner) the disk touches at
    its contact (within ``BUMP_RANGE`` of the first), relative to the heading, + to the
    left; NaN for the features it does not touch (two walls at once in a corner).
    """
    pos = np.asarray(pos, dtype=float).reshape(-1, 2)
    u = unit(heading_deg)
    if not bearings:
        t = caster.cast(pos, u)
        t = np.where(np.isfinite(t), t, 1e6)
        return np.where(t <= BUMP_RANGE, 0.0, drive_distance(t)), u, None
    fd = caster.feature_distances(pos, u)
    t = fd.min(axis=1)
    t = np.where(np.isfinite(t), t, 1e6)
    D = np.where(t <= BUMP_RANGE, 0.0, drive_distance(t))
    c = pos + t[:, None] * u
    rel = c[:, None, :] - caster.A[None]                               # (n, ns, 2)
    lam = np.clip((rel * caster.e[None]).sum(2), 0.0, caster.L[None])
    touch = np.concatenate([caster.A[None] + lam[..., None] * caster.e[None],
                            np.broadcast_to(caster.vertices[None],
                                            (len(c), len(caster.vertices), 2))], axis=1)
    w = touch - c[:, None, :]
    beta = np.degrees(np.arctan2(u[:, None, 0] * w[..., 1] - u[:, None, 1] * w[..., 0],
                                 u[:, None, 0] * w[..., 0] + u[:, None, 1] * w[..., 1]))
    near = (fd <= t[:, None] + BUMP_RANGE) & (np.abs(beta) < 90.0)
    return D, u, np.where(near, beta, np.nan)


def _side_probs(beta, cfg: FeedbackConfig) -> np.ndarray:
    """(n, 3) probability of each reading of :data:`SIDES` given the touched features'
    bearings (n, F) [deg] (NaN: not touched): a feature at bearing β closes the left switch
    when β >= −zone and the right one when β <= zone (the twin's rule), blurred by a normal
    CDF of width ``side_blur_deg``; then mixed with ``side_floor``.
    """
    s = max(cfg.side_blur_deg, 1e-9)
    z = cfg.centre_zone_deg
    with np.errstate(invalid="ignore"):
        left = np.nan_to_num(np.nanmax(ndtr((beta + z) / s), axis=1, initial=0.0))
        right = np.nan_to_num(np.nanmax(ndtr((z - beta) / s), axis=1, initial=0.0))
    p = np.column_stack([left * right, left * (1 - right), (1 - left) * right])
    p /= np.maximum(p.sum(1, keepdims=True), 1e-300)
    return (1 - cfg.side_floor) * p + cfg.side_floor / 3


# ============================================================================ the filter
@dataclass(frozen=True)
class FlightUpdate:
    """What one flight reading did to the belief.

    Attributes
    ----------
    distance : float     the reading [m]
    side : str           one of :data:`SIDES`
    consistent : int     particles that fitted the reading before any re-initialisation
    reinit : int         0: none; 1: local (headings widened); 2: global
    ess : float          effective sample size after the update (before resampling)
    resampled : bool
    """

    distance: float
    side: str
    consistent: int
    reinit: int
    ess: float
    resampled: bool


class ParticleFilter:
    """A belief over the robot's pose as weighted particles (docs/model.md §20).

    Parameters
    ----------
    env : Environment
    config : FeedbackConfig
    rng : numpy.random.Generator   every draw of the filter (turn noise, resampling)
    poses : (n, 3) array-like, optional
        Initial particles (x [m], y [m], heading [deg]), equal weights.
    start : (x, y, heading), optional
        Alternatively the known start pose: ``config.particles`` copies of it.
    """

    def __init__(self, env: Environment, config: FeedbackConfig, rng: np.random.Generator,
                 poses=None, start=None) -> None:
        self.env, self.cfg, self.rng = env, config, rng
        self.caster = casters(env)[0]
        if poses is None:
            if start is None:
                raise UserError("the particle filter needs its start pose or its particles.")
            poses = np.tile(np.asarray(start, dtype=float).reshape(1, 3), (config.particles, 1))
        poses = np.asarray(poses, dtype=float).reshape(-1, 3)
        self.pos = poses[:, :2].copy()
        self.heading = poses[:, 2] % 360.0
        self.w = np.full(len(poses), 1.0 / len(poses))

    @property
    def n(self) -> int:
        """Number of particles."""
        return len(self.w)

    @property
    def weights(self) -> np.ndarray:
        """(n,) normalised weights."""
        return self.w

    @property
    def ess(self) -> float:
        """Effective sample size 1 / Σ w²."""
        return float(1.0 / np.sum(self.w ** 2))

    def poses(self) -> np.ndarray:
        """(n, 3) particles (x [m], y [m], heading [deg])."""
        return np.column_stack([self.pos, self.heading])

    def turn(self, angle_deg: float) -> None:
        """Predict a commanded CCW turn by ``angle_deg`` [deg] with the declared noise."""
        s = self.cfg.turn_spread_deg
        noise = self.rng.normal(0.0, s, self.n) if s > 0 else 0.0
        self.heading = (self.heading + float(angle_deg) + noise) % 360.0

    def back_off(self, distance: float) -> None:
        """Predict a reverse drive of ``distance`` [m] (the executor's back-off)."""
        self.pos = self.pos - float(distance) * unit(self.heading)

    def _loglik(self, d: float, side: int, D, beta):
        sd = self.cfg.dist_sigma_m + self.cfg.dist_sigma_rel * d
        z = (d - D) / sd
        ps = _side_probs(beta, self.cfg)[:, side]
        ok = (np.abs(z) <= self.cfg.consistent_z) & (ps > self.cfg.side_floor)
        return -0.5 * z * z + np.log(ps), ok

    def flight(self, distance: float, left: bool, right: bool) -> FlightUpdate:
        """Update with one flight that ended in a bump after ``distance`` [m] with the
        bumper reading (left, right): every particle flies to its exact contact.
        """
        d, side = float(distance), side_of(left, right)
        D, u, beta = _flights(self.caster, self.pos, self.heading)
        ll, ok = self._loglik(d, side, D, beta)
        ok &= self.w > 0
        consistent, stage = int(ok.sum()), 0
        if consistent:
            with np.errstate(divide="ignore"):
                logw = np.log(self.w) + ll
            pos, head = self.pos + D[:, None] * u, self.heading
            logw = np.where(ok, logw, -np.inf)
        else:
            stage, pos, head, logw = self._reinit(d, side)
        w = np.exp(logw - logw.max())
        w /= w.sum()
        self.pos, self.heading, self.w = pos, head, w
        ess = self.ess
        resampled = ess < self.cfg.resample_ess * self.n or len(w) != self.cfg.particles
        if resampled:
            self.resample(self.cfg.particles)
        return FlightUpdate(d, SIDES[side], consistent, stage, ess, resampled)

    def _reinit(self, d: float, side: int):
        """No particle fits: widen the headings of the previous belief (stage 1), else
        draw poses uniformly over the free space and all headings (stage 2).
        """
        n = self.cfg.particles
        idx = self.rng.choice(self.n, size=4 * n, p=self.w)
        pos0 = self.pos[idx]
        head0 = (self.heading[idx] + self.rng.normal(0.0, self.cfg.reinit_sigma_deg, 4 * n))
        D, u, beta = _flights(self.caster, pos0, head0)
        ll, ok = self._loglik(d, side, D, beta)
        if ok.any():
            return 1, pos0 + D[:, None] * u, head0 % 360.0, np.where(ok, ll, -np.inf)
        x0, y0, x1, y1 = self.env.bounds
        pts = np.empty((0, 2))
        for _ in range(50):
            cand = self.rng.uniform([x0, y0], [x1, y1], size=(16 * n, 2))
            pts = np.vstack([pts, cand[self.env.points_free(cand)]])
            if len(pts) >= 8 * n:
                break
        if len(pts) == 0:
            raise UserError(f"{self.env.name} has no free space for the robot.")
        head = self.rng.uniform(0.0, 360.0, len(pts))
        D, u, beta = _flights(self.caster, pts, head)
        ll, ok = self._loglik(d, side, D, beta)
        return 2, pts + D[:, None] * u, head, np.where(ok, ll, -np.inf) if ok.any() else ll

    def resample(self, n: int | None = None) -> None:
        """Systematic resampling to ``n`` equally weighted particles (default: as many)."""
        n = self.n if n is None else int(n)
        c = np.cumsum(self.w)
        c[-1] = 1.0
        idx = np.searchsorted(c, (self.rng.random() + np.arange(n)) / n)
        self.pos, self.heading = self.pos[idx].copy(), self.heading[idx].copy()
        self.w = np.full(n, 1.0 / n)

    def sample(self, n: int) -> tuple[np.ndarray, np.ndarray]:
        """``n`` poses drawn by weight (systematic): positions (n, 2), headings (n,) [deg]."""
        c = np.cumsum(self.w)
        c[-1] = 1.0
        idx = np.searchsorted(c, (self.rng.random() + np.arange(n)) / n)
        return self.pos[idx].copy(), self.heading[idx].copy()


# ============================================================================ the final drive
def goal_intervals(pos, heading_deg, D, cell_box, goal_heading_deg: float, delta_deg: float):
    """The drive lengths that end each particle's flight in the goal cell.

    Parameters
    ----------
    pos : (n, 2) [m];  heading_deg : (n,) [deg];  D : (n,) flight lengths to the bump [m]
    cell_box : (x0, y0, x1, y1) the goal cell's square [m]
    goal_heading_deg, delta_deg : a particle whose heading is more than Δ/2 from the goal
                                  heading gets no interval

    Returns
    -------
    a, b : (n,) [m]   a drive d ends in the cell when a <= d <= b (b = inf: the flight lands
                      in the cell, where the bump stops the robot); a = inf: never
    """
    pos = np.asarray(pos, dtype=float).reshape(-1, 2)
    u = unit(heading_deg)
    lo = np.zeros(len(pos))
    hi = np.asarray(D, dtype=float).copy()
    box = np.asarray(cell_box, dtype=float)
    for ax in (0, 1):
        p, c = pos[:, ax], u[:, ax]
        inside = (p >= box[ax]) & (p <= box[ax + 2])
        with np.errstate(divide="ignore", invalid="ignore"):
            t0, t1 = (box[ax] - p) / c, (box[ax + 2] - p) / c
        zero = c == 0
        lo = np.where(zero, np.where(inside, lo, np.inf), np.maximum(lo, np.minimum(t0, t1)))
        hi = np.where(zero, np.where(inside, hi, -np.inf), np.minimum(hi, np.maximum(t0, t1)))
    dh = (np.asarray(heading_deg, dtype=float) - goal_heading_deg + 180.0) % 360.0 - 180.0
    ok = (lo <= hi) & (np.abs(dh) <= delta_deg / 2)
    lands = ok & (hi >= np.asarray(D) - 1e-9)
    a = np.where(ok, lo, np.inf)
    b = np.where(lands, np.inf, np.where(ok, hi, -np.inf))
    return a, b


def final_drive(pos, heading_deg, D, w, cell_box, goal_heading_deg: float, delta_deg: float,
                margin: float) -> tuple[float, float]:
    """The final drive d [m] that puts the most weight in the goal cell.

    A particle (pos, heading, flight D to its bump, weight w) ends at pos + min(d, D)·u. It
    counts when that point lies in the cell and its heading is within Δ/2 of the goal's,
    in full once the point lies ``margin`` [m] or deeper inside the cell (depth: the distance
    to the cell's border), in proportion to its depth when shallower. The best d maximises
    that weight, then the weighted depth. Candidates: the ends of every particle's interval
    in the cell (:func:`goal_intervals`), their midpoints, and every flight's point nearest
    the cell's centre.

    Returns (d, mass): mass is the weight whose end point lies in the cell at all; nothing
    in the cell gives (0, 0).

    >>> pos, D = [[0.1, 0.5], [0.1, 0.6]], [3.0, 3.0]
    >>> final_drive(pos, [0.0, 0.0], D, [0.5, 0.5], (1.0, 0.0, 2.0, 1.0), 0.0, 45.0, 0.02)
    (1.4, 1.0)
    """
    pos = np.asarray(pos, dtype=float).reshape(-1, 2)
    head, D, w = (np.asarray(v, dtype=float).reshape(-1) for v in (heading_deg, D, w))
    a, b = goal_intervals(pos, head, D, cell_box, goal_heading_deg, delta_deg)
    ok = np.isfinite(a)
    if not ok.any():
        return 0.0, 0.0
    u = unit(head)
    box = np.asarray(cell_box, dtype=float)
    centre = (box[:2] + box[2:]) / 2
    half = (box[2] - box[0]) / 2
    near = np.clip(((centre - pos) * u).sum(1), a, np.minimum(b, D))[ok]
    ends = np.unique(np.concatenate([a[ok], b[ok & np.isfinite(b)]]))
    cand = np.unique(np.round(np.concatenate([ends, (ends[:-1] + ends[1:]) / 2, near]), 4))
    cand = cand[cand >= 0]
    if len(cand) > _MAX_FINAL_CANDIDATES:          # evenly spread over the sorted ones
        cand = cand[np.linspace(0, len(cand) - 1, _MAX_FINAL_CANDIDATES).round().astype(int)]
    t = np.minimum(cand[:, None], D[None])                       # (C, n) travelled
    end = pos[None] + t[..., None] * u[None]
    depth = half - np.abs(end - centre).max(axis=2)
    good = (np.abs((head - goal_heading_deg + 180.0) % 360.0 - 180.0) <= delta_deg / 2)[None]
    inside = good & (depth >= 0)
    soft = (w[None] * np.where(inside, np.clip(depth / max(margin, 1e-12), 0, 1), 0)).sum(1)
    deep = (w[None] * np.where(inside, depth, 0)).sum(1)
    best = np.lexsort((-deep, -np.round(soft, 9)))[0]
    return float(cand[best]), float((w[None] * inside).sum(1)[best])


# ============================================================================ decisions
@dataclass(frozen=True)
class Candidate:
    """A plan from one particle's pose: fly, then turn by each angle and fly, then the
    final drive on the last flight (docs/model.md §20).

    Attributes
    ----------
    angles : tuple of float    bouncing angles in order [deg]
    flights : tuple of float   expected flights from the planned-from pose [m] (the first
                               is the current flight: 0 right after a bump)
    final_m : float            the plan's own final drive [m]
    cost : float               §15's cost
    p_success : float          estimated success under the belief (nan: not scored)
    """

    angles: tuple
    flights: tuple
    final_m: float
    cost: float
    p_success: float = float("nan")


class FeedbackNavigator:
    """Chooses bouncing angles and the final drive from a :class:`ParticleFilter`'s belief
    (docs/model.md §20).

    Parameters
    ----------
    cells : CellSpace
    angles : sequence of float   bouncing angles Φ [deg]
    goal : int                   goal configuration z
    config : FeedbackConfig
    w1, w2 : float               §15's weights
    """

    def __init__(self, cells: CellSpace, angles, goal: int, config: FeedbackConfig | None = None,
                 w1: float = 1.0, w2: float = 100.0) -> None:
        self.cells, self.cfg = cells, config if config is not None else FeedbackConfig()
        self.nav = ExactNavigator(cells, angles, w1, w2)
        self.goal = self.nav._check(goal, "goal")
        gp, self.gk = (int(v) for v in cells.pk(self.goal))
        lo = np.asarray(cells.env.origin, dtype=float) + cells.cells_ij[gp] * cells.h
        self.box = (float(lo[0]), float(lo[1]), float(lo[0] + cells.h), float(lo[1] + cells.h))
        self.goal_heading = self.gk * cells.delta_deg
        _ = self.nav._scalar_boundary           # build the contact bins now, not at a bump

    # ------------------------------------------------------------------ planning
    def plan_from(self, x: float, y: float, heading_deg: float) -> Candidate | None:
        """§15's cheapest plan from a pose whose heading may lie off the Δ grid: the offset
        ε = heading − kΔ is kept on every later heading (turns are multiples of Δ), so the
        flights are cast at kΔ + ε. The first flight is the current one (0 right after a
        bump). None when the goal is not reached.
        """
        plans = self.plans_from(x, y, heading_deg, 0.0)
        return plans[0] if plans else None

    def plans_from(self, x: float, y: float, heading_deg: float, slack: float,
                   bumped: bool = False) -> list[Candidate]:
        """Like :meth:`plan_from`, every goal arrival within ``slack`` of the cheapest
        (one per settled state whose flight reaches the goal, distinct angle sequences
        only), cheapest first. ``bumped``: the robot is at a contact, the first flight is 0.
        """
        cs, nav = self.cells, self.nav
        K, m, h, dlt = cs.K, nav.m, cs.h, cs.delta_deg
        k0 = int(round(heading_deg / dlt))
        eps = float(heading_deg) - k0 * dlt
        k0 %= K
        units = [tuple(float(v) for v in u) for u in unit(np.arange(K) * dlt + eps)]
        w1, w2 = nav.w1, nav.w2
        first_bump = w1 if m == 1 else min(w1, w2)
        steps = nav._steps.tolist()
        gx0, gy0, gx1, gy1 = self.box
        gk, gp = self.gk, int(cs.pk(self.goal)[0])
        cast, bin_of = nav.caster.cast_one, nav._bin_of_scalar

        def bound(px: float, py: float) -> float:
            return w1 / h * math.hypot(max(gx0 - px, px - gx1, 0.0), max(gy0 - py, py - gy1, 0.0))

        # heap: (key, order, state, cost, x, y, k, angle index, node),
        # node = (parent node, angle, flight)
        heap = [(0.0, 0, None, 0.0, float(x), float(y), k0, -1, None)]
        settled, order, best, arrivals = set(), 1, math.inf, []
        while heap and len(settled) < _MAX_SETTLED:
            key, _, st, c, px, py, k, a, node = heapq.heappop(heap)
            if st in settled:
                continue
            if key > best + slack:
                break
            settled.add(st)
            ux, uy = units[k]
            t = 0.0 if (bumped and st is None) else cast(px, py, ux, uy)
            if math.isinf(t):
                return []
            D = 0.0 if t <= BUMP_RANGE else drive_distance(t)
            if k == gk and min(px, px + D * ux) <= gx1 and max(px, px + D * ux) >= gx0 and \
                    min(py, py + D * uy) <= gy1 and max(py, py + D * uy) >= gy0:
                _, p, tt, depth = chords(cs, [[px, py]], [[ux, uy]], [D])
                for pi, ti, di in zip(p.tolist(), tt.tolist(), depth.tolist()):
                    if pi == gp and di >= nav.min_depth:
                        arrivals.append((c + w1 * ti / h, len(arrivals), node, ti))
                        best = min(best, c + w1 * ti / h)
            lx, ly = px + D * ux, py + D * uy
            lb = bin_of(lx, ly)
            hb = bound(lx, ly)
            for b in range(m):
                k2 = (k + steps[b]) % K
                tgt = (lb, k2, b)
                if tgt in settled:
                    continue
                c2 = c + w1 * D / h + (first_bump if a < 0 else (w1 if a == b else w2))
                heapq.heappush(heap, (c2 + hb, order, tgt, c2, lx, ly, k2, b,
                                      (node, nav.angles[b], D)))
                order += 1
        out: dict = {}
        for cost, _, node, final in sorted(arrivals):
            if cost > best + slack:
                break
            angles, flights = [], []
            while node is not None:
                node, ang, fl = node
                angles.append(ang)
                flights.append(fl)
            key = tuple(reversed(angles))
            if key not in out:
                out[key] = Candidate(key, tuple(reversed(flights)), float(final), cost)
        return list(out.values())

    # ------------------------------------------------------------------ scoring
    def score(self, pos, heading, angles, rng: np.random.Generator,
              bumped: bool = False) -> float:
        """Estimated success of flying (not when ``bumped``: at a contact), then turning by
        each angle and flying, then the best final drive, for equally weighted particles
        (pos (n, 2), heading (n,) [deg]) under the declared noise.
        """
        caster = self.nav.caster
        pos, head = np.array(pos, dtype=float), np.array(heading, dtype=float)
        s = self.cfg.turn_spread_deg
        for j, a in enumerate(angles):
            if not (bumped and j == 0):
                D, u, _ = _flights(caster, pos, head, bearings=False)
                pos = pos + D[:, None] * u
            head = head + a + (rng.normal(0.0, s, len(head)) if s > 0 else 0.0)
        return self.final(pos, head, np.full(len(head), 1.0 / len(head)))[1]

    def final(self, pos, heading, w) -> tuple[float, float]:
        """(drive [m], belief mass in the goal cell) of the best final drive on the current
        flight of weighted particles.
        """
        pos, heading = np.asarray(pos, dtype=float), np.asarray(heading, dtype=float)
        D, _, _ = _flights(self.nav.caster, pos, heading, bearings=False)
        return final_drive(pos, heading, D, w, self.box, self.goal_heading,
                           self.cells.delta_deg, self.cfg.margin_m)

    def heading_offset(self, belief: ParticleFilter) -> float:
        """[deg] the belief's mean heading offset ε̄ from the Δ grid (the weighted circular
        mean of θ − kΔ on the circle of period Δ), in [−Δ/2, Δ/2].
        """
        d = self.cells.delta_deg
        a = np.radians(belief.heading * (360.0 / d))
        m = math.atan2(float(belief.weights @ np.sin(a)), float(belief.weights @ np.cos(a)))
        return math.degrees(m) * d / 360.0

    def choose(self, belief: ParticleFilter, rng: np.random.Generator,
               keep: tuple = (), bumped: bool = False, shift: float = 0.0) -> list[Candidate]:
        """Scored candidate plans from the belief, best first (empty: no particle planned
        from reaches the goal). Planned from the heaviest particle and ``votes`` − 1 drawn by
        weight (distinct poses only); ``keep``, the rest of the previous choice's angles, is
        a candidate too (cost +inf: it loses ties). Each distinct angle sequence is scored by
        :meth:`score` on ``eval_particles`` drawn from the belief. Ties keep the cheaper plan.
        ``bumped``: the robot is at a contact (plans start with a turn); ``shift`` [deg]: the
        next turn is commanded ``shift`` short of its angle (heading correction, §20), so
        plans and scores see every heading less ``shift``.
        """
        cfg = self.cfg
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
        if keep and tuple(keep) not in plans:
            plans[tuple(keep)] = Candidate(tuple(keep), (), float("nan"), math.inf)
        if not plans:
            return []
        epos, ehead = belief.sample(cfg.eval_particles)
        scored = [Candidate(c.angles, c.flights, c.final_m, c.cost,
                            self.score(epos, ehead - shift, c.angles, rng, bumped))
                  for c in plans.values()]
        scored.sort(key=lambda c: (-round(c.p_success, 9), c.cost))
        return scored
