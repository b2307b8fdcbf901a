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

from envs import Environment, UserError
from envs.motion import casters, unit

from ...measures import wrap180
from .config import FeedbackConfig
from .observe import SIDES, flights, landings, side_of, side_probs

__all__ = ["FeedbackConfig", "FlightUpdate", "ParticleFilter", "side_of", "side_probs", "flights",
           "landings", "SIDES"]


# ============================================================================ the filter
@dataclass(frozen=True)
class FlightUpdate:
    """What one flight reading did to the belief, and the filter's health after it.

    Attributes
    ----------
    distance : float     the reading [m]
    side : str           one of :data:`SIDES`, "none" (a bump without a closed switch: no
                         side reading) or "missed" (no bump before the timeout)
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
        self.factor, self.offset = self._prior_turns(len(poses))

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
        self.factor, self.offset = self._prior_turns(n)
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
        """Predict a commanded spin by ``angle_deg`` [deg] (CCW positive, the body spins as
        told: :meth:`command_for`): each particle turns by its own f·φ + b plus the declared
        noise.
        """
        s = self.cfg.turn_spread_deg
        noise = self.rng.normal(0.0, s, self.n) if s > 0 else 0.0
        self.heading = (self.heading + self.factor * float(angle_deg) + self.offset
                        + noise) % 360.0

    def turn_estimate(self) -> tuple[float, float, float, float]:
        """(factor, its std, offset [deg], its std): the belief's weighted estimate of the
        turn's constant factor f and offset b.
        """
        w = self.w
        f, b = float(w @ self.factor), float(w @ self.offset)
        return (f, math.sqrt(max(float(w @ (self.factor - f) ** 2), 0.0)), b,
                math.sqrt(max(float(w @ (self.offset - b) ** 2), 0.0)))

    @property
    def turns_uncertain(self) -> bool:
        """True when the declared turns have a factor or offset (unknown, or known but not
        1 and 0): commands then correct for the estimate (:meth:`command_for`).
        """
        c = self.cfg
        return not (c.turn_scale == 0 and c.turn_bias_deg == 0 and c.turn_factor == 1
                    and c.turn_offset_deg == 0)

    def command_for(self, angle_deg: float) -> float:
        """The spin to command for an actual turn of ``angle_deg`` [deg], the shorter way
        (docs/model.md §21), under the estimated factor and offset: (wrap180(φ) − b̂) / f̂
        (wrap180(φ) itself when nothing is unknown or off).
        """
        if not self.turns_uncertain:
            return wrap180(float(angle_deg))
        f, _, b, _ = self.turn_estimate()
        return (wrap180(float(angle_deg)) - b) / f

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
        p_read = ps[:, side] if side is not None else np.ones(len(D))     # no switch read
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
        # a body may report a bump with no switch closed (a glancing stop): no side reading
        d = float(distance)
        side = side_of(left, right) if (left or right) else None
        if self.fresh:                  # an unknown start: propose poses the reading explains
            self._propose_contacts(d)
        D, end, beta, _, _, h_end = landings(self.caster, self.pos, self.heading,
                                             self.cfg.contact)
        ll, ghost, ok = self._loglik(d, side, D, beta)
        ok &= self.w > 0
        stop = self.pos + np.minimum(d, D)[:, None] * unit(self.heading)
        # which branch it took (a particle the reading rules out, ll = −inf, took neither)
        with np.errstate(invalid="ignore"):
            phantom = np.log(self.rng.random(self.n)) < ghost - ll
        pos = np.where(phantom[:, None], stop, end)
        head = np.where(phantom, self.heading, h_end)
        return self._posterior(d, "none" if side is None else SIDES[side], ll, pos, head,
                               int(ok.sum()),
                               lambda p, h: self._loglik(d, side, *self._cast(p, h))[0])

    def missed(self, distance: float) -> FlightUpdate:
        """Update with a drive that read no bump for ``distance`` [m] (the timeout): with the
        declared rate ``p_miss`` the robot missed its bump and pushed on against the wall,
        where it is now; a particle whose flight is longer stopped mid-flight, as a drive
        does. The reading is nearly uninformative; it never zeroes the belief.
        """
        d, self.fresh = float(distance), False
        D, end, _, _, _, h_end = landings(self.caster, self.pos, self.heading,
                                          self.cfg.contact, bearings=False)
        ll = self._missed_loglik(d, D)
        pos = np.where((D <= d)[:, None], end, self.pos + d * unit(self.heading))
        head = np.where(D <= d, h_end, self.heading)
        return self._posterior(d, "missed", ll, pos, head, self.n,
                               lambda p, h: self._missed_loglik(d, self._cast(p, h)[0]))

    def _missed_loglik(self, d: float, D) -> np.ndarray:
        cfg = self.cfg
        return np.where(D <= d, math.log(max(cfg.p_miss, 1e-300)),
                        math.log1p(-(cfg.p_phantom + cfg.p_miss)))

    def _cast(self, pos, head):
        D, _, beta, _, _, _ = landings(self.caster, pos, head, self.cfg.contact)
        return D, beta

    def _posterior(self, d: float, side: str, ll, pos, head, consistent: int, recovery_ll):
        """Weigh by ``ll`` the particles that flew to ``pos`` with the headings ``head``
        they bumped with, mix in a re-initialised component when the reading is surprising,
        resample when the ESS is low; the :class:`FlightUpdate`.
        """
        with np.errstate(divide="ignore"):
            logw = np.log(self.w) + ll
        top = float(logw.max())
        log_mb = top + math.log(float(np.exp(logw - top).sum()))      # Σ w·L
        stage, mixed = 0, 0.0
        best = self._best_loglik(d) if side != "missed" else 0.0
        if self.cfg.p_lost > 0 and log_mb < best + math.log(self.cfg.surprise):
            rec = self._recovery(recovery_ll, best + math.log(self.cfg.surprise))
            if rec is not None:
                stage, rpos, rhead, rll, rfactor, roffset = rec
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
                self.factor = np.concatenate([self.factor, rfactor])
                self.offset = np.concatenate([self.offset, roffset])
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
        log-likelihoods, turn factors, turn offsets).
        """
        n = self.cfg.particles
        idx = self.rng.choice(self.n, size=4 * n, p=self.w)
        head0 = self.heading[idx] + self.rng.normal(0.0, self.cfg.reinit_sigma_deg, 4 * n)
        pos0, factor, offset = self.pos[idx], self.factor[idx], self.offset[idx]
        ll, stage = loglik(pos0, head0), 1
        if float(ll.max()) < fits:
            poses = self.uniform_poses(8 * n)
            pos0, head0 = poses[:, :2], poses[:, 2]
            factor, offset = self._prior_turns(len(poses))
            ll, stage = loglik(pos0, head0), 2
        D, end, _, _, _, head0 = landings(self.caster, pos0, head0, self.cfg.contact,
                                          bearings=False)
        return stage, end, head0 % 360.0, ll, factor, offset

    def _prior_turns(self, n: int) -> tuple[np.ndarray, np.ndarray]:
        """``n`` turn factors and offsets [deg] drawn from the declared ranges."""
        c = self.cfg
        f = np.full(n, c.turn_factor) + (self.rng.uniform(-c.turn_scale, c.turn_scale, n)
                                         if c.turn_scale > 0 else 0.0)
        b = np.full(n, c.turn_offset_deg) + (self.rng.uniform(-c.turn_bias_deg, c.turn_bias_deg, n)
                                             if c.turn_bias_deg > 0 else 0.0)
        return f, b

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
        self.factor, self.offset = self.factor[idx].copy(), self.offset[idx].copy()
        self.w = np.full(n, 1.0 / n)
        cfg = self.cfg
        if cfg.turn_scale > 0:          # regularised: copies of one factor spread a little
            lo, hi = cfg.turn_factor - cfg.turn_scale, cfg.turn_factor + cfg.turn_scale
            self.factor = np.clip(self.factor + self.rng.normal(0.0, cfg.turn_scale / 50, n),
                                  lo, hi)
        if cfg.turn_bias_deg > 0:
            b0, db = cfg.turn_offset_deg, cfg.turn_bias_deg
            lo, hi = b0 - db, b0 + db
            self.offset = np.clip(self.offset + self.rng.normal(0.0, cfg.turn_bias_deg / 50, n),
                                  lo, hi)

    def sample(self, n: int, turns: bool = False):
        """``n`` poses drawn by weight (systematic): positions (n, 2), headings (n,) [deg];
        with ``turns`` also their turn factors and offsets [deg].
        """
        c = np.cumsum(self.w)
        c[-1] = 1.0
        idx = np.searchsorted(c, (self.rng.random() + np.arange(n)) / n)
        if turns:
            return (self.pos[idx].copy(), self.heading[idx].copy(), self.factor[idx].copy(),
                    self.offset[idx].copy())
        return self.pos[idx].copy(), self.heading[idx].copy()
