"""The team environments (bouncesim.team) and their world (KinematicTeam), docs/model.md §24.

Independent evidence: PettingZoo's own API and seed tests; lone kinematic twins (and
Bounce-v0) for interact="off"; hand-computed contacts of two disks; an exact closest-approach
check of every pair of robots between events, rebuilt from the flights alone.
"""

from __future__ import annotations

import math
import subprocess
import sys
import warnings

import numpy as np
import pytest

pytest.importorskip("pettingzoo")

from gymnasium.utils import seeding  # noqa: E402
from pettingzoo.test import (  # noqa: E402
    api_test,
    parallel_api_test,
    parallel_seed_test,
    seed_test,
)

import envs  # noqa: E402
from bouncesim import team  # noqa: E402
from bouncesim.gym import BounceEnv  # noqa: E402
from bouncesim.robots.kinematic import KinematicRobot  # noqa: E402
from bouncesim.robots.kinematic_team import KinematicTeam  # noqa: E402
from bouncesim.robots.noise import parse_noise  # noqa: E402
from envs import UserError  # noqa: E402
from planners.cells import CellSpace  # noqa: E402

ANGLES = (45.0, 90.0, 135.0)


@pytest.fixture(scope="module")
def lab():
    return envs.load("lab")


@pytest.fixture(scope="module")
def cells(lab):
    return CellSpace(lab)


