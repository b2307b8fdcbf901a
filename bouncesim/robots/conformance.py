"""Conformance checks for any :class:`~bouncesim.robots.base.Robot`: bring a body, test it.

:func:`check_robot` runs every check (or a chosen few) against a factory ``make(env) -> Robot``
(or a :func:`~bouncesim.robots.make_robot` kind name) and raises :class:`ConformanceError`
naming each failed check and why. Each check is also a function ``check_xxx(make)`` in
:data:`CHECKS` (by name without the prefix) that raises AssertionError on its own.

Every check builds a fresh noise-free robot in the test room, places it and uses only the Robot
interface, plus ``place`` / ``true_pose`` to set up and to observe (so they apply to
simulators and to the Create 2 adapter driving the emulator; a hardware backend would run the
interface-only subset). The tolerances are those a physics simulation of the Create 2 must
meet; the kinematic twin meets them with room to spare:

- clock: ``wait(dt)`` advances the clock by dt within one physics step (10 ms);
- straight driving: 0.2 m/s for 2 s covers 0.40 m within 2 cm, heading kept within 1°;
- stop: after ``stop()`` and a 0.2 s settle, the robot moves less than 2 mm in 1 s;
- turns: +90° within 3°; four +90° turns return to the start heading within 5°; a turn takes
  time on the clock; wheel encoders (where present) see the turn within 5%;
- bumps: a head-on drive toward a wall at a known free distance d bumps after d within 2 cm,
  stops with the body within 5 mm of touching (never deeper than 5 mm into the wall), and
  closes both bumper switches; a wall hit on the left front closes only the left switch, on
  the right front only the right one; the bumper is open in free space and while driving
  parallel to a wall the body touches;
- timeouts: ``drive_until_bump`` in free space returns ``bumped=False`` after the timeout.

The test environment is a 5 x 3 cell room (1.70 m x 1.02 m, r = 0.17 m, h = 0.34 m).
"""

from __future__ import annotations

import math
import traceback
from collections.abc import Callable, Iterable

import numpy as np

from envs import Environment

from .base import BumpEvent, Robot
from .factory import make_robot

__all__ = ["ROOM", "CHECKS", "ConformanceError", "check_robot", "room_env"]

ROOM = {"name": "conformance-room", "boundary": [[0, 0], [1.7, 0], [1.7, 1.02], [0, 1.02]],
        "robot_radius": 0.17, "discretization": {"cell_size": 0.34, "orientations": 8}}


def room_env() -> Environment:
    """The small room the conformance checks drive in."""
    return Environment.from_dict(ROOM)


def _dist_to_walls(env: Environment, x: float, y: float) -> float:
    import shapely
    return float(shapely.distance(shapely.points([x, y]), env.walls))


def _hdiff(a: float, b: float) -> float:
    """Signed difference a − b of headings [deg], wrapped to (−180, 180]."""
    d = math.fmod(a - b, 360.0)
    if d > 180:
        d -= 360
    elif d <= -180:
        d += 360
    return d


def _robot(make_robot, x, y, heading):
    env = room_env()
    bot = make_robot(env)
    bot.place(x, y, heading)
    return env, bot


def check_clock_advances_with_wait(make_robot) -> None:
    env, bot = _robot(make_robot, 0.85, 0.51, 0.0)
    with bot:
        t0 = bot.clock()
        bot.wait(0.5)
        t1 = bot.clock()
        bot.wait(0.25)
        t2 = bot.clock()
        assert abs((t1 - t0) - 0.5) <= 0.01
        assert abs((t2 - t1) - 0.25) <= 0.01
        x, y, _ = bot.true_pose()
        assert math.hypot(x - 0.85, y - 0.51) < 2e-3, "waiting without a drive command moved"


def check_drive_straight(make_robot) -> None:
    env, bot = _robot(make_robot, 0.3, 0.51, 0.0)
    with bot:
        bot.drive(0.2)
        bot.wait(2.0)
        bot.stop()
        x, y, h = bot.true_pose()
        assert abs((x - 0.3) - 0.40) <= 0.02, f"drove {x - 0.3:.3f} m instead of 0.40 m"
        assert abs(y - 0.51) <= 0.01
        assert abs(_hdiff(h, 0.0)) <= 1.0
        assert bot.bumper() == (False, False)


def check_drive_backwards(make_robot) -> None:
    env, bot = _robot(make_robot, 1.2, 0.51, 0.0)
    with bot:
        bot.drive(-0.2)
        bot.wait(1.0)
        bot.stop()
        x, _, _ = bot.true_pose()
        assert abs((1.2 - x) - 0.2) <= 0.02


