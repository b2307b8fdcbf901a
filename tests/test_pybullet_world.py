"""The PyBullet Create 2 (bouncesim.robots.pybullet): wall geometry, bumps, turns, encoders,
determinism, recording and the paper's Fig. 3 plans.

Geometry tests need no physics; the others are marked ``physics``. Independent evidence:
exact polygon areas and shapely set operations for the wall geometry, the kinematic twin's
closed-form contact point for where a bump must stop, hand-computed encoder counts, and the
step model (planners) for plan outcomes.
"""

from __future__ import annotations

import doctest
import importlib.util
import math
import sys
from dataclasses import replace

import numpy as np
import pytest
import shapely
from shapely.geometry import Polygon

import envs
from bouncesim.robots import wall_pieces as pbwalls
from bouncesim.robots.base import RobotError
from bouncesim.robots.pybullet import robot as pbw
from bouncesim.robots.wall_pieces import convex_pieces, ear_clip, wall_pieces
from envs import UserError

from .conftest import room

HAVE_PYBULLET = importlib.util.find_spec("pybullet") is not None
needs_pybullet = pytest.mark.skipif(not HAVE_PYBULLET, reason="pybullet is not installed")


def hdiff(a: float, b: float) -> float:
    """A − b for headings [deg], wrapped to (−180, 180]."""
    return (a - b + 180.0) % 360.0 - 180.0


def make(env, **kw):
    from bouncesim.robots.pybullet import PyBulletRobot
    return PyBulletRobot(env, **kw)


def gap_to_walls(bot) -> float:
    """Distance [m] from the simulated body's edge to the nearest wall (negative: inside)."""
    x, y, _ = bot.true_pose()
    return float(shapely.distance(shapely.points(x, y), bot.env.walls)) - bot.body_radius


# =============================================================================== geometry
L_BLOCK = Polygon([(0, 0), (2, 0), (2, 1), (1, 1), (1, 2), (0, 2)])
ZIGZAG = Polygon([(0, 0), (4, 0), (4, 1), (3, 0.4), (2, 1), (1, 0.4), (0, 1)])


def _check_partition(poly: Polygon, pieces) -> None:
    assert all(p.is_valid and p.area > 0 for p in pieces)
    assert all(p.convex_hull.area - p.area <= 1e-9 for p in pieces), "a piece is not convex"
    assert math.isclose(sum(p.area for p in pieces), poly.area, rel_tol=1e-9), "overlap/gap"
    assert shapely.union_all(pieces).symmetric_difference(poly).area <= 1e-9


@pytest.mark.parametrize("poly", [L_BLOCK, ZIGZAG,
                                  Polygon([(0, 0), (1, 0), (1, 1), (0.5, 1), (0, 1)])],
                         ids=["L", "zigzag", "collinear"])
def test_ear_clip_partitions_the_polygon(poly):
    tris = ear_clip(poly)
    _check_partition(poly, tris)
    assert all(len(t.exterior.coords) == 4 for t in tris)
    # a simple polygon with n corners has n - 2 triangles (fewer when collinear corners
    # are dropped, but never fewer than without them)
    n = len(poly.exterior.coords) - 1
    n_min = len(shapely.simplify(poly, 0).exterior.coords) - 1
    assert n_min - 2 <= len(tris) <= n - 2


def test_ear_clip_either_winding():
    cw = Polygon(list(L_BLOCK.exterior.coords)[::-1])
    _check_partition(cw, ear_clip(cw))


@pytest.mark.parametrize("name", envs.names())
def test_convex_pieces_of_catalogue_obstacles(name):
    env = envs.load(name)
    for ob in env.obstacles:
        pieces = convex_pieces(ob)
        _check_partition(ob, pieces)
        convex = ob.convex_hull.area - ob.area <= 1e-9
        assert (len(pieces) == 1) == convex


