"""The navigation wing's one protocol, one record, one registry and one run loop
(planners/navigation/, bouncesim/runs/execute.py): every registered planner through the same
front door, the same Route JSON and the same execute(), against the planners' own classes.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

import bouncesim as bs
import envs
from bouncesim.robots import make_robot
from bouncesim.robots.noise import GaussianNoise
from bouncesim.runs.execute import execute
from envs import UserError
from planners.cells import CellSpace
from planners.measures import goal_check
from planners.navigation import (
    PLANNERS,
    ExactNavigator,
    FeedbackPlanner,
    Navigator,
    Planner,
    ReliableNavigator,
    Route,
    make_planner,
)
from planners.plan import Plan

from .conftest import traced_peak

LAB = CellSpace(envs.load("lab"))
ANGLES = (90, 135)


def _needs(name: str, seed: int = 0) -> dict:
    """What planner ``name`` is built with besides the map and the angles."""
    cls = PLANNERS[name]
    given = {"noise": "none", "rng": np.random.default_rng(seed), "contact": None}
    return {k: v for k, v in given.items() if k in cls.needs and v is not None}


def test_the_registry_holds_the_four_planners_with_the_protocol():
    assert set(PLANNERS) == {"step", "exact", "reliable", "feedback"}
    assert PLANNERS["step"] is Navigator and PLANNERS["exact"] is ExactNavigator
    assert PLANNERS["reliable"] is ReliableNavigator and PLANNERS["feedback"] is FeedbackPlanner
    for name, cls in PLANNERS.items():
        assert cls.name == name and cls.needs <= {"noise", "rng", "contact"}
        planner = make_planner(name, LAB, ANGLES, **_needs(name))
        assert isinstance(planner, Planner) and planner.angles == (90.0, 135.0)
    assert [n for n, c in PLANNERS.items() if c.closed_loop] == ["feedback"]
    assert bs.PLANNERS is PLANNERS and bs.make_planner is make_planner and bs.Route is Route


def test_every_planner_returns_one_route_with_one_json_form():
    keys = None
    for name in PLANNERS:
        route = make_planner(name, LAB, ANGLES, **_needs(name)).plan(8, 0)
        assert isinstance(route, Route) and route.planner == name
        assert (route.start, route.goal) == (8, 0)
        # the plan always carries its flights; only the step model's run by its labels
        plan = route.plan
        assert plan.flights_m is not None and len(plan.flights_m) == plan.bumps
        assert plan.is_exact == (name != "step")
        out = json.loads(json.dumps(route.to_json()))
        keys = set(out) if keys is None else keys
        # the same keys for every planner, beyond each planner's declared extras
        assert set(out) - set(route.extras) == keys - set(route.extras), name
        assert Plan.from_json(out) == plan, name
        # the poses start at the start configuration's pose and end in the goal cell
        assert route.poses[0] == pytest.approx(LAB.pose(8))
        assert goal_check(LAB, 0, route.poses[-1]).in_cell, name
    none = Route.none_json(8, 0, "exact")
    assert set(none) == keys and none["plan"] is None


def test_step_routes_keep_their_configuration_path_and_the_paper_text():
    route = make_planner("step", LAB, ANGLES).plan(8, 0)
    assert str(route.plan) == route.plan.exact_text() == "90° 90° 00000000 90° 90°"
    assert route.path[0] == 8 and route.path[-1] == 0
    assert len(route.poses) == len(route.path) == len(route.plan) + 1
    assert route.plan.flights_m == (0.0, 0.0, 2.72, 0.0) and route.plan.final_m == 0.0


def test_one_run_loop_executes_all_four_planners():
    # the same execute() runs each planner's policy on the same body: the open-loop plans and
    # the feedback policy all reach the goal noise-free (lab, 8 -> 0 along the bottom row)
    for name in PLANNERS:
        planner = make_planner(name, LAB, ANGLES, **_needs(name))
        with make_robot("kinematic", LAB.env) as bot:
            run = execute(planner.policy(8, 0), bot, start=8, goal=0, cells=LAB)
        assert run.success, (name, run.reason)
        assert run.trace[0].event == "start" and run.trace[-2].event == "stop"
        assert (run.trace[-1].event, run.trace[-1].detail) == ("outcome",
                                                               "success: reached the goal")
        assert [r.event for r in run.trace].count("turn") == run.plan.bumps


def test_the_loop_is_the_only_driver_of_the_robot():
    # every robot command of every planner's run goes through the loop's few calls: drive
    # until bump, drive for, turn, stop (and, with back-off, drive/wait/stop); a body that
    # offers only those runs all four planners
    class Spy:
        def __init__(self, bot):
            self.bot, self.calls = bot, []

        def __getattr__(self, name):
            attr = getattr(self.bot, name)
            if callable(attr) and name in {"drive_until_bump", "drive_for", "turn", "drive",
                                           "wait", "stop", "place"}:
                def call(*a, **k):
                    self.calls.append(name)
                    return attr(*a, **k)
                return call
            return attr

    for name in PLANNERS:
        planner = make_planner(name, LAB, ANGLES, **_needs(name))
        spy = Spy(make_robot("kinematic", LAB.env))
        run = execute(planner.policy(8, 0), spy, start=8, goal=0, cells=LAB, back_off=0.01)
        assert run.success, (name, run.reason)
        assert set(spy.calls) <= {"drive_until_bump", "drive_for", "turn", "drive", "wait",
                                  "stop", "place"}
        assert spy.calls.count("turn") == run.plan.bumps
        assert spy.calls.count("wait") == run.bumps          # one back-off per bump


def test_feedback_through_execute_matches_navigate_feedback():
    # navigate_feedback is the feedback planner's policy in the one loop: the same run
    env = LAB.env
    a = bs.navigate_feedback(make_robot("kinematic", env), env, 8, 0, None,
                             np.random.default_rng(3), angles=ANGLES, cells=LAB)
    planner = make_planner("feedback", LAB, ANGLES, rng=np.random.default_rng(3),
                           contact="auto")
    b = execute(planner.policy(8, 0), make_robot("kinematic", env), cells=LAB)
    assert a.plan == b.plan and a.final_pose == b.final_pose and a.p_success == b.p_success
    assert [r.event for r in a.trace] == [r.event for r in b.trace]


def test_make_planner_errors_are_one_sentence():
    def one(fn):
        with pytest.raises(UserError) as err:
            fn()
        msg = str(err.value)
        assert "\n" not in msg and msg.endswith((".", ")", "?"))
        return msg
    assert "did you mean 'exact'" in one(lambda: make_planner("exat", LAB, ANGLES))
    assert "reliable and feedback do" in one(
        lambda: make_planner("step", LAB, ANGLES, noise="gauss:2"))
    assert "does not use a random source" in one(
        lambda: make_planner("exact", LAB, ANGLES, rng=np.random.default_rng(0)))
    assert "no option particles" in one(lambda: make_planner("exact", LAB, ANGLES,
                                                             particles=10))
    assert "memory limit" in one(lambda: make_planner("exact", LAB, ANGLES, max_memory="10K"))
    assert "memory limit" in one(
        lambda: make_planner("exact", LAB, ANGLES).all_pairs(max_memory="1M"))
    assert "repeat an angle" in one(lambda: make_planner("feedback", LAB, (90, 90)))


@pytest.mark.parametrize("name", ["lab", "fig1"])
def test_exact_memory_estimates_bound_what_it_allocates(name):
    # single queries within a factor 2 either way; all pairs never under by more than 20 %,
    # and at most 4x over on these small maps (the flight table's size depends on the map)
    cs = CellSpace(envs.load(name))
    _ = cs.centres
    angles = (45, 90, 135)
    nav = ExactNavigator(cs, angles)
    plan = traced_peak(lambda: nav.plan(0, cs.N - 1))
    est = ExactNavigator.memory_estimate(cs, angles).total
    assert plan / 2 <= est <= 2 * plan
    nav = ExactNavigator(cs, angles)
    pairs = traced_peak(lambda: nav.all_pairs(max_memory=None))
    est = ExactNavigator.memory_estimate(cs, angles, task="allpairs").total
    assert 0.8 * pairs <= est <= 4 * pairs


def test_noise_specs_have_one_grammar():
    # the body's noise model and the coverage models' TurnNoise read the same words
    for spec, sigma in [("gauss:2", 2.0), ("gaussian:sigma=2", 2.0), ("normal:2", 2.0),
                        ("none", 0.0), ("off", 0.0), ("exact", 0.0)]:
        body = bs.parse_noise(spec, 1.0)
        assert bs.TurnNoise.from_spec(spec).sigma_deg == sigma
        assert (body == GaussianNoise(sigma)) if sigma else body.exact
    assert bs.TurnNoise.from_spec("stepped:eps=2,r=0.5") == bs.TurnNoise(2, 0.5)
    with pytest.raises(UserError, match="delta"):
        bs.TurnNoise.from_spec("model:eps=2,r=0.5,delta=1")
