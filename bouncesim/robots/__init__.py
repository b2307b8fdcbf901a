"""Robots: the one bump-and-clock interface and the bodies behind it.

- :mod:`.base`: :class:`Robot` (drive, stop, bumper, clock, wait, turn), :class:`RobotSpec`,
  :data:`CREATE2`, :class:`BumpEvent`, :class:`RobotError`;
- :mod:`.noise`: seeded rotation-noise models;
- :mod:`.kinematic`: the kinematic twin (one robot, and a vectorised batch);
- :mod:`.pybullet`: the Create 2 in PyBullet (extra ``sim``);
- :mod:`.create2`: a real Create 2 over its Open Interface and an emulator of it (extra
  ``hardware``);
- :mod:`.faulty`: :class:`~.faulty.FaultyRobot` wraps a simulated body with bump-sensor
  faults (wrong side, missed and phantom bumps) at declared rates;
- :func:`make_robot` builds any of them by name with one constructor contract;
- :func:`check_robot` runs the conformance checks against any body, yours included.

Examples
--------
>>> import envs
>>> check_robot(lambda env: make_robot("kinematic", env))        # doctest: +ELLIPSIS
['bounce_sequence', 'bump_sides', ...]
"""

from .base import CREATE2, BumpEvent, Robot, RobotError, RobotSpec
from .conformance import ConformanceError, check_robot
from .factory import KINDS, make_robot

__all__ = ["CREATE2", "BumpEvent", "Robot", "RobotError", "RobotSpec", "KINDS", "make_robot",
           "check_robot", "ConformanceError"]