def test_convex_pieces_merge_triangles():
    # the L splits into at best 2 convex parts; triangles merge into at most 3
    assert 2 <= len(convex_pieces(L_BLOCK)) <= 3
    # the same with the fallback triangulation (shapely < 2.1)
    pieces = pbwalls._merge_convex(ear_clip(L_BLOCK))
    _check_partition(L_BLOCK, pieces)
    assert len(pieces) == 2


@pytest.mark.parametrize("boundary", [
    envs.load("lab").boundary, envs.load("complex").boundary,
    Polygon([(0, 0), (3, 0), (1.2, 2.5)]),                                  # acute corners
    Polygon([(0, 0), (2, 0), (2, 2), (1, 0.8), (0, 2)]),                   # reflex corner
    Polygon(list(envs.load("complex").boundary.exterior.coords)[::-1]),    # clockwise
], ids=["lab", "complex", "triangle", "arrow", "complex-cw"])
def test_wall_pieces_seal_the_room_from_outside(boundary):
    t = 0.1
    slabs = wall_pieces(boundary, t)
    assert len(slabs) == len(boundary.exterior.coords) - 1
    assert all(s.is_valid and s.convex_hull.area - s.area <= 1e-9 for s in slabs)
    walls = shapely.union_all(slabs)
    # nothing of the room is inside a wall ...
    assert walls.intersection(boundary).area <= 1e-9
    # ... and every point outside the room within t/2 of it is (no gap at any corner)
    band = boundary.buffer(t / 2, join_style="round").difference(boundary)
    assert band.difference(walls).area <= 1e-9
    # the walls' inner faces run along the whole boundary
    assert boundary.exterior.difference(walls.buffer(1e-9)).length <= 1e-9


# =============================================================================== errors
def test_missing_pybullet_is_one_sentence(monkeypatch):
    monkeypatch.setitem(sys.modules, "pybullet", None)
    with pytest.raises(UserError, match=r"pip install 'bouncesim\[sim\]'"):
        pbw.import_pybullet()


@needs_pybullet
def test_gui_without_display_is_a_user_error(monkeypatch):
    if not sys.platform.startswith("linux"):
        pytest.skip("the display check is for Linux")
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    with pytest.raises(UserError, match="display") as err:
        make("lab", gui=True)
    assert "--gui" in str(err.value)           # the CLI user's words, not only Python's


@needs_pybullet
@pytest.mark.parametrize("kw,match", [
    ({"turn": "compass"}, "turn must be"), ({"solver": "magic"}, "solver must be"),
    ({"turn_speed": 0.9}, "turn_speed"), ({"back_off": -0.01}, "back_off"),
    ({"record": "run.avi2"}, "gif"),
])
def test_bad_arguments(kw, match):
    with pytest.raises(UserError, match=match):
        make("lab", **kw)


@needs_pybullet
def test_mp4_needs_imageio_ffmpeg(tmp_path):
    if importlib.util.find_spec("imageio_ffmpeg") is not None:
        pytest.skip("imageio-ffmpeg is installed")
    with pytest.raises(UserError, match="imageio-ffmpeg"):
        make("lab", record=tmp_path / "run.mp4")


@needs_pybullet
@pytest.mark.physics
def test_interface_errors_and_close():
    bot = make("lab")
    with pytest.raises(UserError, match="limit"):
        bot.drive(0.7)
    with pytest.raises(UserError):
        bot.wait(-1.0)
    bot.close()
    bot.close()                                   # idempotent
    with pytest.raises(RobotError):
        bot.drive(0.1)


