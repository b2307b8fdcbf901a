"""Fast-forward of steady motion in a PyBullet world (docs/model.md Appendix C).

A Create 2 that drives straight far from every wall, slides steadily along one, or turns in
place at its commanded rate moves with a constant twist (forward speed and yaw rate) as long
as nothing new touches it: the physics steps of such a stretch only integrate that twist. A
:class:`Coaster` advances the body over such a stretch in one move instead (the pose by the
exact integral of the twist, once the measured motion has been checked to follow it; the
velocities and the wheel joints carried along), so that physics steps are spent where
something happens: starts, stops, approaches to a wall, contacts.

The mechanism is honest only where it is safe, and :class:`FastForward` says where:

- **drives** jump only when the measured motion is steady (speed within ``speed_tol`` of the
  command, yaw rate within ``yaw_rate_tol``) and the body is out of contact (at least
  ``clearance`` from every wall); the jump ends before the body, grown by ``margin``, would
  touch a wall it approaches (an exact capsule ray cast, :class:`envs.motion.WallCaster`,
  which ignores walls the motion leaves or runs parallel to; a wall it approaches nearer
  than ``margin`` already allows no jump), so the last ``margin`` of every approach, the
  contact and the bump are simulated;
- **slides** along one straight wall side (``slides``) jump when the last two sensor
  periods measured the same speed along the side and none across it, and the incidence
  stays inside (0.5°, β − 0.5°), until ``margin`` before the side's end or another wall;
- **turns** (``turns=True``, off by default) run ``turn_steps`` physics steps at a time
  (the spin-up, and any push-off from the wall just bumped) until the wheels and the body
  turn at the commanded rate (within ``yaw_rate_tol``) and the centre moves slower than
  ``speed_tol``, then jump the rest of the spin; the stop and the settling are simulated.
  A disk turning about its own centre sweeps no new area, so a spin never meets a wall it
  did not touch already; but the jump drops the centre's slow push-off from that wall,
  which decides the next bump (docs/model.md Appendix C), so the default simulates turns.

Examples
--------
>>> FastForward().margin
0.01
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from envs import UserError
from envs.motion import WallCaster

__all__ = ["FastForward", "Coaster", "DEFAULT_FAST_FORWARD"]


@dataclass(frozen=True)
class FastForward:
    """Where a :class:`Coaster` may skip physics steps (docs/model.md Appendix C).

    Attributes
    ----------
    margin : float        [m] a drive's jump ends this far before the body would touch a
                          wall it approaches
    clearance : float     [m] a drive jumps only while the body is this far from every wall
                          (out of contact: beyond the 0.1-0.3 mm at which a bump leaves it)
    (the margin is raised to the world's contact breaking distance where that is larger, so
    no wall the body approaches has a contact point during a jump)
    turns : bool          also jump the steady middle of turns in place (default off: the
                          jump drops the push-off of a body spinning at its wall, which
                          decides its next bump; docs/model.md Appendix C)
    slides : bool         also jump steady slides along one straight wall side
    slide_tol : float     [m/s] steady slide: the speed along the wall of the last two polls
                          agrees within this, the speed across it is below it; [rad/s] the
                          yaw rates of the two polls agree within a tenth of it
    turn_steps : int      physics steps a turn runs before it may jump
    speed_tol : float     [m/s] steady: |speed − command| at most this (wheels and body)
    yaw_rate_tol : float  [rad/s] steady: |yaw rate − command| at most this (wheels and body)
    """

    margin: float = 0.01
    clearance: float = 0.0005
    turns: bool = False
    slides: bool = True
    slide_tol: float = 0.001
    turn_steps: int = 3
    speed_tol: float = 0.003
    yaw_rate_tol: float = 0.01

    def __post_init__(self) -> None:
        if not (self.margin > 0 and self.clearance > 0 and self.speed_tol > 0
                and self.slide_tol > 0
                and self.yaw_rate_tol > 0 and int(self.turn_steps) >= 1):
            raise UserError("fast-forward margin and tolerances must be positive and "
                            "turn_steps >= 1.")


DEFAULT_FAST_FORWARD = FastForward()
"""The settings :class:`~bouncesim.robots.pybullet.batch.PyBulletBatch` uses by default."""


def _rot(c: float, s: float, x: float, y: float) -> tuple[float, float]:
    return c * x - s * y, s * x + c * y


class Coaster:
    """Advance steadily moving Create 2 bodies of one PyBullet world without physics steps.

    Parameters
    ----------
    p, kw : the pybullet module and its ``physicsClientId`` keyword dict
    env : Environment      the world's walls
    body_radius : float    [m] collision radius of the bodies
    wheel_radius : float   [m]
    wheel_base : float     [m] distance between the wheels
    settings : FastForward
    contact_distance : float   [m] the world's contact breaking threshold
    """

    def __init__(self, p, kw: dict, env, body_radius: float, wheel_radius: float,
                 wheel_base: float, settings: FastForward,
                 contact_distance: float = 0.02) -> None:
        self.p, self.kw, self.ff = p, kw, settings
        self.clearance = float(settings.clearance)
        self.margin = max(settings.margin, float(contact_distance))
        self.radius = float(body_radius)
        self.wheel_r = float(wheel_radius)
        self.wheel_base = float(wheel_base)
        self.caster = WallCaster(env.wall_segments, self.radius + self.margin)
        self._masks: dict[int, np.ndarray] = {}
        c = self.caster
        self._segs = [tuple(float(v) for v in row)
                      for row in np.column_stack([c.A, c.e, c.L])]

    def near(self, x: float, y: float) -> tuple[float, int]:
        """(gap [m] between the body at (x, y) and the nearest wall, index of the one wall
        segment within ``clearance``, or −1 when none or several are that near).
        """
        best, side, count, lim = math.inf, -1, 0, self.clearance + self.radius
        for k, (ax, ay, ex, ey, length) in enumerate(self._segs):
            rx, ry = x - ax, y - ay
            lam = min(max(rx * ex + ry * ey, 0.0), length)
            d = math.hypot(rx - lam * ex, ry - lam * ey)
            if d < lim:
                count += 1
                side = k
            best = min(best, d)
        return best - self.radius, side if count == 1 else -1

    def free_travel(self, x: float, y: float, ux: float, uy: float) -> float:
        """Distance [m] the body can move from (x, y) along the unit vector (ux, uy) before it
        comes within ``margin`` of a wall it approaches (walls it leaves or runs parallel to
        do not count).
        """
        return self.caster.cast_one(x, y, ux, uy)

    def wheel_twist(self, body: int) -> tuple[float, float]:
        """(forward speed [m/s], yaw rate [rad/s]) the wheel joint rates drive the body at."""
        (_, wl, *_), (_, wr, *_) = self.p.getJointStates(body, [0, 1], **self.kw)
        R = self.wheel_r
        return R * (wl + wr) / 2, R * (wr - wl) / self.wheel_base

    def steady(self, body: int, speed: float, yaw_rate: float) -> bool:
        """True when the wheels turn at the commanded (``speed`` [m/s], ``yaw_rate``
        [rad/s]) and the body follows them (base speed and yaw rate within the tolerances).
        """
        v, w = self.wheel_twist(body)
        (vx, vy, _), (_, _, wz) = self.p.getBaseVelocity(body, **self.kw)
        ff = self.ff
        return (abs(v - speed) <= ff.speed_tol and abs(w - yaw_rate) <= ff.yaw_rate_tol
                and abs(math.hypot(vx, vy) - abs(speed)) <= ff.speed_tol
                and abs(wz - yaw_rate) <= ff.yaw_rate_tol)

    def slide(self, track, speed: float, beta_deg: float):
        """A steady slide along one wall side, from the last three polls, or None.

        Parameters
        ----------
        track : the last three polls' (time [s], x [m], y [m], heading [rad], side index of
                :meth:`near`), oldest first
        speed : commanded drive speed [m/s]
        beta_deg : the bumper's blind incidence [deg] (90° − the arc): a slide keeps its
                   incidence at least 0.5° inside (0, β), so its bump is simulated

        Returns
        -------
        (u [m/s], ux, uy, ω [rad/s], t_max [s]) : speed along the side's unit direction
        (ux, uy) (exactly parallel to it), the mean yaw rate, and how long the slide may be
        advanced: until the body grown by ``margin`` meets another wall or corner ahead (the
        side's own end points excluded: the body passes them beside the side), until its
        foot point comes within ``margin`` of the side's end, or until the incidence comes
        within 0.5° of 0 or β.
        """
        if len(track) < 3:
            return None
        (ta, xa, ya, ha, ka), (tb, xb, yb, hb, kb), (tc, xc, yc, hc, kc) = track[-3:]
        if ka < 0 or not ka == kb == kc or not (tb > ta and tc > tb):
            return None
        ex, ey = (float(v) for v in self.caster.e[kc])
        d1, d2 = tb - ta, tc - tb
        u1 = ((xb - xa) * ex + (yb - ya) * ey) / d1
        u2 = ((xc - xb) * ex + (yc - yb) * ey) / d2
        n1 = ((yb - ya) * ex - (xb - xa) * ey) / d1
        n2 = ((yc - yb) * ex - (xc - xb) * ey) / d2
        w1 = math.remainder(hb - ha, math.tau) / d1
        w2 = math.remainder(hc - hb, math.tau) / d2
        tol = self.ff.slide_tol
        if not (abs(u1 - u2) <= tol and abs(n1) <= tol and abs(n2) <= tol
                and abs(w1 - w2) <= tol / 10 and abs(u2) >= speed / 2):
            return None
        sign = 1.0 if u2 > 0 else -1.0
        ux, uy = sign * ex, sign * ey
        alpha = abs(math.degrees(math.remainder(hc - math.atan2(uy, ux), math.tau)))
        spare = min(alpha - 0.5, beta_deg - 0.5 - alpha)
        if spare <= 0:
            return None
        w = (w1 + w2) / 2
        t_drift = spare / abs(math.degrees(w)) if w != 0 else math.inf
        c = self.caster
        dist = c.feature_distances((xc, yc), (ux, uy))[0]
        m = len(c.L)
        room = min(dist[:m].min(), dist[m:][self._not_ends(kc)].min(initial=math.inf))
        lam = (xc - c.A[kc, 0]) * ex + (yc - c.A[kc, 1]) * ey
        room = min(room, (c.L[kc] - lam if sign > 0 else lam) - self.margin)
        return abs(u2), ux, uy, w, min(t_drift, room / abs(u2))

    def _not_ends(self, k: int) -> np.ndarray:
        """Mask of the caster's vertices that are not end points of segment k."""
        if k not in self._masks:
            c = self.caster
            ends = np.stack([c.A[k], c.A[k] + c.L[k] * c.e[k]])
            d = np.hypot(*(c.vertices[:, None, :] - ends[None]).transpose(2, 0, 1))
            self._masks[k] = d.min(axis=1) > 1e-9
        return self._masks[k]

    def advance(self, body: int, duration: float, speed: float, yaw_rate: float,
                along: tuple[float, float] | None = None) -> None:
        """Move a steady body on for ``duration`` [s] at forward ``speed`` [m/s] and
        ``yaw_rate`` [rad/s].

        The heading turns by ω·t. Without ``along`` the centre moves by
        ∫ v (cos θ(s), sin θ(s)) ds (a straight line along the heading when ω = 0, an arc
        otherwise); with ``along`` = (ux, uy), a unit vector, it moves v·t along it (a slide
        along a wall). Height, roll and pitch
        are kept, the base velocity turns with the heading, the wheel angles advance at their
        rates. (The command, not an instantaneous measurement: the body's velocity jitters by
        ~0.5 % from step to step, and in turns the wheels spin ~0.8 % faster than the body
        turns; the steady physics averages to the command within ~0.1 %, docs/model.md Appendix C.)
        """
        p, kw = self.p, self.kw
        (x, y, z), orn = p.getBasePositionAndOrientation(body, **kw)
        (vx, vy, vz), (wx, wy, wz) = p.getBaseVelocity(body, **kw)
        joints = p.getJointStates(body, [0, 1], **kw)
        v, w = float(speed), float(yaw_rate)
        yaw = p.getEulerFromQuaternion(orn)[2]
        t = float(duration)
        a = w * t
        if along is not None:
            dx, dy = v * t * along[0], v * t * along[1]
        elif abs(a) < 1e-12:
            dx, dy = v * t * math.cos(yaw), v * t * math.sin(yaw)
        else:
            dx = v / w * (math.sin(yaw + a) - math.sin(yaw))
            dy = v / w * (math.cos(yaw) - math.cos(yaw + a))
        c, s = math.cos(a), math.sin(a)
        qz = (0.0, 0.0, math.sin(a / 2), math.cos(a / 2))
        _, orn2 = p.multiplyTransforms((0, 0, 0), qz, (0, 0, 0), orn)
        p.resetBasePositionAndOrientation(body, (x + dx, y + dy, z), orn2, **kw)
        p.resetBaseVelocity(body, (*_rot(c, s, vx, vy), vz), (*_rot(c, s, wx, wy), wz), **kw)
        for j, (ang, rate, *_) in enumerate(joints):
            p.resetJointState(body, j, ang + rate * t, rate, **kw)
