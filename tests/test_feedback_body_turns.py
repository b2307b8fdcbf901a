"""A body's own turn errors in the feedback filter (docs/model.md §15, "A body's own
turns"): the declaration is read from the body (and through a wrapper), added to the
declared noise by hand-computed rules, and it makes a biased body reach its goals.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from bouncesim.robots.faulty import FaultyRobot
from bouncesim.robots.kinematic import KinematicRobot
from bouncesim.robots.noise import parse_noise
from bouncesim.runs.execute import navigate_feedback
from bouncesim.runs.feedback import body_turns
from envs import Environment, UserError
from planners.cells import CellSpace
from planners.navigation.feedback import FeedbackConfig, FeedbackPlanner

PILLAR = Environment.from_dict({
    "name": "pillar", "boundary": [[0, 0], [2.5, 0], [2.5, 2], [0, 2]],
    "obstacles": [[[1.1, 0.8], [1.5, 0.9], [1.4, 1.3], [1.0, 1.2]]],
    "robot_radius": 0.17, "discretization": {"cell_size": 0.25, "orientations": 8}})


def test_a_body_declares_its_turns_and_a_wrapper_passes_them_on():
    body = KinematicRobot(PILLAR)
    assert body_turns(body) is None                     # the twin declares nothing
    body.turn_errors = "gauss:0.5,offset=-2"
    assert body_turns(body) == "gauss:0.5,offset=-2"
    wrapped = FaultyRobot(body, p_side=0.0, rng=np.random.default_rng(0))
    assert body_turns(wrapped) == "gauss:0.5,offset=-2"


def test_the_body_s_errors_add_to_the_declared_noise():
    # declared gauss:2 (σ 2°, no offset), the body's own gauss:1,offset=-2: σ = √5°, offset
    # −2°; a declared factor 1.1 with offset 1° then the body's −2°: f = 1.1, b = 1 − 2 = −1
    cs = CellSpace(PILLAR)
    fp = FeedbackPlanner(cs, [45, 90, 135], noise="gauss:2", rng=np.random.default_rng(0))
    cfg = fp.navigator(5, None, 80, "gauss:1,offset=-2").cfg
    assert cfg.turn_sigma_deg == pytest.approx(math.sqrt(5))
    assert cfg.turn_offset_deg == pytest.approx(-2.0) and cfg.turn_factor == 1.0
    fp = FeedbackPlanner(cs, [45, 90, 135], noise="gauss:0,factor=1.1,offset=1",
                         rng=np.random.default_rng(0))
    cfg = fp.navigator(5, None, 80, "gauss:0,offset=-2").cfg
    assert (cfg.turn_factor, cfg.turn_offset_deg) == pytest.approx((1.1, -1.0))
    assert fp.navigator(5, None, 80).cfg.turn_offset_deg == pytest.approx(1.0)
    with pytest.raises(UserError):
        fp.navigator(5, None, 80, "gauss:-1")


def test_a_run_records_the_turns_its_filter_assumed():
    body = KinematicRobot(PILLAR)
    body.turn_errors = "gauss:1.5,offset=-2"
    run = navigate_feedback(body, PILLAR, 3, 60, "gauss:2", np.random.default_rng(1),
                            max_bumps=3)
    assert run.to_json()["assumed_turns"] == {"sigma": 2.5, "scale": 0.0, "bias": 0.0,
                                              "factor": 1.0, "offset": -2.0}


def _runs(declare: bool, config: FeedbackConfig | None = None) -> int:
    # the twin turning 3° short of every command, told nothing (noise None) by the user
    env, cs, done = PILLAR, CellSpace(PILLAR), 0
    for i in range(10):
        rng = np.random.default_rng(100 + i)
        body = KinematicRobot(env, parse_noise("gauss:0.3,offset=-3", 45.0), rng.spawn(1)[0])
        if declare:
            body.turn_errors = "gauss:0.5,offset=-3"
        run = navigate_feedback(body, env, 3, 60, None, rng, cells=cs, config=config)
        done += run.success
    return done


def test_a_biased_body_that_declares_its_bias_reaches_its_goals():
    # declared: at least 9 of 10 (the filter commands 3° more and expects 0.5° scatter);
    # the same body with its declaration ignored does worse (measured: 10 against 2)
    declared = _runs(True)
    ignored = _runs(True, FeedbackConfig(body_turns=False))
    assert declared >= 9
    assert ignored <= declared - 3
    assert _runs(False) == ignored                     # ignoring = declaring nothing


@pytest.mark.parametrize("kind", ["emulator", "create3-emulator"])
def test_the_create_adapters_pass_on_their_emulated_body_s_turns(kind):
    from bouncesim.robots import make_robot
    with make_robot(kind, PILLAR) as robot:
        assert body_turns(robot) is None            # the emulated wheel body declares none
        emulator = robot.emulator if kind == "emulator" else robot.backend.emulator
        emulator.body.turn_errors = "gauss:0.5,offset=1"
        assert body_turns(robot) == "gauss:0.5,offset=1"
