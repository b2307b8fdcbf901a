"""A differential-drive body moved by wheel-speed commands in emulated time: the physics the
two robot emulators share (the Create 2 Open Interface emulator
:mod:`bouncesim.robots.create2.emulator` and the Create 3 SDK emulator
:mod:`bouncesim.robots.create3.emulator`).

The body is the kinematic twin (:class:`bouncesim.robots.kinematic.KinematicRobot`): straight
motion and contacts are the twin's (the body stops at the wall, the bumper reads the contact
side), in-place spins rotate in place, other wheel pairs follow the differential-drive arc in
5 ms sub-steps. The wheels' own travel is counted (a blocked body's wheels slip, a lifted
robot's spin freely, a stalled wheel does not turn), and so is the odometry a robot computes
from it (distance [mm] and angle [deg] accumulators).

``noise`` is applied once per in-place spin, at its end, to the whole spin (a spin ends when
the wheels stop, reverse or stop spinning in place, not when they slow down): the body slips,
the wheel counts do not see it.

>>> import envs
>>> body = WheelBody(envs.load("lab"), start=(0.51, 0.51, 0.0))
>>> body.set_wheels(200, 200)            # [mm/s] left, right
>>> body.advance_to(1.0)
>>> tuple(round(v, 3) for v in body.true_pose()), round(body.dist_acc, 1)
((0.71, 0.51, 0.0), 200.0)
"""

from __future__ import annotations

import math

import numpy as np

from envs import Environment

from .kinematic import KinematicRobot
from .noise import NoiseModel, noise_and_rng

__all__ = ["WheelBody"]

SUBSTEP = 0.005                 # [s] sub-step of a curved motion
_EPS_W = 1e-9


def spin_sense(left: float, right: float) -> int:
    """+1 / -1 for an in-place spin CCW / CW, 0 for anything else."""
    if right == -left and right != 0:
        return 1 if right > 0 else -1
    return 0


class WheelBody:
    """The twin moved by (left, right) wheel speeds [mm/s] in emulated time.

    Parameters
    ----------
    env : Environment
    noise : NoiseModel, optional
        Body slip per in-place spin (default exact).
    rng : numpy.random.Generator or int, optional
        Draws the noise (required when the noise is not exact).
    start : (x [m], y [m], heading [deg]), optional
        Initial pose (default: the twin's, cell 0 facing east).
    glance_deg : float or None
        The twin's glancing-contact arc (:class:`~bouncesim.robots.kinematic.KinematicRobot`).

    Attributes
    ----------
    left, right : float     accepted wheel command [mm/s]
    stalled : dict          {"left": bool, "right": bool}: that wheel does not turn
    lifted : bool           wheels off the floor: they turn, the body does not move
    wheel_m : list          (left, right) wheel travel [m]
    dist_acc, angle_acc : float   odometry accumulators [mm], [deg] (readers reset them)
    t : float               emulated time the body has been advanced to [s]
    """

    def __init__(self, env: Environment, noise: NoiseModel | None = None,
                 rng: np.random.Generator | int | None = None, *,
                 start: tuple[float, float, float] | None = None,
                 glance_deg: float | None = 80.0) -> None:
        self.noise, self.rng = noise_and_rng(noise, rng)
        self.bot = KinematicRobot(env, glance_deg=glance_deg)
        self.spec = self.bot.spec
        if start is not None:
            self.bot.place(*start)
        self.left = self.right = 0.0
        self.stalled = {"left": False, "right": False}
        self.lifted = False
        self.spin = 0.0                 # commanded rotation of the current spin [deg]
        self.wheel_m = [0.0, 0.0]
        self.dist_acc = 0.0
        self.angle_acc = 0.0
        self.t = 0.0

    @property
    def contact(self):
        """The twin's contact rule (:class:`envs.motion.ContactParams`, or None: the
        front-half bumper): what a filter that models this body should assume.
        """
        return self.bot.contact

    def place(self, x: float, y: float, heading_deg: float) -> None:
        """Put the body at a pose, its current spin forgotten and its wheels on the floor."""
        self.bot.place(x, y, heading_deg)
        self.spin = 0.0
        self.lifted = False

    def true_pose(self) -> tuple[float, float, float]:
        """(x [m], y [m], heading [deg])."""
        return self.bot.true_pose()

    def bumper(self) -> tuple[bool, bool]:
        """(left, right) bumper switches now."""
        return self.bot.bumper()

    def set_wheels(self, left: float, right: float) -> None:
        """Accept a wheel command [mm/s]; reversing or leaving an in-place spin ends it (and
        applies the spin's slip).
        """
        if (left, right) != (self.left, self.right) and \
                spin_sense(left, right) != spin_sense(self.left, self.right):
            self.end_spin()             # (slowing a spin down does not end it)
        self.left, self.right = float(left), float(right)

    def end_spin(self) -> None:
        """At the end of an in-place spin the body slips by the noise model's draw."""
        if self.spin and not self.noise.exact:
            actual = self.noise.sample(self.rng, self.spin)
            x, y, h = self.bot.true_pose()
            self.bot.place(x, y, h + (actual - self.spin))
        self.spin = 0.0

    def actual_wheels(self) -> tuple[float, float]:
        """(left, right) wheel speeds [m/s] actually turning."""
        left = 0.0 if self.stalled["left"] else self.left / 1000.0
        right = 0.0 if self.stalled["right"] else self.right / 1000.0
        return left, right

    def advance_to(self, now: float) -> float | None:
        """Move the body under the current command up to emulated time ``now`` [s].

        Returns the time [s] at which a straight forward drive met a wall that stopped it in
        this interval (exact, from the twin's ray cast), else None.
        """
        if now <= self.t:
            return None
        t0, dt = self.t, now - self.t
        self.t = now
        vl, vr = self.actual_wheels()
        if vr == 0 and vl == 0:
            return None
        b = self.spec.wheel_base
        self.wheel_m[0] += vl * dt
        self.wheel_m[1] += vr * dt
        self.dist_acc += (vl + vr) / 2 * dt * 1000.0
        self.angle_acc += math.degrees((vr - vl) * dt / b)
        if self.lifted:
            return None
        v, w = (vr + vl) / 2, (vr - vl) / b
        bot = self.bot
        if abs(w) < _EPS_W and v > 0:
            t_bump, _ = bot._forward(v, dt)         # the twin's wait(), with the contact time
            return None if t_bump is None else t0 + t_bump
        if abs(w) < _EPS_W:
            bot.drive(v)
            bot.wait(dt)
            bot.stop()
        elif abs(v) < 1e-12:
            step = math.degrees(w * dt)
            bot.turn(step)
            self.spin += step
            return None
        else:
            n = max(1, int(math.ceil(dt / SUBSTEP)))
            h = dt / n
            half = math.degrees(w * h) / 2
            for _ in range(n):
                bot.turn(half)
                bot.drive(v)
                bot.wait(h)
                bot.turn(half)
            bot.stop()
        return None

    def free_ahead(self) -> float:
        """Free distance [m] along the heading before the body touches a wall."""
        return self.bot._free_distance(1.0)