def _quiet(fn, *args, **kwargs):
    """Run a PettingZoo test; its style warnings about Dict observations are expected."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        fn(*args, **kwargs)


# ============================================================================ PettingZoo's tests
@pytest.mark.parametrize("task,interact", [("cover", "bump"), ("navigate", "bump"),
                                           ("cover", "off")])
def test_pettingzoo_api_and_seed_tests_pass(task, interact):
    kw = dict(robots=3, task=task, interact=interact, noise="gauss:5", max_steps=25)
    _quiet(parallel_api_test, team.parallel_env("lab", **kw), num_cycles=60)
    _quiet(api_test, team.env("lab", **kw), num_cycles=60)
    _quiet(seed_test, lambda: team.env("lab", **kw), num_cycles=30)
    _quiet(parallel_seed_test, lambda: team.parallel_env("lab", **kw), num_cycles=30)


def test_spaces_are_the_same_objects_and_unknown_reset_options_warn():
    e = team.parallel_env("lab", robots=2)
    assert e.observation_space("robot_1") is e.observation_space("robot_1")
    assert e.action_space("robot_0") is e.action_space("robot_0")
    assert e.action_space("robot_0").n == 3
    with pytest.warns(UserWarning, match="unknown option 'begin'"):
        e.reset(seed=0, options={"begin": 1})


def test_bad_arguments_are_one_sentence():
    for kwargs, match in [({"task": "explore"}, "unknown task"),
                          ({"interact": "push"}, "off or bump"), ({"robots": 0}, "at least one"),
                          ({"goals": [1, 2, 3]}, "one goal per"), ({"angles": (100,)}, "45"),
                          ({"max_steps": 0}, "max_steps"), ({"render_mode": "human"}, "render")]:
        with pytest.raises(UserError, match=match):
            team.parallel_env("lab", **{"robots": 2, **kwargs})
    e = team.parallel_env("lab", robots=2)
    e.reset(seed=1)
    with pytest.raises(UserError, match="no action for robot_1"):
        e.step({"robot_0": 0})
    with pytest.raises(UserError, match="not an index"):
        e.step({"robot_0": 0, "robot_1": 3})
    with pytest.raises(UserError, match="overlaps"):
        e.reset(options={"starts": [0, 0]})


# ============================================================================ seeding
def _parallel_rollout(e, seed, steps=15):
    obs, infos = e.reset(seed=seed)
    rng = np.random.default_rng(5)
    out = [[infos[a]["pose"] for a in e.agents]]
    for _ in range(steps):
        if not e.agents:
            break
        obs, rew, term, trunc, infos = e.step({a: int(rng.integers(3)) for a in e.agents})
        out.append([(infos[a]["pose"], obs[a]["bumper"].tolist(), rew[a]) for a in infos])
    return out


def test_same_seed_same_trajectories_other_seed_differs():
    e = team.parallel_env("lab", robots=4, task="cover", noise="gauss:5")
    a, b, c = _parallel_rollout(e, 3), _parallel_rollout(e, 3), _parallel_rollout(e, 4)
    assert a == b and a != c


# ============================================================================ interact="off"
def _aec_poses(e, seed, starts, n_actions, rng):
    """Per robot: its poses at its flight ends, first flight included (AEC env, random
    actions), and its actions.
    """
    e.reset(seed=seed, options={"starts": starts})
    poses = {a: [] for a in e.agents}
    actions = {a: [] for a in e.agents}
    for _ in range(n_actions):
        agent = e.agent_selection                       # its flight has just ended
        if e.terminations[agent] or e.truncations[agent]:
            break
        poses[agent].append(e.infos[agent]["pose"])
        a = int(rng.integers(3))
        actions[agent].append(a)
        e.step(a)
    return poses, actions


@pytest.mark.parametrize("k", [1, 3])
def test_off_each_robot_is_a_lone_twin_with_its_own_stream(lab, cells, k):
    noise = "gauss:7"
    starts = [5, 200, 301][:k]
    e = team.raw_env("lab", robots=k, task="cover", interact="off", noise=noise,
                     max_steps=100)
    poses, actions = _aec_poses(e, 9, starts, 60 * k, np.random.default_rng(1))
    children = seeding.np_random(9)[0].spawn(k)         # the env spawns one per robot
    for i, agent in enumerate(e.possible_agents):
        bot = KinematicRobot(lab, parse_noise(noise, cells.delta_deg), children[i])
        bot.place(*cells.pose(starts[i]))
        cap = e.core.max_flight / e.core.speed
        bot.drive_until_bump(0.2, cap)
        lone = [bot.true_pose()]
        for a in actions[agent][:len(poses[agent]) - 1]:
            bot.turn(ANGLES[a])
            bot.drive_until_bump(0.2, cap)
            lone.append(bot.true_pose())
        assert len(lone) > 10
        assert poses[agent] == lone[:len(poses[agent])]  # bitwise


@pytest.mark.parametrize("task", ["cover", "navigate"])
def test_one_robot_is_bounce_v0(task, cells):
    goal = int(cells.z(20, 2))
    rng = np.random.default_rng(0)
    for seed in range(4):
        gym = BounceEnv("lab", task, goal=goal, max_steps=40)
        e = team.parallel_env("lab", robots=1, task=task, goals=[goal], max_steps=40)
        o1, i1 = gym.reset(seed=seed)
        o2, i2 = e.reset(seed=seed)
        assert i1["pose"] == i2["robot_0"]["pose"]
        for _ in range(40):
            a = int(rng.integers(3))
            o1, r1, t1, u1, i1 = gym.step(a)
            o2, r2, t2, u2, i2 = e.step({"robot_0": a})
            assert i1["pose"] == i2["robot_0"]["pose"]
            assert o1["bumper"].tolist() == o2["robot_0"]["bumper"].tolist()
            assert o1["duration"][0] == pytest.approx(o2["robot_0"]["duration"][0], rel=1e-6)
            assert (r1, t1, u1) == pytest.approx((r2["robot_0"], t2["robot_0"], u2["robot_0"]),
                                                 abs=1e-12)
            if task == "cover":
                np.testing.assert_array_equal(i1["visits"], i2["robot_0"]["visits"])
            if t1 or u1:
                break


# ============================================================================ interact="bump"
def test_head_on_robots_meet_at_the_midpoint(lab):
    # lab's row 0: two robots 2.72 m apart drive at each other at 0.2 m/s; the disks
    # (r = 0.17 m) touch when 2r apart, after (2.72 − 0.34) / 0.4 = 5.95 s, at x = 1.36, 1.70
    e = team.raw_env(lab, robots=2, task="cover", interact="bump")
    e.reset(seed=0, options={"starts": [(0.17, 0.17, 0.0), (2.89, 0.17, 180.0)]})
    assert e.agent_selection == "robot_0"              # the tie goes to the agent order
    for agent, x in (("robot_0", 1.36), ("robot_1", 1.70)):
        obs, info = e.observe(agent), e.infos[agent]
        assert obs["bumper"].tolist() == [1, 1]         # straight ahead: both switches
        assert obs["duration"][0] == pytest.approx(5.95, abs=1e-6)
        assert info["time"] == pytest.approx(5.95, abs=1e-12) and info["by"] == "robot"
        assert info["pose"][0] == pytest.approx(x, abs=2e-9)
    x0, x1 = e.infos["robot_0"]["pose"][0], e.infos["robot_1"]["pose"][0]
    assert 0.34 < x1 - x0 < 0.34 + 1e-8
    # passing through each other instead, each reaches the far wall after 13.6 s
    off = team.raw_env(lab, robots=2, task="cover", interact="off")
    off.reset(seed=0, options={"starts": [(0.17, 0.17, 0.0), (2.89, 0.17, 180.0)]})
    assert off.infos["robot_0"]["time"] == pytest.approx(13.6)
    assert off.infos["robot_0"]["pose"][0] == pytest.approx(2.89)


def test_a_contact_off_the_axis_closes_one_switch_and_the_still_robot_feels_nothing(lab):
    team_ = KinematicTeam(lab, 2, interact="bump")
    team_.place(0, 0.17, 0.17, 0.0)                    # drives east along y = 0.17
    team_.place(1, 1.53, 0.37, 90.0)                   # still, 0.2 m to the left of that line
    team_.launch(0)
    (end,) = team_.advance()
    dx = math.sqrt(0.34 ** 2 - 0.2 ** 2)               # the disks touch 2r apart
    assert end.robot == 0 and end.by == "robot"
    assert end.end[0] == pytest.approx(1.53 - dx, abs=2e-9)
    assert end.elapsed == pytest.approx((1.53 - dx - 0.17) / 0.2, abs=1e-8)
    assert math.degrees(math.atan2(0.2, dx)) > 10      # bearing 36°: the left switch alone
    assert (end.left, end.right) == (True, False)
    assert not team_.moving().any()


def test_parallel_round_a_robot_that_bumped_waits_and_is_hit(lab):
    # robot_1 drives south to the wall (0.34 m, 1.7 s) and waits there; robot_0 drives east
    # along that wall into it: contact at x = 1.53 − 0.34, after 5.1 s
    e = team.parallel_env(lab, robots=2, task="cover", interact="bump")
    obs, infos = e.reset(seed=0, options={"starts": [(0.17, 0.17, 0.0), (1.53, 0.51, 270.0)]})
    assert infos["robot_1"]["by"] == "wall" and infos["robot_1"]["time"] == pytest.approx(1.7)
    assert infos["robot_0"]["by"] == "robot"
    assert infos["robot_0"]["time"] == pytest.approx(5.1)
    assert infos["robot_0"]["pose"][0] == pytest.approx(1.19, abs=2e-9)
    assert obs["robot_0"]["bumper"].tolist() == [1, 1]
    assert not e.core.world.moving().any()              # a step ends with every robot still
    obs, rew, *_ = e.step({"robot_0": 1, "robot_1": 1})
    assert not e.core.world.moving().any()
    assert all(infos["steps"] == 1 for infos in _[2].values())


def _trajectories(team_, flights):
    """Position function per robot from its flights (start pose, go time, end pose, end time)."""
    def at(i, t):
        x, y = team_.robots[i].true_pose()[:2] if not flights[i] else flights[i][0][0][:2]
        for start, go, end, t_end in flights[i]:
            if t < go:
                return np.array([x, y])
            if t <= t_end:
                u = np.array([math.cos(math.radians(start[2])), math.sin(math.radians(start[2]))])
                return np.array(start[:2]) + 0.2 * (t - go) * u
            x, y = end[:2]
        return np.array([x, y])
    return at


@pytest.mark.parametrize("name,k", [("lab", 5), ("complex", 4)])
def test_robots_never_overlap_under_bump(name, k):
    room = envs.load(name)
    cs = CellSpace(room)
    rng = np.random.default_rng(11)
    team_ = KinematicTeam(room, k, interact="bump", noise=parse_noise("gauss:5", cs.delta_deg),
                          rngs=rng.spawn(k))
    r = team_.radius
    cells_ = rng.choice(cs.P, size=k, replace=False)
    starts = [cs.pose(int(cs.z(int(p), int(rng.integers(cs.K))))) for p in cells_]
    for i, pose in enumerate(starts):
        team_.place(i, *pose)
    flights = {i: [] for i in range(k)}
    go = {}
    for i in range(k):
        go[i] = (team_.launch(i).start, 0.0)
    robot_hits = 0
    for _ in range(250 * k):
        for e in team_.advance():
            flights[e.robot].append((e.start, e.time - e.elapsed, e.end, e.time))
            robot_hits += e.by == "robot"
            flight = team_.launch(e.robot, float(rng.choice(ANGLES)))
            del flight
    assert robot_hits > 20
    at = _trajectories(team_, flights)
    times = sorted({t for fl in flights.values() for _, g, _, te in fl for t in (g, te)})
    times = [t for t in times if t <= min(fl[-1][3] for fl in flights.values())]
    worst = math.inf
    for t0, t1 in zip(times[:-1], times[1:]):
        if t1 - t0 < 1e-12:
            continue
        for i in range(k):
            for j in range(i + 1, k):
                d0 = at(j, t0) - at(i, t0)
                dd = (at(j, t1) - at(i, t1)) - d0
                s = 0.0 if not dd @ dd else float(np.clip(-(d0 @ dd) / (dd @ dd), 0, 1))
                worst = min(worst, float(np.hypot(*(d0 + s * dd))))
    assert worst >= 2 * r - 1e-9, worst - 2 * r


# ============================================================================ AEC order, tasks
def test_aec_selects_the_robot_whose_flight_ended_in_time_order():
    e = team.raw_env("lab", robots=4, task="cover", interact="bump", noise="gauss:5")
    e.reset(seed=2)
    rng = np.random.default_rng(0)
    last = 0.0
    for _ in range(200):
        agent = e.agent_selection
        t = e.infos[agent]["time"]
        assert t >= last and t == e.core.world.time
        assert not e.core.world.moving()[e._index[agent]]
        last = t
        e.step(int(rng.integers(3)))
    # cover: every agent's return is the team's TV decrease since the reset
    assert len({round(v, 12) for v in e._cumulative_rewards.values()}) >= 1


def test_navigate_robots_park_in_their_goal_cells(cells):
    goals = [int(cells.z(20, 2)), int(cells.z(3, 0))]
    e = team.parallel_env("lab", robots=2, task="navigate", goals=goals, noise="gauss:10",
                          max_steps=150)
    rng = np.random.default_rng(4)
    reached = 0
    for seed in range(6):
        obs, infos = e.reset(seed=seed)
        while e.agents:
            obs, rew, term, trunc, infos = e.step({a: int(rng.integers(3)) for a in e.agents})
            for a, done in term.items():
                if done:
                    i = e._index[a]
                    p, _ = cells.pk(goals[i])
                    assert cells.cell_of_point([infos[a]["pose"][:2]])[0] == p
                    assert infos[a]["is_success"] and rew[a] == 1.0
                    assert obs[a]["bumper"].tolist() == [0, 0]
                    reached += 1
                else:
                    assert rew[a] == -0.01
    assert reached >= 3


# ============================================================================ the extra
def test_import_bouncesim_leaves_pettingzoo_alone_and_a_missing_extra_is_one_sentence():
    code = ("import sys, bouncesim\n"
            "bouncesim.CellSpace, bouncesim.execute\n"
            "assert 'pettingzoo' not in sys.modules, 'pettingzoo imported'\n"
            "sys.modules['pettingzoo'] = None\n"
            "try:\n"
            "    import bouncesim.team\n"
            "except ModuleNotFoundError as exc:\n"
            "    print(exc)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.strip()
    assert out == ("bouncesim.team needs pettingzoo, the optional extra team: "
                   "pip install 'bouncesim[team]'.")


def test_the_docs_example_runs():
    import re
    from pathlib import Path
    page = Path(__file__).resolve().parent.parent / "docs" / "readme_team.md"
    (code,) = re.findall(r"^```python\n(.*?)^```", page.read_text(encoding="utf-8"), re.S | re.M)
    exec(compile(code, "docs/readme_team.md", "exec"), {})
