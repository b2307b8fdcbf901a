"""The exact navigation planner (docs/model.md §13) and the exact plan format.

Independent evidence: closed-form flights in a rectangle room, a shapely ray cast against the
buffered C-space on random non-rectilinear rooms with a hole, and replays in the kinematic
twin (which executes by bump and clock only).
"""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest
from shapely.geometry import LineString, Point

import envs
from bouncesim.cli import main
from bouncesim.robots import make_robot
from bouncesim.runs.execute import execute
from envs import Environment
from envs.generated import PENTAGON
from experiments import nav_exact
from planners.cells import CellSpace
from planners.navigation.exact import ExactNavigator, chords
from planners.plan import Plan, PlanParseError

from .conftest import room

ANGLES = (45, 90, 135)


def _replay(env, cs, route):
    robot = make_robot("kinematic", env)
    return execute(route.plan, robot, start=route.start, goal=route.goal, cells=cs)


# ----------------------------------------------------------------------------- hand-computed
def test_rectangle_by_hand():
    """4 × 3 cells of 0.34 m, r = 0.17: the C-space is [0.17, 1.19] × [0.17, 0.85]. From cell
    (0, 0) facing east to cell (3, 2) facing north with Φ = {90°}: drive east 1.02 m to the
    wall (less the 1e-9 m contact gap), turn 90°, drive north to the goal cell's centre (the
    nearest point of the chord), which is the contact with the north wall: 0.68 m less the
    gap. Cost 1.02/0.34 + 1 + 0.68/0.34 = 6 (less 2e-9/0.34).
    """
    env = room(4, 3)
    cs = CellSpace(env)
    route = ExactNavigator(cs, [90]).plan(cs.z(0, 0), cs.z(11, 2))
    assert route.plan.turns == (90,)
    assert route.plan.flights_m[0] == pytest.approx(1.02 - 1e-9, abs=1e-12)
    assert route.plan.final_m == pytest.approx(0.68 - 1e-9, abs=1e-12)
    assert route.cost == pytest.approx(6.0, abs=1e-8)
    assert str(route.plan) == "000 90° 00"
    assert route.poses[-1][:2] == pytest.approx((1.19, 0.85), abs=1e-9)


def _box_flight(x, y, heading, lo, hi):
    """Closed form: distance from (x, y) along heading to the box [lo, hi]² of the C-space."""
    ux, uy = math.cos(math.radians(heading)), math.sin(math.radians(heading))
    ts = []
    for p, u, a, b in ((x, ux, lo[0], hi[0]), (y, uy, lo[1], hi[1])):
        if u > 1e-12:
            ts.append((b - p) / u)
        elif u < -1e-12:
            ts.append((a - p) / u)
    return max(min(ts) - 1e-9, 0.0)


@pytest.mark.parametrize("cols,rows", [(5, 3), (4, 4)])
def test_rectangle_flights_closed_form(cols, rows):
    """In an empty rectangle every flight is the distance to the C-space box (less the
    contact gap): replaying each plan in closed form reproduces its flights, poses and cost,
    and ends in the goal cell with the goal heading.
    """
    env = room(cols, rows)
    cs = CellSpace(env)
    nav = ExactNavigator(cs, ANGLES)
    lo, hi = (0.17, 0.17), (cols * 0.34 - 0.17, rows * 0.34 - 0.17)
    rng = np.random.default_rng(3)
    for s, g in rng.integers(0, cs.N, size=(15, 2)):
        route = nav.plan(s, g)
        if route is None:
            continue
        x, y, head = cs.pose(s)
        cost, prev = 0.0, None
        for k, (a, f) in enumerate(zip(route.plan.turns, route.plan.flights_m)):
            d = _box_flight(x, y, head, lo, hi)
            assert f == pytest.approx(d, abs=1e-9)
            x += d * math.cos(math.radians(head))
            y += d * math.sin(math.radians(head))
            head = (head + a) % 360
            assert route.poses[k + 1] == pytest.approx((x, y, head), abs=1e-9)
            cost += d / cs.h + (1 if prev is None or prev == a else 100)
            prev = a
        d = route.plan.final_m
        assert d <= _box_flight(x, y, head, lo, hi) + 1e-9
        x += d * math.cos(math.radians(head))
        y += d * math.sin(math.radians(head))
        cost += d / cs.h
        assert route.cost == pytest.approx(cost, abs=1e-8)
        gp, gk = cs.pk(g)
        assert cs.cell_of_point([[x, y]])[0] == gp and abs(head - gk * 45) < 1e-9


