"""The PyBullet Create 2 (extra ``sim``): :class:`PyBulletRobot` in :mod:`.robot`, its video
recording in :mod:`.video`; the convex wall pieces it is built from are in
:mod:`bouncesim.robots.wall_pieces` (shared with MuJoCo). pybullet itself is imported when a
robot is built.
"""

from .robot import DEFAULT_SPEED, DEFAULT_TIME_STEP, DEFAULT_TURN_SPEED, PyBulletRobot

__all__ = ["PyBulletRobot", "DEFAULT_SPEED", "DEFAULT_TURN_SPEED", "DEFAULT_TIME_STEP"]
