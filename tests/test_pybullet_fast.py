"""Fast-forward of steady motion in the PyBullet batch (docs/model.md Appendix C).

Independent evidence: the same PyBullet world stepped through every physics step (the jump
must land where the physics goes), the geometry of a hand-made room (where a slide along a
wall must end), and runs of the batch with and without the fast-forward from the same starts
and seeds (same bump points within the repository's 1 cm bump bound).
"""

from __future__ import annotations

import importlib.util
import math

import numpy as np
import pytest
import shapely

from envs import UserError
from planners.cells import CellSpace

from .conftest import room

pytestmark = [pytest.mark.physics,
              pytest.mark.skipif(importlib.util.find_spec("pybullet") is None,
                                 reason="pybullet is not installed")]


def _jump_or_step(env, start, wheels, jump: bool, n: int = 200):
    """Spin the wheels up for 20 physics steps, cover n more steps by a Coaster jump or by
    physics, then 30 steps of physics; the final pose.
    """
    from bouncesim.robots.pybullet import PyBulletRobot
    from bouncesim.robots.pybullet.fastforward import Coaster, FastForward
    with PyBulletRobot(env, contact_threshold=0.002) as bot:
        coast = Coaster(bot._p, bot._kw, env, bot.body_radius, bot._wheel_r,
                        bot.spec.wheel_base, FastForward(), 0.002)
        bot.place(*start)
        bot._set_wheels(*wheels)
        bot._step(20)
        v, w = (wheels[0] + wheels[1]) / 2, (wheels[1] - wheels[0]) / bot.spec.wheel_base
        assert coast.steady(bot._robot, v, w)
        if jump:
            coast.advance(bot._robot, n * bot.time_step, v, w)
        else:
            bot._step(n)
        bot._step(30)
        return bot.true_pose()


@pytest.mark.parametrize("start, wheels", [
    ((0.40, 0.60, 0.0), (0.3, 0.3)),          # straight drive, 0.3 m of free floor
    ((0.40, 0.50, 30.0), (0.3, 0.3)),
    ((0.60, 0.1701, -90.0), (-0.1, 0.1)),      # spin in place touching the south wall
    ((0.60, 0.1701, -90.0), (0.1, -0.1)),
])
def test_a_jump_lands_where_the_physics_goes(start, wheels):
    """A jump over 200 steady physics steps (1 s: 0.3 m of drive, 49° of spin) ends within
    1 mm and 0.1° of the pose the physics reaches (measured: ≤ 0.3 mm, ≤ 0.02°).
    """
    env = room(6, 4)
    a = _jump_or_step(env, start, wheels, jump=False)
    b = _jump_or_step(env, start, wheels, jump=True)
    assert math.hypot(a[0] - b[0], a[1] - b[1]) <= 1e-3
    assert abs((a[2] - b[2] + 180) % 360 - 180) <= 0.1
    moved = math.hypot(a[0] - start[0], a[1] - start[1]) + abs(a[2] - start[2]) / 100
    assert moved > 0.2                                  # it went somewhere


def _runs(env, policy, starts, steps, seeds):
    from bouncesim.robots.noise import NoNoise
    from bouncesim.robots.pybullet.batch import PyBulletBatch
    from bouncesim.robots.pybullet.fastforward import FastForward
    cs = CellSpace(env)
    out = {}
    for ff in (None, FastForward()):
        with PyBulletBatch(env, len(starts), rngs=[np.random.default_rng(s) for s in seeds],
                           starts=starts, cells=cs, noise=NoNoise(), fast_forward=ff) as b:
            out[ff is not None] = b.run(policy, steps, record=True)
    return cs, out[False], out[True]


def test_fast_forward_bumps_where_every_step_bumps():
    """Bouncing at 90° in an empty 2.04 m x 1.36 m room from four starts (headings 20°, 30°,
    65°, 160°, no corner on their first paths): the first bump, reached by a fast-forwarded
    drive, is where the run through every physics step bumps (within 5 mm; measured ≤ 1.1 mm)
    with the same heading (0.05°); every later bump has the plain batch test's bounds (edge
    within 1 cm of a wall, never 2 mm into it; turns within 1.5°), and the turns, simulated
    in both (the default fast-forward does not jump them), end short by the same on average
    (within 0.1°; measured 0.25° and 0.27°, all 11 short). Later bumps
    are not compared point by point: a turn that starts touching a wall varies by a few
    tenths of a degree with the contact's details (plain physics: −0.67° to +0.04° here), so
    the two runs part after the first turn, as two plain runs from starts 1 mm apart would.
    """
    env = room(6, 4, K=72)
    cs = CellSpace(env)
    starts = [int(cs.z(p, k)) for p, k in ((0, 4), (7, 6), (14, 13), (17, 32))]
    cs, plain, fast = _runs(env, 90.0, starts, 10, (0, 1, 2, 3))
    for a, b in zip(plain.turns, fast.turns):
        (xa, ya, ha, *_), (xb, yb, hb, *_) = a[0], b[0]
        assert math.hypot(xa - xb, ya - yb) <= 0.005
        assert abs((ha - hb + 180) % 360 - 180) <= 0.05
    rows = [t for per in fast.turns for t in per]
    assert len(rows) >= 8
    xy = np.array([(x, y) for x, y, *_ in rows])
    gaps = shapely.distance(shapely.points(xy), env.walls) - (env.robot_radius - 0.002)
    assert gaps.min() >= -0.002 and gaps.max() <= 0.01
    def errors(run):
        return np.array([(after - before - turn + 180.0) % 360.0 - 180.0
                         for per in run.turns for _, _, before, turn, after in per])
    err = errors(fast)
    assert np.abs(err).max() <= 1.5 and abs(err.mean() - errors(plain).mean()) <= 0.1
    assert fast.skipped.sum() > 0.5 * plain.physics_steps * len(starts)


def test_a_slide_is_fast_forwarded_to_the_same_corner():
    """A robot heading 5° into the south wall of an empty 2.04 m x 0.68 m room slides along it
    (incidence below the bumper's 10° blind angle) to the east wall, 1.7 m on, and bumps
    there: with and without the fast-forward the bump is at the corner (x = 2.04 − r within
    1 cm, on the south wall), after the same number of steps, and the slide was jumped.
    """
    env = room(6, 2, K=72)
    cs = CellSpace(env)
    start = int(cs.z(0, 71))                            # cell (0, 0) facing −5°
    _, plain, fast = _runs(env, 90.0, [start], 8, (0,))
    r = env.robot_radius
    for run in (plain, fast):
        x, y, heading, *_ = run.turns[0][0]
        assert abs(x - (2.04 - r)) <= 0.01 and abs(y - r) <= 0.01
        assert abs((heading + 5 + 180) % 360 - 180) <= 1.0     # slid with its heading kept
    assert len(plain.turns[0]) == len(fast.turns[0])
    assert np.allclose([t[:2] for t in plain.turns[0]], [t[:2] for t in fast.turns[0]],
                       rtol=0, atol=0.01)
    assert np.array_equal(plain.counts, fast.counts)
    assert fast.skipped[0] > 0.5 * plain.physics_steps


def test_fast_forward_settings_are_checked():
    from bouncesim.robots.pybullet.fastforward import FastForward
    with pytest.raises(UserError):
        FastForward(margin=0.0)
    with pytest.raises(UserError):
        FastForward(turn_steps=0)