# =============================================================================== physics
@needs_pybullet
@pytest.mark.physics
def test_default_start_and_place():
    env = envs.load("lab")
    with make(env) as bot:
        x, y, h = bot.true_pose()
        assert (x, y) == pytest.approx((0.17, 0.17), abs=1e-6) and h == pytest.approx(0.0)
        bot.place(1.2, 0.6, 250.0)
        x, y, h = bot.true_pose()
        assert (x, y) == pytest.approx((1.2, 0.6), abs=1e-6)
        assert hdiff(h, 250.0) == pytest.approx(0.0, abs=1e-6)
        assert bot.clock() == 0.0
        with pytest.raises(UserError, match="overlap a wall"):
            bot.place(1.2, 1.1, 0.0)                             # inside the interior block
        with pytest.raises(UserError, match="overlap a wall"):
            bot.place(0.1, 1.0, 0.0)                             # 0.1 m from the west wall
        bot.wait(0.015)
        assert bot.clock() == pytest.approx(0.015)          # 3 steps of 5 ms, no drift
        for _ in range(200):
            bot.wait(0.015)
        assert bot.clock() == pytest.approx(201 * 0.015, abs=1e-12)


@needs_pybullet
@pytest.mark.physics
@pytest.mark.parametrize("heading", [0, 30, 90, 135, 200, 250, 300, 330])
def test_bump_stops_within_1cm_of_the_wall(heading):
    """From (0.68, 0.51) in the lab: the stop pose is within 1 cm of the exact contact point
    of a disk of the body's radius (the kinematic twin's closed form), and the body's edge is
    within 1 cm of the wall (never more than 2 mm into it), also 0.5 s after the stop.
    """
    from bouncesim.robots.kinematic import KinematicRobot
    env = envs.load("lab")
    with make(env) as bot:
        twin = KinematicRobot(replace(env, robot_radius=bot.body_radius))
        bot.place(0.68, 0.51, heading)
        twin.place(0.68, 0.51, heading)
        ev = bot.drive_until_bump(0.2, 30.0)
        exact = twin.drive_until_bump(0.2, 30.0)
        assert ev.bumped and exact.bumped
        x, y, _ = bot.true_pose()
        xe, ye, _ = twin.true_pose()
        assert math.hypot(x - xe, y - ye) <= 0.01, (x, y, xe, ye)
        assert -0.002 <= gap_to_walls(bot) <= 0.01
        bot.wait(0.5)
        x2, y2, h2 = bot.true_pose()
        assert math.hypot(x2 - x, y2 - y) <= 0.002, "the robot kept moving after the bump"
        assert -0.002 <= gap_to_walls(bot) <= 0.01
        assert abs(hdiff(h2, heading)) <= 1.0


@needs_pybullet
@pytest.mark.physics
@pytest.mark.parametrize("heading,expect", [
    (90, (True, True)), (60, (True, False)), (120, (False, True)),       # north wall
    (180, (True, True)), (150, (True, False)), (210, (False, True)),     # west wall
])
def test_bumper_left_right_split(heading, expect):
    """Approaching a wall at +30° / −30° to its normal closes one switch (the side of the
    contact); head-on closes both.
    """
    env = room(6, 4)                                       # 2.04 m x 1.36 m
    with make(env, start=(1.02, 0.68, heading)) as bot:
        ev = bot.drive_until_bump(0.2, 20.0)
        assert ev.bumped
        assert (ev.left, ev.right) == expect


@needs_pybullet
@pytest.mark.physics
def test_bumper_ignores_parallel_and_rear_contacts():
    env = room(6, 4)
    with make(env, start=(1.02, 1.36 - 0.17, 90.0)) as bot:
        ev = bot.drive_until_bump(0.2, 5.0)               # already at the north wall
        assert ev.bumped and ev.elapsed <= 0.05
        bot.turn(90)                                      # now parallel to it, facing west
        assert bot.bumper() == (False, False)
        ev = bot.drive_until_bump(0.2, 20.0)              # slides along to the west wall
        assert ev.bumped and ev.left and ev.right
        x, y, h = bot.true_pose()
        assert x == pytest.approx(0.17, abs=0.01) and y == pytest.approx(1.19, abs=0.01)
        # backing into the east wall is not a bump (the bumper is the front half)
        bot.place(2.04 - 0.3, 0.68, 180.0)
        ev = bot.drive_until_bump(-0.2, 3.0)
        assert not ev.bumped
        assert bot.true_pose()[0] == pytest.approx(2.04 - 0.17, abs=0.01)


