"""The kinematic twin: hand-computed bounces, an independent ray-cast reference, the polling
default, determinism, and the batch against the discrete step table (docs/model.md §7, §8, §21).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import shapely

import envs
from bouncesim.robots.base import Robot
from bouncesim.robots.kinematic import (
    CONTACT_GAP,
    KinematicBatch,
    KinematicRobot,
    LocalCaster,
    WallCaster,
    unit,
)
from bouncesim.robots.noise import GaussianNoise, SteppedNoise
from envs import UserError
from planners.cells import CellSpace
from planners.plan import PolicyMix

from .conftest import room

SPEED = 0.2


@pytest.fixture(scope="module")
def lab():
    return envs.load("lab")


@pytest.fixture(scope="module")
def complex_env():
    return envs.load("complex")


def _wall_distance(env, x, y):
    return float(shapely.distance(shapely.points([x, y]), env.walls))


# ------------------------------------------------------------------ hand-computed geometry
def test_bounce_at_30_degrees_by_hand():
    env = room(5, 3)                         # 1.70 m x 1.02 m, r = 0.17
    bot = KinematicRobot(env)
    bot.place(0.5, 0.3, 30.0)
    # north wall: the centre reaches y = 1.02 - 0.17 = 0.85 after t = 0.55 / sin 30° = 1.1 m;
    # the east wall would need (1.53 - 0.5) / cos 30° = 1.189 m
    ev = bot.drive_until_bump(SPEED, 60.0)
    assert ev.bumped
    assert ev.elapsed == pytest.approx(1.1 / SPEED, abs=1e-8)
    x, y, h = bot.true_pose()
    assert (x, y) == pytest.approx((0.5 + 1.1 * math.cos(math.radians(30)), 0.85), abs=1e-8)
    assert h == 30.0
    # contact point (1.4526, 1.02) at bearing 60° left of the heading: left switch only
    assert (ev.left, ev.right) == (True, False)
    assert bot.bumper() == (True, False)


def test_ninety_degree_bounce_sequence_by_hand():
    env = room(5, 3)
    bot = KinematicRobot(env, turn_speed=0.1)
    bot.place(0.85, 0.51, 0.0)
    # E wall after 0.68 m, N after 0.34, W after 1.36, S after 0.68, E again after 1.36
    expect = [((1.53, 0.51), 0.68), ((1.53, 0.85), 0.34), ((0.17, 0.85), 1.36),
              ((0.17, 0.17), 0.68), ((1.53, 0.17), 1.36)]
    t_turn = bot.spec.turn_time(90, 0.1)            # pi/2 / (2 * 0.1 / 0.235) = 1.8457 s
    assert t_turn == pytest.approx(math.pi / 2 * 0.235 / 0.2)
    for i, ((ex, ey), dist) in enumerate(expect):
        t0 = bot.clock()
        ev = bot.drive_until_bump(SPEED, 60.0)
        assert ev.bumped and ev.left and ev.right
        assert ev.elapsed == pytest.approx(dist / SPEED, abs=1e-8)
        assert bot.clock() - t0 == pytest.approx(ev.elapsed)
        assert bot.true_pose()[:2] == pytest.approx((ex, ey), abs=1e-8)
        t1 = bot.clock()
        bot.turn(90.0)
        assert bot.clock() - t1 == pytest.approx(t_turn)
        assert bot.true_pose()[2] == (90.0 * (i + 1)) % 360


def test_corner_contact_by_hand():
    # block [1.0, 1.34] x [0.5, 0.84]: its bottom-left corner V = (1.0, 0.5)
    env = envs.Environment.from_dict({
        "boundary": [[0, 0], [2.04, 0], [2.04, 1.36], [0, 1.36]],
        "obstacles": [[[1.0, 0.5], [1.34, 0.5], [1.34, 0.84], [1.0, 0.84]]],
        "robot_radius": 0.17, "discretization": {"cell_size": 0.34, "orientations": 8}})
    bot = KinematicRobot(env)
    bot.place(0.3, 0.4, 0.0)                 # passes 0.1 m below V: touches the corner
    ev = bot.drive_until_bump(SPEED, 60.0)
    x_hit = 1.0 - math.sqrt(0.17 ** 2 - 0.1 ** 2)   # 0.862518
    assert ev.bumped and bot.true_pose()[0] == pytest.approx(x_hit, abs=1e-8)
    # bearing of V: atan2(0.1, 0.1375) = 36° to the left
    assert (ev.left, ev.right) == (True, False)
    # passing exactly r below V (tangent) is not a contact: on to the east wall
    bot.place(0.3, 0.5 - 0.17, 0.0)
    ev = bot.drive_until_bump(SPEED, 60.0)
    assert ev.bumped and bot.true_pose()[0] == pytest.approx(2.04 - 0.17, abs=1e-8)


def test_parallel_to_touching_wall_is_free(lab):
    bot = KinematicRobot(lab)
    bot.place(0.17, 0.17, 0.0)           # touches the south and west walls
    assert bot.bumper() == (False, False)
    ev = bot.drive_until_bump(SPEED, 100.0)
    # along the south wall, under the block that touches the east wall, to x = 2.89
    assert ev.bumped and bot.true_pose()[0] == pytest.approx(2.89, abs=1e-8)


def test_unit_snaps_axis_headings():
    assert unit(90.0).tolist() == [0.0, 1.0]
    assert unit(np.array([180.0, 270.0])).tolist() == [[-1.0, 0.0], [0.0, -1.0]]


# ------------------------------------------------------------------ independent reference
def _reference_cast(env, c, u, hi):
    """First contact distance by bisection on shapely's segment-to-wall distance."""
    lo = 0.0
    seg = lambda t: shapely.linestrings([c, c + t * u])  # noqa: E731
    if shapely.distance(seg(hi), env.walls) >= env.robot_radius:
        return np.inf
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if shapely.distance(seg(mid), env.walls) >= env.robot_radius:
            lo = mid
        else:
            hi = mid
    return lo


