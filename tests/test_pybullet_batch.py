"""Many Create 2 bodies in one PyBullet world (bouncesim.robots.pybullet.batch).

Independent evidence: the single-robot path (``execute`` on a ``PyBulletRobot``, same start,
same noise seed), two robots started on the same pose (if they collided they would push each
other apart), the exact wall geometry for where a bump stops, and the noise sample each turn
was commanded with.
"""

from __future__ import annotations

import importlib.util
import math

import numpy as np
import pytest
import shapely

import envs
from planners.cells import CellSpace
from planners.plan import PolicyMix

pytestmark = [pytest.mark.physics,
              pytest.mark.skipif(importlib.util.find_spec("pybullet") is None,
                                 reason="pybullet is not installed")]

MIX = PolicyMix((75.0,), (1.0,), 5.0, 0.8)


@pytest.fixture(scope="module")
def lab72():
    env = envs.load("lab", orientations=72)
    return env, CellSpace(env)


def _noise(cs):
    from bouncesim.robots.noise import noise_for_mix
    return noise_for_mix(MIX, cs.delta_deg)


def test_batch_robot_follows_the_single_robot(lab72):
    """Robot i of a batch with generator seed s bumps within 1 cm of the same wall points,
    in the same order, as one PyBulletRobot run by execute() with seed s (same physics, every
    physics step: the fast-forward is pinned against this path in test_pybullet_fast.py).
    """
    from bouncesim.robots.pybullet import PyBulletRobot
    from bouncesim.robots.pybullet.batch import BATCH_PHYSICS, PyBulletBatch
    from bouncesim.runs.execute import execute
    env, cs = lab72
    seeds, steps = (0, 1, 2), 40
    with PyBulletBatch(env, len(seeds), rngs=[np.random.default_rng(s) for s in seeds],
                       cells=cs, noise=_noise(cs), fast_forward=None) as batch:
        res = batch.run(MIX, steps, record=True)
    for i, s in enumerate(seeds):
        rng = np.random.default_rng(s)
        with PyBulletRobot(env, noise=_noise(cs), rng=rng, **BATCH_PHYSICS) as bot:
            run = execute(MIX, bot, steps=steps, epoch=1000, rng=rng, cells=cs, speed=0.3)
        single = [(r.x, r.y) for r in run.trace.events("bump")]
        batched = [(x, y) for x, y, *_ in res.turns[i]]
        assert len(single) == len(batched) == run.bumps == res.bumps[i] > 5
        for (x, y), (xb, yb) in zip(single, batched):
            assert math.hypot(x - xb, y - yb) <= 0.01
        assert np.array_equal(run.counts, res.counts[i])


def test_robots_ignore_each_other(lab72):
    """Two robots started on the same pose with the same seed overlap all the time; with
    robot-robot collisions filtered out they move exactly alike.
    """
    from bouncesim.robots.pybullet.batch import PyBulletBatch
    env, cs = lab72
    with PyBulletBatch(env, 2, rngs=[np.random.default_rng(7), np.random.default_rng(7)],
                       starts=[130, 130], cells=cs, noise=_noise(cs)) as batch:
        res = batch.run(MIX, 25, record=True)
    assert res.bumps[0] > 3
    assert np.array_equal(res.counts[0], res.counts[1])
    assert np.allclose(res.poses[0], res.poses[1], atol=1e-9)


def test_batch_bumps_at_the_wall_and_turns_accurately(lab72):
    """Every bump of 8 robots stops with the body's edge within 1 cm of a wall (never more
    than 2 mm into it), and every turn executes the noise-sampled angle within 1.5° (mean
    within 0.25°). Turns start touching the wall; with Bullet's default contact settings
    (the single robot's) the same run measured mean 0.17°, max 1.18°; with the batch's
    0.17° and 1.06°.
    """
    from bouncesim.robots.pybullet.batch import PyBulletBatch
    env, cs = lab72
    with PyBulletBatch(env, 8, 3, cells=cs, noise=_noise(cs)) as batch:
        res = batch.run(MIX, 40, record=True)
        radius = batch.host.body_radius
    rows = [t for per in res.turns for t in per]
    assert len(rows) > 40
    xy = np.array([(x, y) for x, y, *_ in rows])
    gaps = shapely.distance(shapely.points(xy), env.walls) - radius
    assert gaps.min() >= -0.002 and gaps.max() <= 0.01
    err = np.array([(after - before - turn + 180.0) % 360.0 - 180.0
                    for _, _, before, turn, after in rows])
    assert np.abs(err).max() <= 1.5 and np.abs(err).mean() <= 0.25


def test_halves_are_independent_robots(lab72):
    """BatchRun.halves splits the robots (even / odd), and the floor is their TV."""
    from bouncesim.robots.batch_run import BatchRun
    counts = np.array([[2, 0], [0, 1], [1, 1]])
    run = BatchRun(counts=counts, dropped=np.zeros(3, int), bumps=np.zeros(3, int), steps=2,
                   physics_steps=0, sim_time=0.0, wall_s=0.0, cpu_s=0.0)
    a, b = run.halves()
    assert a.tolist() == [3, 1] and b.tolist() == [0, 1]
    assert run.floor() == pytest.approx(0.75)     # ½ (|3/4 − 0| + |1/4 − 1|)
    assert run.total == 5
