"""The particle filter of feedback navigation (docs/model.md §15): a belief over the robot's
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

__all__ = ["FeedbackConfig", "FlightUpdate", "ParticleFilter", "side_of", "side_probs", "flights",
           "landings", "SIDES"]

SIDES = ("both", "left", "right")
"""Bumper readings: both switches, the left one only, the right one only."""


# ============================================================================ configuration
@dataclass(frozen=True)
class FeedbackConfig:
    """Parameters of the filter and the decision rule (docs/model.md §15).

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
    side_union : float         in a corner (several walls touched), the weight of the
                               twin's convention (every switch any wall selects closes)
                               against one wall's reading (a body that reads one point)
    p_side : float             the declared rate of wrong bumper-side readings: a reading is
                               one of the two others with this probability (a real bumper's
                               switches in a corner are no more predictable than either
                               convention); no side reading can zero the belief
    p_phantom : float          the declared rate of phantom bumps: the bumper closes with no
                               wall, the robot stopped mid-flight (the reading is uniform
                               over the flight, the side any of the three)
    p_miss : float             the declared rate of missed bumps: the robot pushed on
                               against the wall until the drive's timeout
    p_lost : float             prior probability that the belief has lost track at a
                               reading: the weight of the re-initialised component mixed in
                               (the posterior's share is p_lost·m_r / ((1 − p_lost)·m_b +
                               p_lost·m_r), m the readings' marginal likelihoods)
    surprise : float           a re-initialised component is tried only when the belief's
                               marginal likelihood of a reading is below this fraction of
                               the best possible one
    consistent_z : float       a particle counts as fitting a reading (reported, not used to
                               weigh) within this many σ_d and with the side it predicts
    resample_ess : float       resample when ESS < this · n
    reinit_sigma_deg : float   [deg] heading spread of the local re-initialisation
    global_particles : int     particles of a belief that starts anywhere (unknown start),
                               kept until it has localized
    localized_mass : float     the belief has localized when this share of its weight lies
                               within h/2 of its mean position and Δ/2 of its mean heading
    jitter_deg, jitter_m : float
        while an unknown start has not localized, every resampled copy is moved by
        N(0, jitter_deg²) in heading and N(0, jitter_m²) in position (a regularised filter:
        copies of one pose explore around it instead of staying identical)
    votes : int                poses planned from after every bump
    slack : float              plans within this of the cheapest (§13's cost) are candidates
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
                               to go of the contact-state graph (§15), not by §13's bound
    reference : bool           the straightforward search (unguided) and scoring instead of
                               the fast ones (for benchmarks and tests)
    contact : ContactParams or None
        the body's contact rule (docs/model.md §9) in the filter's motion model, the plan
        search's flights and the scores: a flight whose contact lies outside the bumper arc
        slides on to its bump, and only contacts inside the arc press the bumper. None
        (default): the front-half bumper (§15 as before, bitwise)
    """

    particles: int = 300
    turn_sigma_deg: float = 0.0
    sigma_floor_deg: float = 0.0
    dist_sigma_m: float = 0.01
    dist_sigma_rel: float = 0.01
    centre_zone_deg: float = CENTRE_ZONE_DEG
    side_blur_deg: float = 1.0
    side_union: float = 0.5
    p_side: float = 0.05
    p_phantom: float = 0.01
    p_miss: float = 0.01
    p_lost: float = 0.01
    surprise: float = 0.01
    consistent_z: float = 5.0
    resample_ess: float = 0.5
    reinit_sigma_deg: float = 10.0
    global_particles: int = 3000
    localized_mass: float = 0.9
    jitter_deg: float = 1.0
    jitter_m: float = 0.005
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
        for name in ("particles", "votes", "per_pose", "eval_particles", "global_particles"):
            v = getattr(self, name)
            if int(v) != v or v < 1:
                raise UserError(f"feedback {name} must be a positive whole number, got {v}.")
        for name in ("turn_sigma_deg", "sigma_floor_deg", "dist_sigma_m", "dist_sigma_rel", "slack",
                     "centre_zone_deg", "side_blur_deg", "reinit_sigma_deg", "margin_m",
                     "edge_guard", "jitter_deg", "jitter_m"):
            v = float(getattr(self, name))
            if not (math.isfinite(v) and v >= 0):
                raise UserError(f"feedback {name} must be a non-negative number, got {v}.")
        if self.dist_sigma_m <= 0:
            raise UserError("feedback dist_sigma_m must be positive.")
        if not 0 <= self.final_min <= 1:
            raise UserError("feedback final_min must lie in [0, 1].")
        if not 0 < self.localized_mass <= 1:
            raise UserError("feedback localized_mass must lie in (0, 1].")
        for name in ("p_side", "p_phantom", "p_miss", "p_lost", "surprise", "side_union"):
            v = float(getattr(self, name))
            if not 0 <= v < 1:
                raise UserError(f"feedback {name} must lie in [0, 1), got {v}.")
        if self.p_side > 2 / 3:
            raise UserError("feedback p_side above 2/3 would make a wrong side likelier than "
                            "the right one.")
        if self.p_phantom + self.p_miss >= 1:
            raise UserError("feedback p_phantom + p_miss must stay below 1.")
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
    """Flights of poses to their bump under a contact rule (docs/model.md §15, §9).

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


def side_probs(beta, cfg: FeedbackConfig) -> np.ndarray:
    """(n, 3) probability of each reading of :data:`SIDES` given the touched features'
    bearings (n, F) [deg] (NaN: not touched).

    A feature at bearing β closes the left switch when β >= −zone and the right one when
    β <= zone, blurred by a normal CDF of width ``side_blur_deg``. Where several features
    are touched (a corner) bodies differ: the twin closes every switch any of them selects
    (the union), a body whose switches read one wall point the switches of one of them. The
    model weighs the two conventions ``side_union`` : 1 − ``side_union`` (one touched
    feature at random for the second); then a wrong reading with probability ``p_side``,
    spread evenly over the two others: (1 − p_side)·p + p_side·(1 − p)/2.
    """
    s = max(cfg.side_blur_deg, 1e-9)
    z = cfg.centre_zone_deg
    with np.errstate(invalid="ignore"):
        fl = ndtr((beta + z) / s)                      # (n, F): NaN where not touched
        fr = ndtr((z - beta) / s)
        left = np.nan_to_num(np.nanmax(fl, axis=1, initial=0.0))
        right = np.nan_to_num(np.nanmax(fr, axis=1, initial=0.0))
        touched = np.isfinite(beta).sum(axis=1)
        one = np.stack([np.nansum(fl * fr, axis=1), np.nansum(fl * (1 - fr), axis=1),
                        np.nansum((1 - fl) * fr, axis=1)], axis=1)
    p = np.column_stack([left * right, left * (1 - right), (1 - left) * right])
    p = cfg.side_union * p + (1 - cfg.side_union) * one / np.maximum(touched, 1)[:, None]
    total = p.sum(1, keepdims=True)
    p = np.where(total > 0, p / np.maximum(total, 1e-300), 1.0 / 3)    # nothing touched
    return (1 - cfg.p_side) * p + cfg.p_side * (1 - p) / 2


# ============================================================================ the filter
@dataclass(frozen=True)
class FlightUpdate:
    """What one flight reading did to the belief, and the filter's health after it.

    Attributes
    ----------
    distance : float     the reading [m]
    side : str           one of :data:`SIDES`, or "missed" (no bump before the timeout)
    consistent : int     particles that fitted the reading (within ``consistent_z`` σ_d and
                         with the side they predict), before any re-initialisation
    reinit : int         0: no re-initialised component mixed in; 1: one drawn around the
                         previous belief (headings widened); 2: one drawn over the room
    ess : float          effective sample size after the update (before resampling)
    resampled : bool
    loglik : float       log of the reading's marginal likelihood under the belief before
                         it (the mean of every particle's likelihood, weighted) [log 1/m]
    mixed : float        the re-initialised component's share of the posterior (0: none)
    lost : bool          that share is above one half: the belief had lost track
    """

    distance: float
    side: str
    consistent: int
    reinit: int
    ess: float
    resampled: bool
    loglik: float = 0.0
    mixed: float = 0.0
    lost: bool = False


class ParticleFilter:
    """A belief over the robot's pose as weighted particles (docs/model.md §15).

    Parameters
    ----------
    env : Environment
    config : FeedbackConfig
    rng : numpy.random.Generator   every draw of the filter (turn noise, resampling)
    poses : (n, 3) array-like, optional
        Initial particles (x [m], y [m], heading [deg]), equal weights.
    start : (x, y, heading), optional
        Alternatively the known start pose: ``config.particles`` copies of it.
    region : (x0, y0, x1, y1), optional
        With neither: the start is unknown, anywhere in the free space (within this box
        [m] when given) with any heading: ``config.global_particles`` poses drawn uniformly,
        kept until the belief has localized (:meth:`localized`).

    Attributes
    ----------
    size : int       the particle count the filter resamples to: ``global_particles`` while
                     an unknown start has not localized, then ``particles``
    """

    def __init__(self, env: Environment, config: FeedbackConfig, rng: np.random.Generator,
                 poses=None, start=None, region=None) -> None:
        self.env, self.cfg, self.rng = env, config, rng
        self.caster = casters(env)[0]
        self.size = config.particles
        self.region = None if region is None else tuple(float(v) for v in region)
        self.fresh = False                # an unknown start before its first reading
        if poses is None and start is None:
            poses = self.uniform_poses(config.global_particles, region)
            self.size, self.fresh = config.global_particles, True
        elif poses is None:
            poses = np.tile(np.asarray(start, dtype=float).reshape(1, 3), (config.particles, 1))
        poses = np.asarray(poses, dtype=float).reshape(-1, 3)
        self.pos = poses[:, :2].copy()
        self.heading = poses[:, 2] % 360.0
        self.w = np.full(len(poses), 1.0 / len(poses))

    def uniform_poses(self, n: int, region=None) -> np.ndarray:
        """(n, 3) poses uniform over the robot's free space (within the box ``region``
        (x0, y0, x1, y1) [m] when given) and uniform headings [deg].
        """
        x0, y0, x1, y1 = self.env.bounds if region is None else (float(v) for v in region)
        if not (x1 > x0 and y1 > y0):
            raise UserError(f"the start region {region} is not a box (x0, y0, x1, y1) with "
                            "x1 > x0 and y1 > y0.")
        pts = np.empty((0, 2))
        for _ in range(200):
            cand = self.rng.uniform([x0, y0], [x1, y1], size=(4 * n, 2))
            pts = np.vstack([pts, cand[self.env.points_free(cand)]])
            if len(pts) >= n:
                break
        if len(pts) == 0:
            where = self.env.name if region is None else f"the start region {tuple(region)}"
            raise UserError(f"{where} has no free space for the robot.")
        pts = pts[:n] if len(pts) >= n else pts[self.rng.integers(0, len(pts), n)]
        return np.column_stack([pts, self.rng.uniform(0.0, 360.0, n)])

    def _propose_contacts(self, d: float) -> None:
        """The first reading of an unknown start: instead of weighing uniform poses (nearly
        all of which the reading rules out), draw the flight's end: contact points uniform
        along the C-space boundary and headings uniform over the half circle into the wall,
        started ``d`` [m] back; weighted by cos(incidence), the density with which uniform
        starts reach the boundary there (and 0 outside the start region).
        """
        from ...boundary import Boundary
        n = self.size
        bd = Boundary(self.env, 0.03)
        length = bd.ring_bin_length[bd.ring_of_bin]
        bins = self.rng.choice(bd.n_bins, n, p=length / length.sum())
        pts, seg = bd.points(bins, self.rng.random(n), return_segment=True)
        inward = bd.seg_inward[seg]
        into = np.degrees(np.arctan2(-inward[:, 1], -inward[:, 0]))
        head = into + self.rng.uniform(-90.0, 90.0, n)
        u = unit(head)
        cos_inc = np.maximum(-(u * inward).sum(1), 0.0)
        start = pts - d * u
        with np.errstate(divide="ignore"):
            logw = np.log(cos_inc)
        if self.region is not None:
            x0, y0, x1, y1 = self.region
            inside = ((start[:, 0] >= x0) & (start[:, 0] <= x1) & (start[:, 1] >= y0)
                      & (start[:, 1] <= y1))
            logw = np.where(inside, logw, -np.inf)
        w = np.exp(logw - logw.max()) if np.isfinite(logw).any() else np.ones(n)
        self.pos, self.heading, self.w = start, head % 360.0, w / w.sum()
        self.fresh = False

    def localized(self, radius: float, heading_tol_deg: float) -> bool:
        """Whether ``localized_mass`` of the weight lies within ``radius`` [m] of the
        weighted mean position and ``heading_tol_deg`` of the circular mean heading.
        """
        w = self.w
        mean = w @ self.pos
        th = np.radians(self.heading)
        mh = math.degrees(math.atan2(float(w @ np.sin(th)), float(w @ np.cos(th))))
        near = (np.hypot(*(self.pos - mean).T) <= radius) & \
            (np.abs((self.heading - mh + 180.0) % 360.0 - 180.0) <= heading_tol_deg)
        return float(w[near].sum()) >= self.cfg.localized_mass

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

    def _sigma_d(self, d: float) -> float:
        return self.cfg.dist_sigma_m + self.cfg.dist_sigma_rel * d

    def _loglik(self, d: float, side: int, D, beta):
        """Per particle: (log-likelihood of a bump reading of ``d`` [m] and ``side``, log of
        its phantom-bump part, fits): a real bump at the particle's contact (Gaussian
        distance, the side model with its ``p_side``), with weight 1 − p_phantom − p_miss;
        or a phantom bump (p_phantom: the distance uniform over the flight, any side).
        """
        cfg = self.cfg
        sd = self._sigma_d(d)
        z = (d - D) / sd
        ps = side_probs(beta, cfg)
        p_read = ps[:, side]
        real = (math.log1p(-(cfg.p_phantom + cfg.p_miss)) - 0.5 * z * z
                - math.log(sd * math.sqrt(2 * math.pi)) + np.log(p_read))
        with np.errstate(divide="ignore"):
            ghost = np.where(d < D, math.log(cfg.p_phantom / 3) - np.log(np.maximum(D, 1e-12)),
                             -np.inf) if cfg.p_phantom > 0 else np.full(len(D), -np.inf)
        ll = np.logaddexp(real, ghost)
        ok = (np.abs(z) <= cfg.consistent_z) & (p_read >= ps.max(axis=1) - 1e-12)
        return ll, ghost, ok

    def _best_loglik(self, d: float) -> float:
        """The largest log-likelihood any pose can give a bump reading of ``d`` [m]."""
        sd = self._sigma_d(d)
        return (math.log1p(-(self.cfg.p_phantom + self.cfg.p_miss)) + math.log1p(-self.cfg.p_side)
                - math.log(sd * math.sqrt(2 * math.pi)))

    def flight(self, distance: float, left: bool, right: bool) -> FlightUpdate:
        """Update with one flight that ended in a bump after ``distance`` [m] with the
        bumper reading (left, right) (docs/model.md §15): every particle flies to its exact
        contact, or with the declared phantom-bump rate stops where the reading says; no
        reading zeroes the belief. When the reading is surprising (its marginal likelihood
        below ``surprise`` × the best possible), a re-initialised component is mixed in with
        the share Bayes gives it under the prior ``p_lost``.
        """
        d, side = float(distance), side_of(left, right)
        if self.fresh:                  # an unknown start: propose poses the reading explains
            self._propose_contacts(d)
        D, end, beta, _, _ = landings(self.caster, self.pos, self.heading, self.cfg.contact)
        ll, ghost, ok = self._loglik(d, side, D, beta)
        ok &= self.w > 0
        stop = self.pos + np.minimum(d, D)[:, None] * unit(self.heading)
        phantom = np.log(self.rng.random(self.n)) < ghost - ll      # which branch it took
        pos = np.where(phantom[:, None], stop, end)
        return self._posterior(d, SIDES[side], ll, pos, int(ok.sum()),
                               lambda p, h: self._loglik(d, side, *self._cast(p, h))[0])

    def missed(self, distance: float) -> FlightUpdate:
        """Update with a drive that read no bump for ``distance`` [m] (the timeout): with the
        declared rate ``p_miss`` the robot missed its bump and pushed on against the wall,
        where it is now; a particle whose flight is longer stopped mid-flight, as a drive
        does. The reading is nearly uninformative; it never zeroes the belief.
        """
        d, self.fresh = float(distance), False
        D, end, _, _, _ = landings(self.caster, self.pos, self.heading, self.cfg.contact,
                                   bearings=False)
        ll = self._missed_loglik(d, D)
        pos = np.where((D <= d)[:, None], end, self.pos + d * unit(self.heading))
        return self._posterior(d, "missed", ll, pos, self.n,
                               lambda p, h: self._missed_loglik(d, self._cast(p, h)[0]))

    def _missed_loglik(self, d: float, D) -> np.ndarray:
        cfg = self.cfg
        return np.where(D <= d, math.log(max(cfg.p_miss, 1e-300)),
                        math.log1p(-(cfg.p_phantom + cfg.p_miss)))

    def _cast(self, pos, head):
        D, _, beta, _, _ = landings(self.caster, pos, head, self.cfg.contact)
        return D, beta

    def _posterior(self, d: float, side: str, ll, pos, consistent: int, recovery_ll):
        """Weigh by ``ll``, mix in a re-initialised component when the reading is surprising,
        resample when the ESS is low; the :class:`FlightUpdate`.
        """
        with np.errstate(divide="ignore"):
            logw = np.log(self.w) + ll
        top = float(logw.max())
        log_mb = top + math.log(float(np.exp(logw - top).sum()))      # Σ w·L
        head, stage, mixed = self.heading, 0, 0.0
        best = self._best_loglik(d) if side != "missed" else 0.0
        if self.cfg.p_lost > 0 and log_mb < best + math.log(self.cfg.surprise):
            rec = self._recovery(recovery_ll, best + math.log(self.cfg.surprise))
            if rec is not None:
                stage, rpos, rhead, rll = rec
                log_mr = float(np.logaddexp.reduce(rll)) - math.log(len(rll))
                a = math.log1p(-self.cfg.p_lost) + log_mb
                b = math.log(self.cfg.p_lost) + log_mr
                mixed = float(np.exp(b - np.logaddexp(a, b)))
                # the belief's posterior with weight 1 − mixed, the component's with mixed
                logw = np.concatenate([logw - log_mb + math.log1p(-mixed) if mixed < 1
                                       else np.full(len(logw), -np.inf),
                                       rll - float(np.logaddexp.reduce(rll))
                                       + math.log(max(mixed, 1e-300))])
                pos = np.vstack([pos, rpos])
                head = np.concatenate([head, rhead])
        w = np.exp(logw - logw.max())
        w /= w.sum()
        self.pos, self.heading, self.w = pos, head % 360.0, w
        ess = self.ess
        resampled = ess < self.cfg.resample_ess * self.n or len(w) != self.size
        if resampled:
            self.resample(self.size)
            if self.size == self.cfg.global_particles and self.size != self.cfg.particles:
                self._jitter()
        return FlightUpdate(d, side, consistent, stage, ess, resampled, log_mb, mixed,
                            mixed > 0.5)

    def _recovery(self, loglik, fits: float):
        """A re-initialised component for a surprising reading: ``4n`` poses around the
        belief with headings widened by ``reinit_sigma_deg`` (stage 1); if none of them
        explains the reading (log-likelihood at least ``fits``), ``8n`` poses uniform over
        the free space and all headings (stage 2). Returns (stage, landing poses, headings,
        log-likelihoods).
        """
        n = self.cfg.particles
        idx = self.rng.choice(self.n, size=4 * n, p=self.w)
        head0 = self.heading[idx] + self.rng.normal(0.0, self.cfg.reinit_sigma_deg, 4 * n)
        pos0 = self.pos[idx]
        ll, stage = loglik(pos0, head0), 1
        if float(ll.max()) < fits:
            poses = self.uniform_poses(8 * n)
            pos0, head0 = poses[:, :2], poses[:, 2]
            ll, stage = loglik(pos0, head0), 2
        D, end, _, _, _ = landings(self.caster, pos0, head0, self.cfg.contact, bearings=False)
        return stage, end, head0 % 360.0, ll

    def _jitter(self) -> None:
        """Move every particle by N(0, jitter_m²) per axis and N(0, jitter_deg²) in heading,
        keeping positions that stay in the free space.
        """
        n = self.n
        moved = self.pos + self.rng.normal(0.0, self.cfg.jitter_m, (n, 2))
        ok = self.env.points_free(moved)
        self.pos = np.where(ok[:, None], moved, self.pos)
        self.heading = (self.heading + self.rng.normal(0.0, self.cfg.jitter_deg, n)) % 360.0

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