@needs_pybullet
@pytest.mark.physics
@pytest.mark.parametrize("mode", ["clock", "encoders"])
def test_turn_error_over_20_turns(mode):
    """20 bump-and-turn cycles in the lab (the executor's use): mean |error| ≤ 2°, each ≤ 3°;
    the body's own heading change is the reference (true pose).
    """
    angles = [45, 90, 135, 30, 75, 315]
    env = envs.load("lab")
    errs = []
    with make(env, turn=mode, start=(0.68, 0.68, 0.0)) as bot:
        for i in range(20):
            a = angles[i % len(angles)]
            if i % 2:
                assert bot.drive_until_bump(0.2, 30.0).bumped
            h0 = bot.true_pose()[2]
            bot.turn(a)
            errs.append(hdiff(bot.true_pose()[2] - h0, a))
    errs = np.abs(errs)
    assert errs.mean() <= 2.0 and errs.max() <= 3.0, errs


@needs_pybullet
@pytest.mark.physics
def test_turn_applies_the_noise_sample_and_back_off():
    class Plus10:
        def sample(self, rng, commanded_deg):
            return commanded_deg + 10.0

    env = room(6, 4)
    with make(env, noise=Plus10(), rng=0, back_off=0.01, start=(1.02, 0.68, 0.0)) as bot:
        assert bot.drive_until_bump(0.2, 20.0).bumped
        x0, y0, h0 = bot.true_pose()
        bot.turn(90)
        x1, y1, h1 = bot.true_pose()
        assert abs(hdiff(h1 - h0, 100.0)) <= 1.0
        assert x0 - x1 == pytest.approx(0.01, abs=0.003)     # backed off west by ~1 cm
        assert abs(y1 - y0) <= 0.002


@needs_pybullet
@pytest.mark.physics
def test_encoders_count_wheel_travel():
    """1 m of straight driving is 1 / (π · 0.072 / 508.8) = 2249.4 counts per wheel; a 90°
    turn is ±(π/2 · 0.235/2) / 0.4446 mm = ±415.1 counts.
    """
    env = envs.load("lab")
    with make(env, start=(0.4, 0.68, 0.0)) as bot:
        e0 = bot.encoders()
        bot.drive(0.2)
        bot.wait(5.0)
        bot.stop()
        bot.wait(0.1)
        e1 = bot.encoders()
        travelled = bot.true_pose()[0] - 0.4
        assert travelled == pytest.approx(1.0, abs=0.01)
        for d in (e1[0] - e0[0], e1[1] - e0[1]):
            assert isinstance(d, int)
            assert d == pytest.approx(2249.4 * travelled, rel=0.005)
        bot.turn(90)
        e2 = bot.encoders()
        assert e2[0] - e1[0] == pytest.approx(-415.1, abs=6)
        assert e2[1] - e1[1] == pytest.approx(415.1, abs=6)


@needs_pybullet
@pytest.mark.physics
def test_same_seed_same_trajectory_and_robots_coexist():
    try:
        from bouncesim.robots.noise import GaussianNoise
        noise = GaussianNoise(3.0)
    except ImportError:                                   # pragma: no cover
        class GaussianNoise:
            def sample(self, rng, deg):
                return deg + rng.normal(0, 3.0)
        noise = GaussianNoise()
    env = envs.load("lab")
    a = make(env, noise=noise, rng=7)
    b = make(env, noise=noise, rng=7)                    # two worlds at once, interleaved
    c = make(env, noise=noise, rng=8)
    try:
        for _ in range(6):
            for bot in (a, b, c):
                bot.drive_until_bump(0.2, 30.0)
                bot.turn(135)
        assert a.true_pose() == b.true_pose()
        assert a.clock() == b.clock() and a.encoders() == b.encoders()
        pa, pc = a.true_pose(), c.true_pose()
        assert math.hypot(pa[0] - pc[0], pa[1] - pc[1]) > 0.01   # the seed matters
    finally:
        for bot in (a, b, c):
            bot.close()


