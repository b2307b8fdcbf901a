"""The Robot conformance suite (bouncesim.robots.conformance) run against every simulated
backend.
"""

from __future__ import annotations

import pytest

from bouncesim.robots import ConformanceError, check_robot
from bouncesim.robots.conformance import CHECKS
from bouncesim.robots.kinematic import KinematicRobot


def _kinematic(env):
    return KinematicRobot(env)


def _kinematic_glance(env):
    return KinematicRobot(env, glance_deg=80)


def _pybullet(env):
    pytest.importorskip("pybullet")
    from bouncesim.robots.pybullet import PyBulletRobot
    return PyBulletRobot(env)


def _mujoco(env):
    pytest.importorskip("mujoco")
    from bouncesim.robots.mujoco import MuJoCoRobot
    return MuJoCoRobot(env)


def _create3_emulator(env):
    from bouncesim.robots import make_robot
    return make_robot("create3-emulator", env)


BACKENDS = [
    pytest.param(_kinematic, id="kinematic"),
    pytest.param(_create3_emulator, id="create3-emulator"),
    pytest.param(_kinematic_glance, id="kinematic-glance80"),
    pytest.param(_pybullet, id="pybullet", marks=pytest.mark.physics),
    pytest.param(_mujoco, id="mujoco", marks=pytest.mark.physics),
]


@pytest.mark.parametrize("make_robot", BACKENDS)
@pytest.mark.parametrize("check", sorted(CHECKS))
def test_conformance(check, make_robot):
    check_robot(make_robot, checks=[check])


def test_suite_is_not_empty():
    assert len(CHECKS) >= 12


# ---------------------------------------------------------------- the checks can fail
class _SwappedBumper(KinematicRobot):
    def bumper(self):
        left, right = super().bumper()
        return right, left


class _ShortTurns(KinematicRobot):
    def turn(self, angle_deg):
        super().turn(0.9 * angle_deg)


class _NoStop(KinematicRobot):
    def stop(self):
        pass


class _SlowClock(KinematicRobot):
    def wait(self, duration):
        super().wait(duration)
        self._t -= 0.5 * duration


@pytest.mark.parametrize("broken,check", [
    (_SwappedBumper, "bump_sides"),
    (_ShortTurns, "turn_90"),
    (_ShortTurns, "four_quarter_turns"),
    (_NoStop, "stop_stops"),
    (_SlowClock, "clock_advances_with_wait"),
])
def test_conformance_catches_broken_backends(broken, check):
    with pytest.raises(AssertionError):
        check_robot(lambda env: broken(env), checks=[check])


def test_check_robot_runs_every_check_and_names_each_failure():
    assert check_robot("kinematic") == sorted(CHECKS)
    with pytest.raises(ConformanceError) as info:
        check_robot(_ShortTurns, checks=["turn_90", "drive_straight", "four_quarter_turns"])
    assert set(info.value.failures) == {"turn_90", "four_quarter_turns"}
    message = str(info.value)
    assert message.startswith("2 of 3 conformance checks failed for _ShortTurns:")
    assert "turn_90: heading" in message


def test_check_robot_refuses_unknown_checks():
    with pytest.raises(ValueError, match="unknown conformance check 'fly'"):
        check_robot("kinematic", checks=["fly"])
