"""The particle filter of feedback navigation (docs/model.md §22): a belief over the robot's
pose as weighted particles, updated by the readings a bump-and-clock robot has (the flight's
distance by the clock, the bumper side) under the exact flights of the motion layer.

Re-exported by :mod:`planners.navigation.feedback`, which adds the decision rule; see there for an
example.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.special import ndtr

from envs import Environment, UserError
from envs.contact import contact_flights
from envs.motion import (
    BUMP_RANGE,
    CENTRE_ZONE_DEG,
    ContactParams,
    casters,
    drive_distance,
    unit,
)

__all__ = ["FeedbackConfig", "FlightUpdate", "ParticleFilter", "side_of", "flights", "landings",
           "SIDES"]

SIDES = ("both", "left", "right")
"""Bumper readings: both switches, the left one only, the right one only."""


# ============================================================================ configuration
@dataclass(frozen=True)
class FeedbackConfig:
    """Parameters of the filter and the decision rule (docs/model.md §22).

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
    edge_guard : float         plans avoid flights that bump at once when turned by ± this
                               many turn spreads (knife edges along a touched wall; 0: off)
    final_min : float          after the last turn the robot stops in the goal cell only
                               when the belief's mass there is at least this; else it flies
                               on to the next bump and decides again (0: whenever any mass
                               does, the rule before)
    correct_heading : bool     extension, off by default: command each turn as its angle
                               less the belief's mean heading offset from the Δ grid
    guided : bool              off by default: searches from a pose are guided by the cost
                               to go of the contact-state graph (§22), not by §15's bound
    reference : bool           the straightforward search (unguided) and scoring instead of
                               the fast ones (for benchmarks and tests)
    contact : ContactParams or None
        the body's contact rule (docs/model.md §23) in the filter's motion model, the plan
        search's flights and the scores: a flight whose contact lies outside the bumper arc
        slides on to its bump, and only contacts inside the arc press the bumper. None
        (default): the front-half bumper (§22 as before, bitwise)
    """

    particles: int = 300
    turn_sigma_deg: float = 0.0
    sigma_floor_deg: float = 0.0
    dist_sigma_m: float = 0.01
    dist_sigma_rel: float = 0.01
    centre_zone_deg: float = CENTRE_ZONE_DEG
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
    edge_guard: float = 2.0
    final_min: float = 0.5
    correct_heading: bool = False
    guided: bool = False
    reference: bool = False
    contact: ContactParams | None = None

    def __post_init__(self) -> None:
        for name in ("particles", "votes", "per_pose", "eval_particles"):
            v = getattr(self, name)
            if int(v) != v or v < 1:
                raise UserError(f"feedback {name} must be a positive whole number, got {v}.")
        for name in ("turn_sigma_deg", "sigma_floor_deg", "dist_sigma_m", "dist_sigma_rel", "slack",
                     "centre_zone_deg", "side_blur_deg", "side_floor", "reinit_sigma_deg",
                     "margin_m", "edge_guard"):
            v = float(getattr(self, name))
            if not (math.isfinite(v) and v >= 0):
                raise UserError(f"feedback {name} must be a non-negative number, got {v}.")
        if self.dist_sigma_m <= 0:
            raise UserError("feedback dist_sigma_m must be positive.")
        if not 0 <= self.final_min <= 1:
            raise UserError("feedback final_min must lie in [0, 1].")
        if not 0 < self.resample_ess <= 1:
            raise UserError("feedback resample_ess must lie in (0, 1].")
        if self.contact is not None and not isinstance(self.contact, ContactParams):
            raise UserError(f"feedback contact must be a ContactParams or None, got "
                            f"{self.contact!r}.")

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


def flights(caster, pos, heading_deg, bearings: bool = True):
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


def landings(caster, pos, heading_deg, contact: ContactParams | None, bearings: bool = True):
    """Flights of poses to their bump under a contact rule (docs/model.md §22, §23).

    Returns (clock [m], end (n, 2) [m], bearings (n, F) [deg] or None, slid (n,) bool or
    None, straight [m]): ``straight`` is :func:`flights`' drive to the first contact and
    ``clock`` the clock length to the bump, where the robot ends (``end``). With a contact
    rule, a flight whose first contact lies outside the bumper arc ±(90° − β) slides on
    (:func:`envs.contact.contact_flights`, ``slid``), and its bearings are those at the
    bump; bearings outside the arc are NaN (they press no switch). ``contact`` None: the
    front-half bumper, bitwise :func:`flights` (clock = straight, slid None).
    """
    pos = np.asarray(pos, dtype=float).reshape(-1, 2)
    D, u, beta = flights(caster, pos, heading_deg, bearings)
    if contact is None:
        return D, pos + D[:, None] * u, beta, None, D
    head = np.broadcast_to(np.asarray(heading_deg, dtype=float).reshape(-1), (len(pos),))
    # resampled copies share a pose: slide each distinct (x, y, heading) once
    _, first, inv = np.unique(np.column_stack([pos, head]), axis=0, return_index=True,
                              return_inverse=True)
    inv = inv.reshape(-1)
    fl = contact_flights(caster, pos[first], u[first], D[first], contact)
    slid = np.zeros(len(first), dtype=bool)
    slid[np.fromiter(fl.legs, np.int64, len(fl.legs))] = True
    clock, end, slid = fl.clock[inv], fl.end[inv], slid[inv]
    if beta is not None:
        arc = 90.0 - contact.beta_deg
        if slid.any():
            beta = beta.copy()
            beta[slid] = flights(caster, end[slid], head[slid])[2]
        with np.errstate(invalid="ignore"):
            beta = np.where(np.abs(beta) <= arc, beta, np.nan)
    return clock, end, beta, slid, D


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
    """A belief over the robot's pose as weighted particles (docs/model.md §22).

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
        D, end, beta, _, _ = landings(self.caster, self.pos, self.heading, self.cfg.contact)
        ll, ok = self._loglik(d, side, D, beta)
        ok &= self.w > 0
        consistent, stage = int(ok.sum()), 0
        if consistent:
            with np.errstate(divide="ignore"):
                logw = np.log(self.w) + ll
            pos, head = end, self.heading
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
        D, end, beta, _, _ = landings(self.caster, pos0, head0, self.cfg.contact)
        ll, ok = self._loglik(d, side, D, beta)
        if ok.any():
            return 1, end, head0 % 360.0, np.where(ok, ll, -np.inf)
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
        D, end, beta, _, _ = landings(self.caster, pts, head, self.cfg.contact)
        ll, ok = self._loglik(d, side, D, beta)
        return 2, end, head, np.where(ok, ll, -np.inf) if ok.any() else ll

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