# ----------------------------------------------------------------------------- shapely
def _random_room(rng) -> Environment:
    """A regular n-gon room (n = 5..8, random rotation) with a regular m-gon hole."""
    n, R = int(rng.integers(5, 9)), float(rng.uniform(1.1, 1.5))
    t = rng.uniform(0, 2 * np.pi) + 2 * np.pi * np.arange(n) / n
    outer = (R + R * np.column_stack([np.cos(t), np.sin(t)])).round(6).tolist()
    m = int(rng.integers(3, 7))
    ts = rng.uniform(0, 2 * np.pi) + 2 * np.pi * np.arange(m) / m
    c = R + rng.uniform(-0.15, 0.15, size=2)
    hole = (c + rng.uniform(0.2, 0.3) * np.column_stack([np.cos(ts), np.sin(ts)])).round(6)
    return Environment.from_dict({
        "name": "random-poly", "boundary": outer, "obstacles": [hole.tolist()],
        "robot_radius": 0.17, "discretization": {"cell_size": 0.34, "orientations": 8}})


def _shapely_flight(C, x, y, heading) -> float:
    """First exit of the ray from the C-space polygon C (0 when it leaves at once)."""
    u = np.array([math.cos(math.radians(heading)), math.sin(math.radians(heading))])
    p = np.array([x, y])
    if not C.buffer(1e-7).contains(Point(*(p + 1e-5 * u))):
        return 0.0
    hit = LineString([p, p + 10.0 * u]).intersection(C.boundary)
    pts = [np.asarray(g.coords) for g in getattr(hit, "geoms", [hit])]
    d = [float(np.hypot(*(q - p))) for g in pts for q in g]
    return min(v for v in d if v > 1e-6)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_flights_match_shapely_on_random_rooms(seed):
    """Every flight of the planner's plans equals an independent ray cast against the
    C-space as shapely buffers it (256 segments per quarter circle: the polygon lies within
    r·(1 − cos(π/1024)) ≈ 1e-6 m of the true rounded corners), to 1e-4 m.
    """
    rng = np.random.default_rng(seed)
    env = _random_room(rng)
    cs = CellSpace(env)
    nav = ExactNavigator(cs, ANGLES)
    C = env.free_space.buffer(-env.robot_radius, quad_segs=256)
    checked = 0
    for s, g in rng.integers(0, cs.N, size=(6, 2)):
        route = nav.plan(s, g)
        if route is None:
            continue
        for pose, f in zip(route.poses, route.plan.flights_m):
            assert f == pytest.approx(_shapely_flight(C, *pose), abs=1e-4), (seed, s, g, pose)
            checked += 1
        run = _replay(env, cs, route)
        assert run.success, (seed, s, g, run.reason)
    assert checked >= 3


# ----------------------------------------------------------------------------- the twin
@pytest.mark.parametrize("name,pairs", [("lab", 12), ("complex", 8), ("pentagon", 10)])
def test_exact_plans_replay_in_the_twin(name, pairs):
    """Noise-free, an exact plan executed by bump and clock in the kinematic twin ends in the
    goal cell with the goal heading, at the pose the planner predicts (1e-6 m), with no
    deviation from the expected flights.
    """
    env = Environment.from_dict(PENTAGON) if name == "pentagon" else envs.load(name)
    cs = CellSpace(env)
    nav = ExactNavigator(cs, ANGLES)
    rng = np.random.default_rng(11)
    done = 0
    for s, g in rng.integers(0, cs.N, size=(pairs, 2)):
        route = nav.plan(s, g)
        if route is None:
            continue
        run = _replay(env, cs, route)
        assert run.success, (name, s, g, route.plan.exact_text(), run.reason)
        assert not run.deviations
        assert run.final_pose[:2] == pytest.approx(route.poses[-1][:2], abs=1e-6)
        done += 1
    assert done >= pairs // 2


def test_candidates_and_all_pairs_agree_with_single_queries():
    """plans() lists arrivals within the slack, cheapest first, the first being plan();
    every candidate replays. all_pairs() gives the single queries' costs.
    """
    env = room(4, 3, obstacles=[(2, 1, 3, 2)])
    cs = CellSpace(env)
    nav = ExactNavigator(cs, ANGLES)
    s, g = cs.z(0, 0), cs.z(cs.P - 1, 2)
    best = nav.plan(s, g)
    cands = nav.plans(s, g, slack=20.0)
    assert cands[0].cost == pytest.approx(best.cost)
    costs = [c.cost for c in cands]
    assert costs == sorted(costs) and costs[-1] <= best.cost + 20.0 + 1e-9
    for c in cands:
        assert _replay(env, cs, c).success
    ap = nav.all_pairs()
    rng = np.random.default_rng(0)
    for i, j in rng.integers(0, cs.N, size=(8, 2)):
        r = nav.plan(i, j)
        assert ap.weights[i, j] == pytest.approx(-1.0 if r is None else r.cost)
        if r is not None and i != j:
            assert ap.angles_used[i, j] == r.angles_used


def test_chords_point_nearest_the_centre():
    """A flight east along y = 0.20 through a row of cells (h = 0.34): each chord's nearest
    point to the cell centre is the centre's x, depth h/2 − 0.03.
    """
    cs = CellSpace(room(4, 1))
    fi, p, t, depth = chords(cs, [[0.17, 0.20]], [[1.0, 0.0]], [1.02])
    assert p.tolist() == [0, 1, 2, 3]
    assert t == pytest.approx([0.0, 0.34, 0.68, 1.02])
    assert depth == pytest.approx([0.14] * 4)
    # a flight of length 0 (the heading faces the wall it touches) keeps its start point
    fi, p, t, depth = chords(cs, [[1.19, 0.17]], [[1.0, 0.0]], [0.0])
    assert p.tolist() == [3] and t.tolist() == [0.0] and depth == pytest.approx([0.17])