def check_stop_stops(make_robot) -> None:
    env, bot = _robot(make_robot, 0.3, 0.51, 0.0)
    with bot:
        bot.drive(0.2)
        bot.wait(1.0)
        bot.stop()
        bot.wait(0.2)
        x1, y1, _ = bot.true_pose()
        bot.wait(1.0)
        x2, y2, _ = bot.true_pose()
        assert math.hypot(x2 - x1, y2 - y1) < 2e-3


def check_turn_90(make_robot) -> None:
    env, bot = _robot(make_robot, 0.85, 0.51, 0.0)
    with bot:
        t0 = bot.clock()
        enc0 = bot.encoders()
        bot.turn(90.0)
        assert bot.clock() > t0, "a turn must take time on the clock"
        x, y, h = bot.true_pose()
        assert abs(_hdiff(h, 90.0)) <= 3.0, f"heading {h:.2f}° after a 90° turn"
        assert math.hypot(x - 0.85, y - 0.51) < 0.01, "a turn in place moved the centre"
        enc1 = bot.encoders()
        if enc0 is not None:
            mpc = bot.spec.metres_per_count
            dl, dr = (enc1[0] - enc0[0]) * mpc, (enc1[1] - enc0[1]) * mpc
            turned = math.degrees((dr - dl) / bot.spec.wheel_base)
            assert abs(turned - 90.0) <= 4.5, f"encoders saw {turned:.1f}° for a 90° turn"


def check_four_quarter_turns(make_robot) -> None:
    env, bot = _robot(make_robot, 0.85, 0.51, 30.0)
    with bot:
        for _ in range(4):
            bot.turn(90.0)
        _, _, h = bot.true_pose()
        assert abs(_hdiff(h, 30.0)) <= 5.0


def check_encoders_count_forward(make_robot) -> None:
    env, bot = _robot(make_robot, 0.3, 0.51, 0.0)
    with bot:
        e0 = bot.encoders()
        if e0 is None:
            return
        bot.drive(0.2)
        bot.wait(1.5)
        bot.stop()
        bot.wait(0.1)
        e1 = bot.encoders()
        x, _, _ = bot.true_pose()
        mpc = bot.spec.metres_per_count
        for d in (e1[0] - e0[0], e1[1] - e0[1]):
            assert abs(d * mpc - (x - 0.3)) <= 0.05 * (x - 0.3) + 0.005


def check_bumper_open_in_free_space(make_robot) -> None:
    env, bot = _robot(make_robot, 0.85, 0.51, 0.0)
    with bot:
        assert bot.bumper() == (False, False)
        bot.turn(45.0)
        assert bot.bumper() == (False, False)


def check_head_on_bump(make_robot) -> None:
    # facing the east wall x = 1.7 from x = 0.6: free travel 1.7 - 0.17 - 0.6 = 0.93 m
    env, bot = _robot(make_robot, 0.6, 0.51, 0.0)
    with bot:
        ev = bot.drive_until_bump(0.2, 20.0)
        assert isinstance(ev, BumpEvent)
        assert ev.bumped and ev.left and ev.right, ev
        assert abs(0.2 * ev.elapsed - 0.93) <= 0.02, f"bumped after {0.2 * ev.elapsed:.3f} m"
        x, y, _ = bot.true_pose()
        gap = _dist_to_walls(env, x, y) - env.robot_radius
        assert -5e-3 <= gap <= 5e-3, f"stopped {gap * 1000:.1f} mm from touching"
        # stopped: the wheels no longer push
        bot.wait(0.5)
        x2, y2, _ = bot.true_pose()
        assert math.hypot(x2 - x, y2 - y) < 2e-3


def check_bump_sides(make_robot) -> None:
    # heading 45° toward the north wall: the contact is ahead-left -> left switch only
    env, bot = _robot(make_robot, 0.85, 0.51, 45.0)
    with bot:
        ev = bot.drive_until_bump(0.2, 10.0)
        assert ev.bumped and ev.left and not ev.right, ev
        _, y, _ = bot.true_pose()
        assert abs(y - (1.02 - 0.17)) <= 5e-3
    # heading -45° toward the south wall: ahead-right -> right switch only
    env, bot = _robot(make_robot, 0.85, 0.51, -45.0)
    with bot:
        ev = bot.drive_until_bump(0.2, 10.0)
        assert ev.bumped and ev.right and not ev.left, ev
        _, y, _ = bot.true_pose()
        assert abs(y - 0.17) <= 5e-3


def check_bump_when_touching(make_robot) -> None:
    # touching the west wall, facing it: the bump comes at once
    env, bot = _robot(make_robot, 0.17, 0.51, 180.0)
    with bot:
        ev = bot.drive_until_bump(0.2, 5.0)
        assert ev.bumped and ev.elapsed <= 0.1, ev


