"""What the two physics-engine bodies share (:class:`bouncesim.robots.pybullet.PyBulletRobot`,
:class:`bouncesim.robots.mujoco.MuJoCoRobot`): a clock of whole physics steps, velocity-driven
wheels, and the in-place turn by the clock.

A body that inherits :class:`SteppedWheels` keeps ``_steps`` (physics steps taken), ``_t_goal``
(the clock the waits have asked for [s]), ``_closed``, ``time_step`` [s], ``turn_speed``
[m/s] and ``spec``, and writes ``_set_wheels(v_left, v_right)`` [m/s] and ``_step(n)``.
"""

from __future__ import annotations

import math

from envs import UserError

from .base import RobotError

__all__ = ["SETTLE_STEPS", "SteppedWheels"]

SETTLE_STEPS = 2
"""Physics steps a body is left still after a turn, so that it has stopped turning."""


class SteppedWheels:
    """The clock, the drive and the clock turn of a body stepped by a physics engine."""

    def _check_open(self) -> None:
        if self._closed:
            raise RobotError(f"this {type(self).__name__} is closed.")

    def drive(self, speed: float) -> None:
        """Drive straight at ``speed`` [m/s] (|speed| ≤ 0.5 m/s, the Create 2's limit)."""
        self._check_open()
        speed = self.spec.check_speed(speed)
        self._set_wheels(speed, speed)

    def stop(self) -> None:
        """Stop both wheels (the velocity motors brake at their torque limit)."""
        if not self._closed:
            self._set_wheels(0.0, 0.0)

    def clock(self) -> float:
        """Simulated time [s]: whole physics steps × time_step."""
        return self._steps * self.time_step

    def wait(self, duration: float) -> None:
        """Step the physics for ``duration`` [s], rounded to whole steps without drift."""
        self._check_open()
        duration = float(duration)
        if not duration >= 0:
            raise UserError(f"cannot wait a negative or undefined time ({duration} s).")
        self._t_goal += duration
        n = int(round(self._t_goal / self.time_step)) - self._steps
        if n > 0:
            self._step(n)

    def _turn_by_clock(self, angle_deg: float) -> None:
        """Spin at wheel speeds ±turn_speed for φ / ω (ω = 2 v / wheel_base), in whole
        steps, then stop and settle.
        """
        v = math.copysign(self.turn_speed, angle_deg)
        n = round(self.spec.turn_time(angle_deg, self.turn_speed) / self.time_step)
        self._set_wheels(-v, v)
        self.wait(n * self.time_step)
        self.stop()
        self.wait(SETTLE_STEPS * self.time_step)