@pytest.mark.parametrize("name", ["complex", "fig1"])
def test_ray_cast_matches_shapely_bisection(name):
    env = envs.load(name)
    rng = np.random.default_rng(11)
    x0, y0, x1, y1 = env.bounds
    pts = rng.uniform([x0, y0], [x1, y1], size=(600, 2))
    pts = pts[env.points_free(pts)][:150]
    ang = rng.uniform(0, 360, size=len(pts))
    u = unit(ang)
    caster = WallCaster(env.wall_segments, env.robot_radius)
    got = caster.cast(pts, u)
    diag = math.hypot(x1 - x0, y1 - y0)
    ref = np.array([_reference_cast(env, c, d, diag) for c, d in zip(pts, u)])
    assert np.all(np.isfinite(got))
    assert np.allclose(got, ref, atol=1e-7)
    # the local caster agrees wherever the contact is nearer than its range
    local = LocalCaster(caster, 0.34).cast(pts, u)
    near = got < 0.34
    assert near.sum() > 10
    assert np.allclose(local[near], got[near], atol=1e-12)
    assert np.all(local[~near] >= 0.34 - 1e-12)


def test_local_caster_grid_stays_small_for_a_point_robot():
    # found by fuzzing: the fine grid was r / 2, so a 1e-12 m robot asked for a 2e12 x 2e12
    # grid; the grid is now bounded and the local cast still agrees with the full one
    segs = np.array([[[0, 0], [1, 0]], [[1, 0], [1, 1]], [[1, 1], [0, 1]], [[0, 1], [0, 0]]],
                    dtype=float)
    caster = WallCaster(segs, 1e-12)
    local = LocalCaster(caster, 0.25)
    assert local.nx * local.ny <= 1024 ** 2
    rng = np.random.default_rng(3)
    pts = rng.uniform(0.05, 0.95, size=(400, 2))
    u = unit(rng.uniform(0, 360, size=400))
    full = caster.cast(pts, u)
    got = local.cast(pts, u)
    near = full < 0.25
    assert near.sum() > 20
    assert np.allclose(got[near], full[near], atol=1e-12)
    assert np.all(got[~near] >= 0.25 - 1e-12)


def test_ray_cast_from_contact_and_parallel(lab):
    caster = WallCaster(lab.wall_segments, lab.robot_radius)
    # touching the west wall: into it 0, along it the far wall, away from it the east side
    c = np.array([[0.17, 0.51]] * 3)
    t = caster.cast(c, unit(np.array([180.0, 90.0, 0.0])))
    assert t[0] == 0.0
    assert t[1] == pytest.approx(2.04 - 0.17 - 0.51)
    assert t[2] == pytest.approx(2.38 - 0.17 - 0.17)   # the block on the east wall