def test_goal_facing_the_wall_is_reached_by_a_last_bump():
    """4 × 3 room, Φ = {270°}. From cell (0, 0) facing east to cell (3, 0) facing south, into
    the wall: drive 1.02 m east to the wall (in the goal cell), turn 270° (south) and stop,
    the robot touching the south wall: one flight, no final drive, cost 3 + 1.
    """
    cs = CellSpace(room(4, 3))
    nav = ExactNavigator(cs, [270])
    route = nav.plan(cs.z(0, 0), cs.z(3, 6))
    assert route.plan.turns == (270,) and route.plan.final_m == 0.0
    assert route.plan.flights_m == pytest.approx((1.02 - 1e-9,), abs=1e-12)
    assert route.cost == pytest.approx(4.0, abs=1e-8)
    assert _replay(cs.env, cs, route).success
    # the same cell facing east: reached on the first flight, without a bump
    route = nav.plan(cs.z(0, 0), cs.z(3, 0))
    assert route.plan.turns == () and route.plan.final_m == pytest.approx(1.02 - 1e-9)


# ----------------------------------------------------------------------------- plan format
def test_exact_plan_format_round_trip():
    plan = Plan.exact([90, 135, 135], [0.7, 0.0, 1.234567], 0.5, h=0.34)
    assert str(plan) == "00 90° 135° 0000 135° 0"          # zeros = round(flight / h)
    assert plan.turns == (90, 135, 135) and plan.angles == (90, 135)
    again = Plan.parse(plan.exact_text())
    assert again.flights_m == pytest.approx(plan.flights_m, abs=1e-9)
    assert again.final_m == 0.5
    assert Plan.from_json(json.loads(json.dumps(plan.to_json()))) == plan
    assert Plan.parse("000 90°").flights_m is None                  # the paper's form
    for bad in ("90° | flights 1 2 m | final 0 m", "90° | flights 1 m", "90° | final 1 m",
                "90° | flights -1 m | final 0 m"):
        with pytest.raises(PlanParseError):
            Plan.parse(bad)


def test_executor_runs_by_angles_and_logs_deviations():
    """The executor ignores the expected flights for control: a plan whose first flight is
    stated 0.3 m too long still reaches the goal and logs one 'early' deviation.
    """
    env = room(4, 3)
    cs = CellSpace(env)
    route = ExactNavigator(cs, [90]).plan(cs.z(0, 0), cs.z(11, 2))
    wrong = Plan(route.plan.labels, (route.plan.flights_m[0] + 0.3,), route.plan.final_m,
                 "exact")
    run = execute(wrong, make_robot("kinematic", env), start=route.start, goal=route.goal,
                  cells=cs)
    assert run.success
    assert [(d.segment, d.kind) for d in run.deviations] == [(0, "early")]


def test_cli_plan_exact_json_on_a_hand_written_env(tmp_path, capsys):
    """`bouncesim plan ENV --planner exact --json` on an env file; its plan replays."""
    path = tmp_path / "pentagon.json"
    path.write_text(json.dumps(PENTAGON))
    assert main(["plan", str(path), "--angles", "45,90,135", "--start", "20", "--goal",
                 "150", "--planner", "exact", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["planner"] == "exact" and len(data["flights_m"]) == len(data["angles"])
    plan = Plan.from_json(data)
    env = Environment.from_dict(PENTAGON)
    run = execute(plan, make_robot("kinematic", env), start=20, goal=150, cells=CellSpace(env))
    assert run.success


def test_nav_exact_experiment_quick(tmp_path):
    """The measurement runs end to end and writes its tables and figure."""
    assert nav_exact.main(["--quick", "--pairs", "3", "--maps", "lab", "--out",
                           str(tmp_path)]) == 0
    summary = pd.read_csv(tmp_path / "summary.csv")
    assert summary["pairs"].tolist() == [3] and summary["exact_found"].between(0, 1).all()
    assert len(pd.read_csv(tmp_path / "pairs.csv")) == 3
    assert (tmp_path / "success.png").stat().st_size > 0


@pytest.mark.slow
@pytest.mark.physics
def test_exact_plan_succeeds_in_pybullet():
    """An exact plan (pentagon room with a hexagonal pillar: walls off the grid) reaches its
    goal in the PyBullet Create 2, noise-free, driven by bump and clock.
    """
    pytest.importorskip("pybullet")
    env = Environment.from_dict(PENTAGON)
    cs = CellSpace(env)
    route = ExactNavigator(cs, ANGLES).plan(20, 150)
    with make_robot("pybullet", env) as robot:
        run = execute(route.plan, robot, start=20, goal=150, cells=cs)
    assert run.success, run.reason
