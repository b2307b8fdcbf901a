"""The MuJoCo Create 2 (extra ``mujoco``): :class:`MuJoCoRobot` in :mod:`.robot`, the MJCF
world it is built from in :mod:`.world`, many bodies in one world in :mod:`.batch`. mujoco
itself is imported when a robot is built.
"""

from .robot import DEFAULT_TIME_STEP, DEFAULT_TURN_SPEED, MuJoCoRobot

__all__ = ["MuJoCoRobot", "DEFAULT_TURN_SPEED", "DEFAULT_TIME_STEP"]