# ------------------------------------------------------------------ Robot semantics
def test_exact_drive_until_bump_agrees_with_polling_default(complex_env):
    rng = np.random.default_rng(5)
    env = complex_env
    x0, y0, x1, y1 = env.bounds
    pts = rng.uniform([x0, y0], [x1, y1], size=(400, 2))
    pts = pts[env.points_free(pts)][:40]
    period = KinematicRobot(env).spec.sensor_period
    for (x, y), h in zip(pts, rng.uniform(0, 360, len(pts))):
        exact, polled = KinematicRobot(env), KinematicRobot(env)
        exact.place(x, y, h)
        polled.place(x, y, h)
        a = exact.drive_until_bump(SPEED, 8.0)
        b = Robot.drive_until_bump(polled, SPEED, 8.0)       # the interface's polling loop
        assert a.bumped == b.bumped
        assert (a.left, a.right) == (b.left, b.right)
        assert b.elapsed - period - 1e-9 <= a.elapsed <= b.elapsed + 1e-9
        # both stop at the same contact (the polled robot stalls there until the next poll)
        assert np.allclose(exact.true_pose(), polled.true_pose(), atol=1e-9)
        assert exact.clock() == pytest.approx(a.elapsed)


def test_never_penetrates_and_stays_in_cspace(complex_env):
    env = complex_env
    bot = KinematicRobot(env, GaussianNoise(20.0), np.random.default_rng(2))
    bot.place(*CellSpace(env).pose(7))
    r = env.robot_radius
    for _ in range(300):
        ev = bot.drive_until_bump(SPEED, 60.0)
        assert ev.bumped
        x, y, _ = bot.true_pose()
        d = _wall_distance(env, x, y)
        assert r - 1e-12 <= d <= r + 1e-8, d - r
        assert env.free_space.covers(shapely.points([x, y]))
        bot.turn(135.0)


def test_contact_gap_is_tiny_and_documented(lab):
    bot = KinematicRobot(lab)
    bot.place(1.02, 0.51, 180.0)
    bot.drive_until_bump(SPEED, 60.0)
    x, _, _ = bot.true_pose()
    assert x - 0.17 == pytest.approx(CONTACT_GAP, abs=1e-12)


def test_backwards_contact_is_not_a_bump():
    env = room(5, 3)
    bot = KinematicRobot(env)
    bot.place(0.5, 0.51, 0.0)
    ev = bot.drive_until_bump(-SPEED, 4.0)         # backs into the west wall after 0.33 m
    assert not ev.bumped and ev.elapsed == pytest.approx(4.0)
    assert bot.true_pose()[0] == pytest.approx(0.17, abs=1e-8)
    assert bot.bumper() == (False, False)
    # the same with the polling default
    bot2 = KinematicRobot(env)
    bot2.place(0.5, 0.51, 0.0)
    ev2 = Robot.drive_until_bump(bot2, -SPEED, 4.0)
    assert not ev2.bumped and bot2.true_pose()[0] == pytest.approx(0.17, abs=1e-8)


def test_wait_moves_exactly_and_stop_halts():
    env = room(5, 3)
    bot = KinematicRobot(env)
    bot.place(0.3, 0.51, 0.0)
    bot.drive(0.25)
    bot.wait(2.0)
    assert bot.true_pose()[0] == pytest.approx(0.8)
    assert bot.clock() == pytest.approx(2.0)
    bot.stop()
    bot.wait(3.0)
    assert bot.true_pose()[0] == pytest.approx(0.8)
    bot.drive(0.25)
    bot.wait(100.0)                                 # stalls at the east wall
    assert bot.true_pose()[0] == pytest.approx(1.53, abs=1e-8)
    assert bot.bumper() == (True, True)


def test_encoders_count_wheel_travel():
    env = room(5, 3)
    bot = KinematicRobot(env)
    bot.place(0.3, 0.51, 0.0)
    mpc = bot.spec.metres_per_count
    bot.drive(0.2)
    bot.wait(2.0)
    assert bot.encoders() == (round(0.4 / mpc), round(0.4 / mpc))
    l0, r0 = bot.encoders()
    bot.turn(90.0)
    arc = math.pi / 2 * bot.spec.wheel_base / 2
    l1, r1 = bot.encoders()
    assert (r1 - r0) * mpc == pytest.approx(arc, abs=2 * mpc)
    assert (l1 - l0) * mpc == pytest.approx(-arc, abs=2 * mpc)


def test_turn_noise_and_determinism(lab):
    def trajectory(seed):
        bot = KinematicRobot(lab, SteppedNoise(45, 0.5, 45), np.random.default_rng(seed))
        bot.place(1.53, 0.51, 0.0)
        poses = []
        for _ in range(30):
            bot.drive_until_bump(SPEED, 60.0)
            bot.turn(135.0)
            poses.append(bot.true_pose())
        return poses
    a, b, c = trajectory(1), trajectory(1), trajectory(2)
    assert a == b
    assert a != c
    headings = {round(p[2]) % 45 for p in a}
    assert headings == {0}, "stepped noise keeps headings on multiples of delta"