def check_parallel_to_wall_is_not_a_bump(make_robot) -> None:
    # the centre row next to the south wall: the body touches it while driving east
    env, bot = _robot(make_robot, 0.17, 0.17, 0.0)
    with bot:
        ev = bot.drive_until_bump(0.2, 3.0)
        assert not ev.bumped, f"driving along a wall bumped after {0.2 * ev.elapsed:.3f} m"
        x, y, _ = bot.true_pose()
        assert abs(x - 0.77) <= 0.02 and abs(y - 0.17) <= 5e-3


def check_timeout_in_free_space(make_robot) -> None:
    env, bot = _robot(make_robot, 0.3, 0.51, 0.0)
    with bot:
        ev = bot.drive_until_bump(0.2, 1.0)
        assert not ev.bumped and not ev.left and not ev.right
        assert abs(ev.elapsed - 1.0) <= 0.02
        x, _, _ = bot.true_pose()
        assert abs((x - 0.3) - 0.2) <= 0.02


def check_bounce_sequence(make_robot) -> None:
    # the 90° bounce around the room from (0.85, 0.51) facing east: E, N, W, S walls
    env, bot = _robot(make_robot, 0.85, 0.51, 0.0)
    expect = [(1.53, None, 0.68), (None, 0.85, 0.34), (0.17, None, 1.36), (None, 0.17, 0.68)]
    with bot:
        for ex, ey, dist in expect:
            ev = bot.drive_until_bump(0.2, 20.0)
            assert ev.bumped
            assert abs(0.2 * ev.elapsed - dist) <= 0.03, \
                f"bumped after {0.2 * ev.elapsed:.3f} m instead of {dist:.2f} m"
            x, y, _ = bot.true_pose()
            if ex is not None:
                assert abs(x - ex) <= 0.01
            if ey is not None:
                assert abs(y - ey) <= 0.01
            bot.turn(90.0)


def check_place_and_true_pose(make_robot) -> None:
    env, bot = _robot(make_robot, 0.5, 0.6, 123.0)
    with bot:
        x, y, h = bot.true_pose()
        assert np.allclose([x, y], [0.5, 0.6], atol=1e-3)
        assert abs(_hdiff(h, 123.0)) <= 0.5
        assert isinstance(bot, Robot)


CHECKS = {name.removeprefix("check_"): fn for name, fn in sorted(globals().items())
          if name.startswith("check_") and callable(fn)}


class ConformanceError(AssertionError):
    """One or more conformance checks failed; :attr:`failures` maps each to its reason."""

    def __init__(self, name: str, failures: dict[str, str], total: int) -> None:
        self.failures = dict(failures)
        lines = "\n".join(f"  {check}: {why}" for check, why in self.failures.items())
        super().__init__(f"{len(failures)} of {total} conformance checks failed for "
                         f"{name}:\n{lines}")


def check_robot(robot: str | Callable[[Environment], Robot], *,
                checks: Iterable[str] | None = None) -> list[str]:
    """Run the conformance checks against a body; return the names of the checks run.

    Parameters
    ----------
    robot : str or callable
        A :func:`~bouncesim.robots.make_robot` kind (``"kinematic"``, ``"pybullet"``,
        ``"emulator"``, ...) or a factory ``make(env) -> Robot`` returning a fresh, noise-free
        robot in ``env`` (each check builds one and closes it).
    checks : iterable of str, optional
        Names from :data:`CHECKS` (default: all of them, in name order).

    Raises
    ------
    ConformanceError
        After running every selected check, when any failed: one line per failed check with
        its reason (a failed assertion, or any exception the robot raised).
    ValueError
        An unknown check name.

    Examples
    --------
    >>> from bouncesim.robots.kinematic import KinematicRobot
    >>> class Lazy(KinematicRobot):
    ...     def turn(self, angle_deg):
    ...         super().turn(angle_deg / 2)
    >>> check_robot(Lazy, checks=["turn_90", "drive_straight"])   # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    bouncesim.robots.conformance.ConformanceError: 1 of 2 conformance checks failed for Lazy:
      turn_90: ...
    """
    if isinstance(robot, str):
        kind = robot

        def factory(env: Environment) -> Robot:
            return make_robot(kind, env)
        name = kind
    else:
        factory, name = robot, getattr(robot, "__name__", repr(robot))
    names = sorted(CHECKS) if checks is None else list(checks)
    unknown = [n for n in names if n not in CHECKS]
    if unknown:
        raise ValueError(f"unknown conformance check {unknown[0]!r}; the checks are "
                         f"{', '.join(sorted(CHECKS))}.")
    failures: dict[str, str] = {}
    for check in names:
        try:
            CHECKS[check](factory)
        except AssertionError as exc:
            where = traceback.extract_tb(exc.__traceback__)[-1]
            failures[check] = str(exc) or f"failed: {where.line} (line {where.lineno})"
        except Exception as exc:  # noqa: BLE001 - a robot that raises fails the check
            failures[check] = f"{type(exc).__name__}: {exc}"
    if failures:
        raise ConformanceError(name, failures, len(names))
    return names
