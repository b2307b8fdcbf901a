"""Fast-forward of steady motion in a PyBullet world (docs/model.md §24).

A Create 2 that drives straight far from every wall, or turns in place at its commanded
rate, moves with a constant twist (linear and angular velocity in its own frame) as long as
nothing touches it: the physics steps of such a stretch only integrate that twist. A
:class:`Coaster` advances the body over such a stretch in one move instead (the pose by the
exact integral of the measured twist, the velocities and the wheel joints carried along),
so that physics steps are spent where something happens: starts, stops, approaches to a
wall, contacts.

The mechanism is honest only where it is safe, and :class:`FastForward` says where:

- **drives** jump only when the measured motion is steady (speed within ``speed_tol`` of the
  command, yaw rate within ``yaw_rate_tol``) and the body is at least ``clearance`` from
  every wall (farther than the world's contact distance, so no contact is active); the jump
  ends before the body, grown by ``margin``, would touch a wall it approaches (an exact
  capsule ray cast, :class:`envs.motion.WallCaster`, which ignores walls the motion leaves
  or runs parallel to), so the last ``margin`` of every approach, the contact and the bump
  are simulated, and so are slides along a wall;
- **turns** run their first ``turn_steps`` physics steps (the spin-up, and any push-off from
  the wall just bumped) and jump the rest of the steady spin when the wheels and the body
  turn at the commanded rate (within ``yaw_rate_tol``) and the centre moves slower than
  ``speed_tol``; the stop and the settling are simulated. A disk turning about its own
  centre sweeps no new area, so a spin never meets a wall it did not touch already.

Examples
--------
>>> FastForward().margin
0.02
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import shapely

from envs import UserError
from envs.motion import WallCaster

__all__ = ["FastForward", "Coaster", "DEFAULT_FAST_FORWARD"]


@dataclass(frozen=True)
class FastForward:
    """Where a :class:`Coaster` may skip physics steps (docs/model.md §24).

    Attributes
    ----------
    margin : float        [m] a drive's jump ends this far before the body would touch a
                          wall it approaches
    clearance : float     [m] a drive jumps only while the body is this far from every wall
                          (the world's contact breaking distance is used if larger)
    turns : bool          also jump the steady middle of turns in place
    turn_steps : int      physics steps a turn runs before it may jump
    speed_tol : float     [m/s] steady: |speed − command| at most this (wheels and body)
    yaw_rate_tol : float  [rad/s] steady: |yaw rate − command| at most this (wheels and body)
    """

    margin: float = 0.02
    clearance: float = 0.005
    turns: bool = True
    turn_steps: int = 6
    speed_tol: float = 0.003
    yaw_rate_tol: float = 0.01

    def __post_init__(self) -> None:
        if not (self.margin > 0 and self.clearance > 0 and self.speed_tol > 0
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
        self.clearance = max(settings.clearance, float(contact_distance))
        self.walls = env.walls
        self.radius = float(body_radius)
        self.wheel_r = float(wheel_radius)
        self.wheel_base = float(wheel_base)
        self.caster = WallCaster(env.wall_segments, self.radius + settings.margin)

    def free_travel(self, x: float, y: float, ux: float, uy: float) -> float:
        """Distance [m] the body can move from (x, y) along the unit vector (ux, uy) before it
        comes within ``margin`` of a wall it approaches; −1 when it is within ``clearance``
        of a wall now.
        """
        gap = shapely.distance(shapely.points(x, y), self.walls) - self.radius
        if not gap >= self.clearance:
            return -1.0
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

    def advance(self, body: int, duration: float, speed: float, yaw_rate: float) -> None:
        """Move a steady body (:meth:`steady`) on for ``duration`` [s] at its commanded
        forward ``speed`` [m/s] and ``yaw_rate`` [rad/s].

        The heading turns by ω·t and the centre moves by ∫ v (cos θ(s), sin θ(s)) ds: a
        straight line along the heading when ω = 0, an arc otherwise. Height, roll and pitch
        are kept, the base velocity turns with the heading, the wheel angles advance at their
        rates. (The command, not an instantaneous measurement: the body's velocity jitters by
        ~0.5 % from step to step, and in turns the wheels spin ~0.8 % faster than the body
        turns; the steady physics averages to the command within ~0.1 %, docs/model.md §24.)
        """
        p, kw = self.p, self.kw
        (x, y, z), orn = p.getBasePositionAndOrientation(body, **kw)
        (vx, vy, vz), (wx, wy, wz) = p.getBaseVelocity(body, **kw)
        joints = p.getJointStates(body, [0, 1], **kw)
        v, w = float(speed), float(yaw_rate)
        yaw = p.getEulerFromQuaternion(orn)[2]
        t = float(duration)
        a = w * t
        if abs(a) < 1e-12:
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