def test_place_validates_and_noise_needs_rng(lab):
    bot = KinematicRobot(lab)
    with pytest.raises(UserError):
        bot.place(0.05, 0.05, 0.0)
    with pytest.raises(UserError):
        bot.place(2.7, 0.7, 0.0)                    # inside the block on the east wall
    with pytest.raises(ValueError):
        KinematicRobot(lab, GaussianNoise(1.0))
    with pytest.raises(UserError):
        bot.drive(0.6)


# ------------------------------------------------------------------ the batch
def _chain_counts(cells: CellSpace, starts, angle: float, steps: int) -> np.ndarray:
    """Visit counts per position cell from the discrete step table (docs/model.md §7)."""
    counts = np.zeros(cells.P, dtype=np.int64)
    fwd = cells.forward
    for z in starts:
        z = int(z)
        for _ in range(steps):
            counts[cells.pk(z)[0]] += 1
            z = int(fwd[z]) if fwd[z] >= 0 else int(cells.rotate(z, angle))
    return counts


@pytest.mark.parametrize("env_name,angle,K", [("room", 90.0, 4), ("room", 180.0, 4),
                                              ("lab", 90.0, 8), ("lab", 270.0, 8)])
def test_batch_tracks_the_step_table_on_axis_headings(env_name, angle, K):
    """On axis-aligned headings the continuous twin visits exactly the cells the discrete
    chain visits: walls are on grid lines and h = 2 r, so a blocked step bumps at once.
    """
    env = room(6, 4, obstacles=[(2, 1, 4, 2), (5, 2, 6, 4)], K=4) if env_name == "room" \
        else envs.load("lab")
    cells = CellSpace(env)
    axis_k = np.arange(0, cells.K, cells.K // 4)
    starts = (axis_k[:, None] * cells.P + np.arange(cells.P)[None, :]).ravel()
    batch = KinematicBatch(env, len(starts), np.random.default_rng(0), starts=starts)
    res = batch.run(angle, 60)
    expected = _chain_counts(cells, starts, angle, 60)
    assert res.dropped == 0
    assert np.array_equal(res.counts, expected)
    assert res.total == len(starts) * 60


def test_batch_accounting_and_coverage(complex_env):
    batch = KinematicBatch(complex_env, 300, np.random.default_rng(4))
    res = batch.run(135.0, 40, burn_in=5)
    assert res.total == 300 * 40
    assert res.dropped > 0                      # the complex env has unreachable-cell corners
    assert res.coverage.sum() == pytest.approx(1.0)
    assert 0 < res.bumps < res.total
    q = np.full(len(res.counts), 1.0)
    assert 0 <= res.tv(q) <= 1


def test_batch_determinism_and_mix(lab):
    mix = PolicyMix((90.0, 135.0), (0.5, 0.5), eps=45, r=0.5)
    a = KinematicBatch(lab, 100, np.random.default_rng(9)).run(mix, 50, epoch=10)
    b = KinematicBatch(lab, 100, np.random.default_rng(9)).run(mix, 50, epoch=10)
    c = KinematicBatch(lab, 100, np.random.default_rng(10)).run(mix, 50, epoch=10)
    assert np.array_equal(a.counts, b.counts)
    assert not np.array_equal(a.counts, c.counts)
    with pytest.raises(UserError, match="epoch"):
        KinematicBatch(lab, 10, np.random.default_rng(0)).run(mix, 5)
    with pytest.raises(UserError):
        KinematicBatch(lab, 10, np.random.default_rng(0)).run(100.0, 5)


def test_batch_noise_keeps_walls(complex_env):
    batch = KinematicBatch(complex_env, 200, np.random.default_rng(3))
    noise = GaussianNoise(5.0)
    for _ in range(100):
        batch.step(np.full(200, 135.0), noise)
    d = shapely.distance(shapely.points(batch.pos), complex_env.walls)
    assert np.all(d >= complex_env.robot_radius - 1e-12)


def test_scalar_and_vector_casts_are_bitwise_equal(complex_env):
    """The single robot (plain Python floats) and the batch (numpy) compute the same numbers,
    so a KinematicRobot and a KinematicBatch robot follow the same trajectory.
    """
    env = complex_env
    rng = np.random.default_rng(3)
    x0, y0, x1, y1 = env.bounds
    pts = rng.uniform([x0, y0], [x1, y1], size=(2000, 2))
    pts = pts[env.points_free(pts)][:300]
    u = unit(rng.choice([0.0, 45.0, 90.0, 135.0, 200.0, 333.3], size=len(pts)))
    full, local = WallCaster(env.wall_segments, env.robot_radius), None
    local = LocalCaster(full, env.cell_size)
    vec_full, vec_local = full.cast(pts, u), local.cast(pts, u)
    sc_full = [full.cast_one(x, y, a, b) for (x, y), (a, b) in zip(pts.tolist(), u.tolist())]
    sc_local = [local.cast_one(x, y, a, b) for (x, y), (a, b) in zip(pts.tolist(), u.tolist())]
    assert np.array_equal(vec_full, sc_full)
    near = vec_local < local.max_dist
    assert np.array_equal(vec_local[near], np.array(sc_local)[near])
    assert np.all(np.array(sc_local)[~near] >= local.max_dist)


# ------------------------------------------------------------------ glancing contacts (opt-in)
def test_glancing_contact_in_a_corridor_by_hand():
    env = room(5, 1)                         # a corridor exactly one robot wide, 1.70 m long
    default = KinematicRobot(env)
    default.place(0.17, 0.17, 1.0)
    ev = default.drive_until_bump(SPEED, 20.0)
    # the front-half bumper: the north wall at bearing 89° closes the left switch at once
    assert ev.bumped and ev.elapsed == 0.0 and (ev.left, ev.right) == (True, False)

    bot = KinematicRobot(env, glance_deg=80)
    bot.place(0.17, 0.17, 1.0)
    assert bot.bumper() == (False, False)
    ev = bot.drive_until_bump(SPEED, 20.0)
    # slides along the north wall at v cos 1° to the east wall, which it meets head-on
    assert ev.bumped and ev.left and ev.right
    assert bot.true_pose()[:2] == pytest.approx((1.53, 0.17), abs=1e-8)
    assert ev.elapsed == pytest.approx(1.36 / (SPEED * math.cos(math.radians(1.0))), rel=1e-9)
    assert bot.true_pose()[2] == 1.0


def test_glancing_corner_wrap_by_hand():
    # block [1.0, 1.34] x [0.5, 0.84]; the robot passes 1 mm too close to its corner (1.0, 0.5)
    env = envs.Environment.from_dict({
        "boundary": [[0, 0], [2.04, 0], [2.04, 1.36], [0, 1.36]],
        "obstacles": [[[1.0, 0.5], [1.34, 0.5], [1.34, 0.84], [1.0, 0.84]]],
        "robot_radius": 0.17, "discretization": {"cell_size": 0.34, "orientations": 8}})
    r, d, y0 = 0.17, 0.169, 0.5 - 0.169
    bot = KinematicRobot(env, glance_deg=80)
    bot.place(0.3, y0, 0.0)
    ev = bot.drive_until_bump(SPEED, 60.0)
    x_touch = 1.0 - math.sqrt(r * r - d * d)
    beta0 = math.atan2(d, math.sqrt(r * r - d * d))          # bearing of the corner, 83.8°
    assert math.degrees(beta0) > 80
    wrap = (r / SPEED) * -math.log(math.tan(beta0 / 2))
    # wraps to abeam the corner (y = 0.5 - r), then straight on to the east wall
    assert ev.bumped
    assert bot.true_pose()[:2] == pytest.approx((2.04 - r, 0.5 - r), abs=1e-8)
    expected = (x_touch - 0.3) / SPEED + wrap + (2.04 - r - 1.0) / SPEED
    assert ev.elapsed == pytest.approx(expected, rel=1e-9)
    # the default twin stops at the corner instead
    bot = KinematicRobot(env)
    bot.place(0.3, y0, 0.0)
    ev = bot.drive_until_bump(SPEED, 60.0)
    assert ev.bumped and ev.left and not ev.right
    assert bot.true_pose()[0] == pytest.approx(x_touch, abs=1e-8)


def test_glancing_model_never_penetrates(complex_env):
    env = complex_env
    bot = KinematicRobot(env, GaussianNoise(20.0), np.random.default_rng(8), glance_deg=80)
    bot.place(*CellSpace(env).pose(7))
    r = env.robot_radius
    slid = 0
    for _ in range(300):
        ev = bot.drive_until_bump(SPEED, 30.0)
        x, y, _ = bot.true_pose()
        d = _wall_distance(env, x, y)
        assert d >= r - 1e-9, d - r
        slid += not ev.bumped
        bot.turn(135.0)
    assert slid < 30   # almost every drive still ends in a bump
