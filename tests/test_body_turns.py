"""experiments.body_turns on the kinematic twin, whose turns and bumps are exact by
construction (docs/model.md §21): every error is zero to round-off, and the table has a row
per angle plus the pooled one; on the MuJoCo body, the turn errors it declares.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import envs
from experiments.body_turns import ANGLES, declaration, measure, table


def test_the_twin_turns_exactly_and_keeps_its_heading_at_bumps():
    runs = measure("kinematic", envs.load("lab"), 12, np.random.default_rng(3))
    assert len(runs) == 12
    assert np.abs(runs.turn_error_deg).max() < 1e-6
    assert np.abs(runs.flight_rotation_deg).max() < 1e-6
    t = table(runs)
    assert set(t.angle) <= set(ANGLES) | {"all"} and "all" in set(t.angle)
    assert int(t[t.angle == "all"].trials.iloc[0]) == 12
    assert declaration(runs) == "none"


@pytest.mark.physics
def test_the_mujoco_body_turns_as_it_declares():
    # the MuJoCo body's declared turn errors (DECLARED_TURNS, a factor and an offset: what
    # the coverage chain and a feedback filter add to the declared noise) against fresh
    # measurements: on lab (seed 0, the declaration's room, 150 trials) the fitted factor
    # within 0.001 and the declared mean error O + (F − 1)·φ within 0.1° at every angle; on
    # another map and seed the mean turn error within 0.3° of the declared mean over the
    # trials' angles, the turn and bump scatter in quadrature within a factor 1.6 of the
    # declared σ
    pytest.importorskip("mujoco")
    from bouncesim.robots.mujoco.robot import DECLARED_TURNS
    from planners.navigation.feedback.planner import declared_turn
    from planners.noise import TurnNoise
    declared = declared_turn(DECLARED_TURNS)
    body = TurnNoise().with_body(DECLARED_TURNS)
    angles = (30.0, 45.0, 75.0, 90.0, 135.0, 315.0)
    printed = declaration(measure("mujoco", envs.load("lab"), 150, np.random.default_rng(0),
                                  angles=angles), True)
    assert abs(declared_turn(printed)["factor"] - declared["factor"]) <= 0.001
    fitted = TurnNoise().with_body(printed)
    for a in angles:
        assert abs(fitted.body_mean_deg(a) - body.body_mean_deg(a)) <= 0.1, a
    runs = measure("mujoco", envs.load("fig1"), 120, np.random.default_rng(11))
    predicted = np.mean([body.body_mean_deg(a) for a in runs.angle])
    assert abs(runs.turn_error_deg.mean() - predicted) <= 0.3
    scatter = math.hypot(runs.turn_error_deg.std(), runs.flight_rotation_deg.std())
    assert declared["sigma"] / 1.6 <= scatter <= declared["sigma"] * 1.6, scatter


@pytest.mark.physics
def test_the_mujoco_body_declares_its_turns_by_bump_speed():
    # after a bump at 0.2 m/s (navigation's speed) the body turns less short than at 0.3 m/s
    # (DECLARED_TURNS_AT): what `... --trials 150 --speed 0.2` prints (lab, seed 0), within
    # 0.05°, and the two speeds' mean errors at 45°-135° more than 0.3° apart; a feedback
    # run at each speed
    # assumes that speed's declaration
    pytest.importorskip("mujoco")
    from bouncesim.robots.mujoco.robot import DECLARED_TURNS_AT, MuJoCoRobot
    from bouncesim.runs.execute import navigate_feedback
    from bouncesim.runs.feedback import body_turns
    from planners.navigation.feedback.planner import declared_turn
    slow = declared_turn(DECLARED_TURNS_AT[0.2])
    printed = declared_turn(declaration(measure("mujoco", envs.load("lab"), 150,
                                                np.random.default_rng(0), speed=0.2)))
    assert abs(printed["offset"] - slow["offset"]) <= 0.05
    assert abs(printed["sigma"] - slow["sigma"]) <= 0.05
    from planners.noise import TurnNoise
    fast = TurnNoise().with_body(DECLARED_TURNS_AT[0.3])     # a factor: its mean at 45°-135°
    assert slow["offset"] - np.mean([fast.body_mean_deg(a) for a in ANGLES]) > 0.3
    with MuJoCoRobot("lab") as bot:
        assert body_turns(bot, 0.2) == DECLARED_TURNS_AT[0.2]
        assert body_turns(bot, 0.3) == body_turns(bot) == bot.turn_errors
        assert body_turns(bot, 0.25) is None          # no measurement at that speed
        for speed in (0.2, 0.3):                       # one bump each: what the filter assumed
            run = navigate_feedback(bot, bot.env, 8, 0, None, np.random.default_rng(1),
                                    speed=speed, max_bumps=1)
            told = declared_turn(DECLARED_TURNS_AT[speed])
            assert run.assumed_turns["offset"] == pytest.approx(told["offset"])
            assert run.assumed_turns["bias"] == pytest.approx(told["bias"])


def test_body_turns_follows_a_wrapper_to_the_speed_of_its_body():
    # FaultyRobot passes the wrapped body's speed-dependent declarations through; a body
    # with only a fixed declaration gives it at every speed
    from bouncesim.robots.faulty import FaultyRobot
    from bouncesim.runs.feedback import body_contact, body_turns

    class Fixed:
        env = envs.load("lab")
        turn_errors, contact, spec = "gauss:0.3,offset=-0.2", None, None

    class BySpeed(Fixed):
        def turn_errors_at(self, speed):
            return {0.2: "gauss:0.5,offset=-0.7"}.get(speed)

        def contact_at(self, speed):
            return None

    assert body_turns(Fixed(), 0.2) == "gauss:0.3,offset=-0.2"
    assert body_turns(BySpeed(), 0.2) == "gauss:0.5,offset=-0.7"
    assert body_turns(BySpeed(), 0.3) is None and body_turns(BySpeed()) == Fixed.turn_errors
    wrapped = FaultyRobot(BySpeed())
    assert body_turns(wrapped, 0.2) == "gauss:0.5,offset=-0.7"
    assert body_contact(wrapped, 0.2) is None


@pytest.mark.physics
def test_contact_flights_agree_away_from_the_bump_angle(capsys):
    # experiments.contact_flights: PyBullet and the twin with PyBullet's rule, one flight
    # from the same glancing pose at 13°–20° (well above β): both bodies bump at the wall
    # and end within 2 cm of each other; a bad --incidence is one sentence, exit 2
    pytest.importorskip("pybullet")
    from experiments.contact_flights import compare, glancing_starts, main
    env = envs.load("lab")
    starts = glancing_starts(env, 8, (13.0, 20.0), np.random.default_rng(2))
    assert len(starts) == 8 and all(13 <= s[3] < 20 for s in starts)
    runs = compare(env, "pybullet", starts)
    assert (runs.apart_m < 0.02).all(), runs
    with pytest.raises(SystemExit) as stop:
        main(["--incidence", "20,5"])
    assert stop.value.code == 2 and "--incidence" in capsys.readouterr().err


def test_lockstep_of_the_twin_against_itself_ends_together():
    """contact_flights' lockstep flies the twin from the body's pose after each turn: with
    the twin as the body (the same rule) every flight ends within 1 mm of the body's (the
    start is moved 20 µm off the wall it touches, which a glancing flight stretches), and each
    row names the wall direction it left from.
    """
    import envs
    from experiments.contact_flights import lockstep
    runs = lockstep(envs.load("lab"), "kinematic", 75.0, 20, np.random.default_rng(1))
    assert len(runs) == 20 and runs.apart_m.max() < 1e-3
    assert set(runs.wall) <= {"x", "y", "slanted"}