@needs_pybullet
@pytest.mark.physics
def test_non_convex_obstacle_fig1_L_block():
    """The robot driving into the L block's concave corner stops with both inner faces
    touching (centre (1.02 + r', 1.02 + r')), both switches closed; it never enters it.
    """
    env = envs.load("fig1")
    with make(env, start=(1.53, 1.53, 225.0)) as bot:
        ev = bot.drive_until_bump(0.2, 10.0)
        assert ev.bumped and ev.left and ev.right
        x, y, _ = bot.true_pose()
        c = 1.02 + bot.body_radius
        assert math.hypot(x - c, y - c) <= 0.01, (x, y)
        assert gap_to_walls(bot) >= -0.002


@needs_pybullet
@pytest.mark.physics
@pytest.mark.parametrize("name", ["fig1", "complex"])
def test_bounce_never_penetrates(name):
    """40 s of bouncing in fig1 (L block, triangles, a stub wall) and complex (L-shaped
    room, L block, pillars, a partition): at every 15 ms sample the body is less than 3 mm
    into any wall, and never outside the free space.
    """
    env = envs.load(name)
    walls = env.walls
    angles = [135, 90, 45, 135, 270]
    worst, bumps = np.inf, 0
    with make(env) as bot:
        while bot.clock() < 40.0:
            bot.drive(0.2)
            while not any(bot.bumper()) and bot.clock() < 40.0:
                bot.wait(0.015)
                x, y, _ = bot.true_pose()
                d = float(shapely.distance(shapely.points(x, y), walls))
                inside = env.free_space.covers(shapely.points(x, y))
                worst = min(worst, (d if inside else -d) - bot.body_radius)
            bot.stop()
            bot.turn(angles[bumps % len(angles)])
            bumps += 1
    assert bumps >= 5
    assert worst >= -0.003, f"{-worst * 1000:.1f} mm into a wall"


@needs_pybullet
@pytest.mark.physics
@pytest.mark.parametrize("mode", ["clock", "encoders"])
@pytest.mark.parametrize("start,goal", [(8, 0), (103, 8)])
def test_fig3_plans_succeed_in_pybullet(mode, start, goal):
    """The paper's Fig. 3 plans in the lab with angles {90°, 135°}, without rotation noise,
    run by the plan executor on the PyBullet Create 2.
    """
    if importlib.util.find_spec("bouncesim.runs.execute") is None:
        pytest.skip("bouncesim.runs.execute (the plan executor) is not there yet")
    from bouncesim.runs.execute import execute
    from planners.cells import CellSpace
    env = envs.load("lab")
    cells = CellSpace(env)
    try:
        from planners.navigation import Navigator
        plan = Navigator(cells, [90, 135]).plan(start, goal).plan
    except ImportError:                                   # pragma: no cover
        plan = {(8, 0): "90° 90° 00000000 90° 90°", (103, 8): "135° 135° 0"}[(start, goal)]
    with make(env, turn=mode) as bot:
        run = execute(plan, bot, start=start, goal=goal, cells=cells)
    assert run.success, run.reason
    assert not run.deviations
    assert run.position_error <= 0.02 and abs(run.heading_error) <= 2.0


@needs_pybullet
@pytest.mark.physics
def test_gif_recording(tmp_path):
    import imageio.v3 as iio
    out = tmp_path / "run.gif"
    with make("lab", record=out, record_width=96) as bot:
        bot.drive(0.2)
        bot.wait(1.0)
        n = len(bot.frames)
    assert n == 10                                       # every 0.1 s of simulated time
    frames = iio.imread(out, index=None)
    assert frames.shape[0] == n and frames.shape[2] == 96
    assert np.abs(frames[0].astype(int) - frames[-1].astype(int)).max() > 0   # it moved


def test_doctests():
    result = doctest.testmod(pbwalls, optionflags=doctest.ELLIPSIS)
    assert result.attempted > 0 and result.failed == 0
