"""make_robot and the one constructor contract of the bodies (noise and rng the same way)."""

from __future__ import annotations

import importlib.util

import numpy as np
import pytest

import envs
from bouncesim.robots import KINDS, make_robot
from bouncesim.robots.conformance import room_env
from bouncesim.robots.kinematic import KinematicRobot
from bouncesim.robots.noise import GaussianNoise, NoNoise
from bouncesim.runs.execute import execute
from envs import UserError

NEEDS_RNG = "a robot with rotation noise needs an rng"


@pytest.fixture(scope="module")
def lab():
    return envs.load("lab")


def test_noisy_bodies_without_an_rng_are_refused_alike(lab):
    from bouncesim.robots.create2 import OIEmulator
    from bouncesim.robots.pybullet import PyBulletRobot
    for build in (lambda: KinematicRobot(lab, GaussianNoise(1.0)),
                  lambda: PyBulletRobot(lab, GaussianNoise(1.0)),
                  lambda: OIEmulator(lab, GaussianNoise(1.0)),
                  lambda: make_robot("kinematic", lab, noise=GaussianNoise(1.0))):
        with pytest.raises(UserError, match=NEEDS_RNG):
            build()


def test_exact_bodies_need_no_rng(lab):
    assert KinematicRobot(lab, NoNoise()).rng is None
    assert make_robot("kinematic", lab).rng is None


def test_make_robot_is_the_constructor(lab):
    """The same noise stream, whether the rng is a seed or a Generator, by name or by class."""
    def final(bot):
        return execute("135° 135° 0", bot, start=103, goal=8).final_pose
    a = final(make_robot("kinematic", lab, noise=GaussianNoise(3.0), rng=4))
    b = final(KinematicRobot(lab, GaussianNoise(3.0), np.random.default_rng(4)))
    assert a == b
    bot = make_robot("kinematic", lab, glance_deg=80, turn="encoders")
    assert bot.glance_deg == 80.0 and bot.turn_mode == "encoders" and bot.env is lab


@pytest.mark.parametrize("kind,options,message", [
    ("roomba", {}, "unknown robot 'roomba'"),
    ("kinematic", {"gui": True}, "the kinematic robot takes no option 'gui'"),
    ("create2", {}, "needs a serial port"),
    ("create2", {"port": "/dev/null", "wheel_base": 0.9}, "wheel base must lie in"),
])
def test_make_robot_user_errors(lab, kind, options, message):
    if kind == "create2":
        pytest.importorskip("serial")
    with pytest.raises(UserError, match=message):
        make_robot(kind, lab, **options)


def test_kinds():
    assert KINDS == ("kinematic", "pybullet", "mujoco", "create2", "emulator", "create3",
                     "create3-emulator")


@pytest.mark.skipif(importlib.util.find_spec("serial") is None, reason="needs pyserial")
def test_make_robot_emulator_is_the_adapter_on_an_emulator():
    env = room_env()
    with make_robot("emulator", env, lockstep=True, faults=["garbage@100"]) as bot:
        assert type(bot).__name__ == "Create2Robot" and bot.env is env
        assert bot.emulator.faults[0].kind == "garbage"
        bot.place(0.85, 0.51, 0.0)
        ev = bot.drive_until_bump(0.2, 10.0)
        assert ev.bumped and ev.left and ev.right
    assert bot.emulator._thread is None or not bot.emulator._thread.is_alive()
