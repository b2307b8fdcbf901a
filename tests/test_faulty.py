"""The faulty body (bouncesim.robots.faulty) and the held-out generated maps (envs.generated):
each fault happens at its declared rate and does what docs/model.md §15 says, a body with no
faults is its wrapped body, and feedback navigation copes with the faults it declares.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from bouncesim.robots import check_robot
from bouncesim.robots.faulty import READINGS, FaultyRobot
from bouncesim.robots.kinematic import KinematicRobot
from bouncesim.runs.execute import navigate_feedback
from envs import Environment, UserError
from envs import generated as gen
from planners.cells import CellSpace

ROOM = Environment.from_dict({"name": "room", "boundary": [[0, 0], [2, 0], [2, 1], [0, 1]],
                              "robot_radius": 0.17,
                              "discretization": {"cell_size": 0.25, "orientations": 8}})
SPEED, TIMEOUT = 0.2, 30.0


def _head_on(body):
    """Drive west from (1.0, 0.5): the wall is 0.83 m ahead (hand-computed: 1.0 − r)."""
    body.place(1.0, 0.5, 180.0)
    return body.drive_until_bump(SPEED, TIMEOUT)


def test_no_faults_is_the_body():
    plain, wrapped = KinematicRobot(ROOM), FaultyRobot(KinematicRobot(ROOM))
    a, b = _head_on(plain), _head_on(wrapped)
    assert a == b and a.bumped and math.isclose(a.elapsed, 0.83 / SPEED, rel_tol=1e-6)
    assert plain.true_pose() == wrapped.true_pose() and plain.clock() == wrapped.clock()


def test_no_faults_passes_conformance():
    assert "bump_sides" in check_robot(lambda env: FaultyRobot(KinematicRobot(env)))


def test_missed_bump_pushes_on_until_the_timeout():
    body = FaultyRobot(KinematicRobot(ROOM), p_miss=1.0, rng=np.random.default_rng(1))
    t0 = body.clock()
    ev = _head_on(body)
    assert not ev.bumped and ev.elapsed == TIMEOUT
    assert math.isclose(body.clock() - t0, TIMEOUT, abs_tol=1e-9)
    x, y, _ = body.true_pose()
    assert math.isclose(x, 0.17, abs_tol=1e-6) and math.isclose(y, 0.5, abs_tol=1e-9)
    assert body.faults == {"side": 0, "miss": 1, "phantom": 0}


def test_phantom_bump_stops_short_on_the_flight():
    body = FaultyRobot(KinematicRobot(ROOM), p_phantom=1.0, rng=np.random.default_rng(2))
    for _ in range(20):
        t0 = body.clock()
        ev = _head_on(body)
        assert ev.bumped and 0 <= ev.elapsed < 0.83 / SPEED
        x, y, h = body.true_pose()
        # the body is where the reported flight puts it, and the clock says the same
        assert math.isclose(x, 1.0 - SPEED * ev.elapsed, abs_tol=1e-6) and y == 0.5
        assert math.isclose(body.clock() - t0, ev.elapsed, abs_tol=1e-9)
    assert body.faults["phantom"] == 20


def test_side_faults_at_their_rate_and_always_wrong():
    """2000 head-on bumps (true reading: both) at p_side = 0.3: the count of wrong readings is
    within 4 binomial standard deviations of 600, and each wrong one is left or right.
    """
    n, p = 2000, 0.3
    body = FaultyRobot(KinematicRobot(ROOM), p_side=p, rng=np.random.default_rng(3))
    wrong = []
    for _ in range(n):
        ev = _head_on(body)
        assert ev.bumped
        if (ev.left, ev.right) != (True, True):
            wrong.append((ev.left, ev.right))
    assert abs(len(wrong) - n * p) < 4 * math.sqrt(n * p * (1 - p))
    assert set(wrong) == {READINGS[0], READINGS[1]} and len(wrong) == body.faults["side"]
    # the two wrong readings are equally likely
    left = sum(w == READINGS[0] for w in wrong)
    assert abs(left - len(wrong) / 2) < 4 * math.sqrt(len(wrong) / 4)


def test_miss_rate_and_one_fault_per_drive():
    n = 2000
    body = FaultyRobot(KinematicRobot(ROOM), p_miss=0.1, p_phantom=0.1, p_side=0.5,
                       rng=np.random.default_rng(4))
    for _ in range(n):
        _head_on(body)
    f = body.faults
    for kind, p in (("miss", 0.1), ("phantom", 0.1), ("side", 0.5 * 0.8)):
        assert abs(f[kind] - n * p) < 4 * math.sqrt(n * p * (1 - p)), (kind, f)


@pytest.mark.parametrize("kwargs, words", [
    ({"p_side": 1.5}, "p_side"), ({"p_miss": -0.1}, "p_miss"),
    ({"p_miss": 0.6, "p_phantom": 0.6}, "must not exceed 1"),
    ({"p_side": 0.1}, "needs an rng")])
def test_bad_rates_are_refused(kwargs, words):
    with pytest.raises(UserError, match=words):
        FaultyRobot(KinematicRobot(ROOM), **kwargs)


def test_feedback_navigates_a_faulty_body_on_a_held_out_map():
    """The L-room (never tuned on), no turn noise, wrong sides at 5 % and missed bumps at 2 %
    (the observation model declares both rates): feedback reaches the goal from known starts
    in at least 18 of 20 pairs the exact planner reaches (20 of 20 when this was written).
    """
    from planners.navigation import make_planner
    env = gen.l_room_octagon(orientations=8)
    cells = CellSpace(env)
    exact = make_planner("exact", cells, (45.0, 90.0, 135.0))
    rng = np.random.default_rng(5)
    ok = n = 0
    while n < 20:
        s, g = (int(v) for v in rng.choice(cells.N, 2, replace=False))
        if exact.plan(s, g) is None:
            continue
        body = FaultyRobot(KinematicRobot(env, side_rule="nearest"), p_side=0.05, p_miss=0.02,
                           rng=np.random.default_rng(100 + n))
        run = navigate_feedback(body, env, s, g, None, np.random.default_rng(n), cells=cells)
        ok += run.success
        n += 1
    assert ok >= 18, ok


# ---------------------------------------------------------------------- the generated maps
def test_l_room_octagon_hand_computed():
    env = gen.l_room_octagon()
    # 4.08 × 2.72 less 1.70 × 1.19, less the octagon 2·√2·R² with R = 0.30
    area = 4.08 * 2.72 - 1.70 * 1.19 - 2 * math.sqrt(2) * 0.30 ** 2
    assert math.isclose(env.free_space.area, area, rel_tol=1e-5)
    oct_ = np.asarray(env.obstacles[0].exterior.coords)[:-1]
    edges = np.diff(np.vstack([oct_, oct_[:1]]), axis=0)
    angles = np.degrees(np.arctan2(edges[:, 1], edges[:, 0])) % 90
    assert np.all(np.minimum(angles, 90 - angles) > 5)     # no face is axis-aligned


@pytest.mark.parametrize("seed", range(12))
def test_slanted_rooms_are_joined_and_slanted(seed):
    env = gen.slanted_room(np.random.default_rng(seed))
    assert env.cspace.geom_type == "Polygon"            # the robot can reach every part
    assert 1 <= len(env.obstacles) <= 2
    ring = np.asarray(env.boundary.exterior.coords)
    d = np.diff(ring, axis=0)
    slanted = np.abs(d[:, 0]) > 1e-9
    slanted &= np.abs(d[:, 1]) > 1e-9
    pillars = [np.asarray(o.exterior.coords) for o in env.obstacles]
    assert slanted.any() or any(len(p) - 1 != 4 for p in pillars)
    for o in env.obstacles:                            # pillars keep clear of the walls
        assert env.boundary.exterior.distance(o) > 2.2 * 0.17


def test_slanted_room_is_a_function_of_its_rng():
    a = gen.slanted_room(np.random.default_rng(7)).to_dict()
    b = gen.slanted_room(np.random.default_rng(7)).to_dict()
    assert a == b
