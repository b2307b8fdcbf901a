"""Meetings of a team (docs/model.md §20a): two robots counted in the same cell at the same
step of their own clocks.

Independent evidence: a corridor whose cycle is written out by hand, the product chain's
exact first meeting against the sampler on a small room, the closed-form limit against long
runs, the kinematic twin's passing team (its own cell walks, step by step) against the
model's prediction, and by-hand walks for the twin's count.
"""

from __future__ import annotations

import numpy as np
import pytest

import envs
from bouncesim.robots.noise import NoNoise, parse_noise
from bouncesim.runs.team_runs import _colocations, team_coverage
from planners.cells import CellSpace
from planners.coverage import TurnNoise, model_for
from planners.coverage.cover_time import coverage_metrics

CORRIDOR3 = envs.Environment.from_dict({
    "boundary": [[0, 0], [1.1, 0], [1.1, 0.4], [0, 0.4]], "robot_radius": 0.17,
    "discretization": {"cell_size": 0.34, "orientations": 4}})


@pytest.mark.parametrize("exact", [True, False])
def test_two_robots_on_the_corridor_cycle_meet_as_counted_by_hand(exact):
    # step model, 90°: from cell 0 facing east the cycle's cells are 0 1 2 2 2 1 0 0 (§20a);
    # from cell 2 facing west the same cycle four steps on: 2 1 0 0 0 1 2 2
    cs = CellSpace(CORRIDOR3)
    start = np.zeros(cs.N)
    start[[cs.z(0, 0), cs.z(2, 2)]] = 0.5
    m, = coverage_metrics(model_for(cs, "step"), 90, horizon=800, start=start, robots=2,
                          exact=exact, rng=1, runs=4000)
    first = m.meeting["first"]
    # same start (probability 1/2): they meet at step 0 and at every step after; different
    # starts: first at step 1, then at steps 1 and 5 of every 8
    assert first["method"] == ("exact" if exact else "sampled")
    assert first["median"] == 0 and first["not_reached"] == 0
    if exact:
        assert first["mean"] == pytest.approx(0.5, abs=1e-12)
    else:
        assert abs(first["mean"] - 0.5) <= 4 * first["mean_se"]
    per = m.meeting["per_1000"]                     # 1/2 · 1000 + 1/2 · 250
    assert abs(per - 625) <= 4 * m.meeting["per_1000_se"]
    # the limit mixes the phases independently: return times 8/3, 4, 8/3 steps
    assert m.meeting["per_1000_limit"] == pytest.approx(1000 * (9 + 4 + 9) / 64, abs=1e-9)
    assert m.to_json()["meeting"]["first"]["mean"] == first["mean"]


def test_the_product_chain_agrees_with_the_sampler_on_a_small_room():
    env = envs.Environment.from_dict({
        "boundary": [[0, 0], [1.02, 0], [1.02, 0.68], [0, 0.68]], "robot_radius": 0.17,
        "discretization": {"cell_size": 0.34, "orientations": 8}})
    model, noise = model_for(CellSpace(env), "event"), TurnNoise(45, 0.7)
    ex, = coverage_metrics(model, 135, noise, robots=2, horizon=60, exact=True, rng=1)
    sa, = coverage_metrics(model, 135, noise, robots=2, horizon=60, exact=False, rng=2,
                           runs=20000)
    e, s = ex.meeting["first"], sa.meeting["first"]
    assert e["method"] == "exact" and s["method"] == "sampled"
    assert abs(e["mean"] - s["mean"]) <= 4 * s["mean_se"]
    assert abs(e["not_reached"] - s["not_reached"]) <= 0.01
    assert abs(e["median"] - s["median"]) <= 1
    # six cells, fast mixing: within 60 steps the meetings run at nearly the limit's rate
    assert sa.meeting["per_1000"] == pytest.approx(sa.meeting["per_1000_limit"], rel=0.05)
    one, = coverage_metrics(model, 135, noise, robots=1, horizon=60, exact=False, rng=1,
                            runs=10)
    assert one.meeting is None and "meeting" not in one.to_json()


def test_colocations_by_hand():
    # step 0: cells 0 3 1; step 1: all three in cell 1 (3 pairs); step 2: 2 2 and a dropped
    # step (1 pair); dropped steps never meet
    assert _colocations([np.array([0, 1, 2]), np.array([3, 1, 2]),
                         np.array([1, 1, -1])]) == (1, 4)
    assert _colocations([np.array([-1, 5]), np.array([-1, 4])]) == (-1, 0)
    assert _colocations([np.array([0, 1])]) == (-1, 0)


def test_bumping_robots_in_the_corridor_touch_but_never_share_a_cell():
    corridor = envs.Environment.from_dict({
        "name": "corridor", "boundary": [[0, 0], [1.36, 0], [1.36, 0.34], [0, 0.34]],
        "robot_radius": 0.17, "discretization": {"cell_size": 0.34, "orientations": 4}})
    cs = CellSpace(corridor)
    res = team_coverage(corridor, 180.0, NoNoise(), robots=2, steps=30, burn_in=0,
                        interact="bump", rng=np.random.default_rng(0), cells=cs,
                        starts=[cs.z(0, 0), cs.z(3, 2)])
    # every flight is a step and a bump step; the first bump step (own step 1) ends at the
    # other robot; robot 0 walks 0 1 1 0 0 1 …, robot 1 mirrored 3 2 2 3 …
    assert res.first_contact == 1
    assert res.first_meeting == -1 and res.colocations == 0


@pytest.mark.slow
def test_the_model_predicts_when_a_passing_twin_team_first_meets():
    """Four twins that pass through each other, each from its own uniform start (the model's
    assumption), in lab at 75°: the first own step at which two share a cell, and how often
    they do, against the model's sampled prediction. Bound: 4 combined standard errors plus
    5 % of the value (the model is a discretisation of the twin).
    """
    env = envs.load("lab", orientations=72)
    cs = CellSpace(env)
    T, runs = 200, 150
    rec, = coverage_metrics(model_for(cs, "event"), 75, TurnNoise(5, 0.8), robots=4,
                            horizon=T, runs=20000, rng=0, exact=False)
    body = parse_noise("model:eps=5,r=0.8", cs.delta_deg)
    rng = np.random.default_rng(1)
    first, colo = [], 0
    for _ in range(runs):
        res = team_coverage(env, 75.0, body, robots=4, steps=T, interact="off", rng=rng,
                            cells=cs, starts=rng.integers(cs.N, size=4))
        first.append(res.first_meeting)
        colo += res.colocations
    first = np.array(first, dtype=float)
    assert (first >= 0).all()
    m = rec.meeting
    se = np.hypot(first.std(ddof=1) / np.sqrt(runs), m["first"]["mean_se"])
    assert abs(first.mean() - m["first"]["mean"]) <= 4 * se + 0.05 * m["first"]["mean"]
    per_twin = 2000.0 * colo / (4 * T * runs)
    assert per_twin == pytest.approx(m["per_1000"], rel=0.1)
