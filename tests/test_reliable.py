"""Plans chosen for reliability (planners/navigation/reliable.py, docs/model.md §14).

Independent evidence: a success probability computed by hand in a 4 × 3 room, the kinematic
twin driven through the executor (scalar casts, its own turn handling) with the particles'
turn errors, a Monte-Carlo of the twin with its own noise draws, and noise-free replay.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from scipy.stats import norm

import envs
from bouncesim.cli import main
from bouncesim.robots.kinematic import KinematicRobot
from bouncesim.robots.noise import GaussianNoise
from bouncesim.runs.execute import execute
from envs import Environment
from envs.generated import random_polygon_room
from envs.motion import PYBULLET_CONTACT, ContactParams
from planners.cells import CellSpace
from planners.navigation import Navigator
from planners.navigation.exact import ExactNavigator
from planners.navigation.reliable import (
    ReliableNavigator,
    draw_turns,
    estimate,
    plan_cost,
    rollout,
    wilson,
)
from planners.noise import TurnNoise

ANGLES = (45.0, 90.0, 135.0)
ROOM = {"boundary": [[0, 0], [1.36, 0], [1.36, 1.02], [0, 1.02]], "robot_radius": 0.17,
        "discretization": {"cell_size": 0.34, "orientations": 8}}


@pytest.fixture(scope="module")
def room():
    """A small random room: a regular polygon with a polygonal hole (seeded)."""
    env = random_polygon_room(np.random.default_rng(np.random.SeedSequence([0, 2, 1])), "r1")
    return env, CellSpace(env)


def _pairs(cells, nav, n, seed):
    rng = np.random.default_rng(seed)
    out = []
    while len(out) < n:
        s, g = (int(v) for v in rng.integers(0, cells.N, 2))
        if s != g and (r := nav.plan(s, g)) is not None and r.plan.bumps >= 2:
            out.append((s, g, r))
    return out


class _Scripted:
    """A twin noise model that turns by the given executed turns, in order."""

    exact = False

    def __init__(self, turns):
        self.turns = list(turns)

    def sample(self, rng, commanded_deg):
        return float(self.turns.pop(0))


# ============================================================================ hand-computed
def test_hand_computed_probability_in_a_small_room():
    # east to the wall, turn 90° + δ, drive 0.68 m north by the clock: δ < 0 points into
    # the wall just touched (no motion, bottom row); δ > 0 succeeds while the drift
    # 0.68 sin δ stays within half a cell, so p = Φ(asin(1/4)/σ) − 1/2
    env = Environment.from_dict(ROOM)
    cs = CellSpace(env)
    s, g = int(cs.z(0, 0)), int(cs.z(11, 2))
    route = ExactNavigator(cs, [90, 135]).plan(s, g)
    assert route.plan.turns == (90,)
    for sigma in (3.0, 10.0):
        p = norm.cdf(math.degrees(math.asin(0.25)) / sigma) - 0.5
        est = estimate(cs, route.plan, s, g, TurnNoise.gauss(sigma), 3000,
                       np.random.default_rng(7), confidence=0.999)
        lo, hi = est.ci
        assert lo <= p <= hi, (sigma, p, est.p)
    # the §11 model at ε = Δ = 45°, r = 0.6: any error (±45°) misses the cell, so p = r
    est = estimate(cs, route.plan, s, g, "model:eps=45,r=0.6", 3000,
                   np.random.default_rng(8), confidence=0.999)
    lo, hi = est.ci
    assert lo <= 0.6 <= hi


def test_wilson_interval_hand_computed():
    # k = 8, n = 10, z = 1.96: (p + z²/2n ± z·sqrt(p(1−p)/n + z²/4n²)) / (1 + z²/n)
    z = norm.ppf(0.975)
    p, n = 0.8, 10
    c = (p + z * z / (2 * n)) / (1 + z * z / n)
    w = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    assert wilson(8, 10) == pytest.approx((c - w, c + w), abs=1e-12)


# ============================================================================ the twin
def test_particles_replay_the_twin_turn_for_turn(room):
    # the same executed turns through the executor on the twin (scalar casts, its own
    # bumper and timeout): the same final poses and the same outcomes
    env, cs = room
    nav = ExactNavigator(cs, ANGLES)
    outcomes = []
    for s, g, route in _pairs(cs, nav, 4, seed=3):
        turns = draw_turns(TurnNoise.gauss(3.0), route.plan, 25, np.random.default_rng(s),
                           cs.delta_deg)
        ro = rollout(cs, route.plan, s, g, turns)
        for i in range(len(turns)):
            bot = KinematicRobot(env, _Scripted(turns[i]), rng=0)
            run = execute(route.plan, bot, start=s, goal=g, cells=cs)
            assert run.success == bool(ro.success[i])
            if run.completed:
                assert np.allclose(run.final_pose, ro.poses[i], atol=1e-9, rtol=0)
            outcomes.append(run.success)
    assert 0 < np.mean(outcomes) < 1            # both outcomes were exercised


def test_predicted_p_success_agrees_with_twin_monte_carlo(room):
    # the twin with its own Gaussian draws (GaussianNoise, one draw per turn); the two
    # estimates agree within the two-sample bound at 99.9 %
    env, cs = room
    rel = ReliableNavigator(cs, ANGLES, "gauss:2", particles=2000,
                            rng=np.random.default_rng(11))
    checked = 0
    for s, g, _ in _pairs(cs, rel.exact, 2, seed=5):
        route = rel.plan(s, g)
        lo, hi = route.p_success_ci
        assert lo <= route.p_success <= hi
        bot = KinematicRobot(env, GaussianNoise(2.0), rng=np.random.default_rng(s + 1))
        checked += _agrees_with_twin(route, bot, cs, s, g, 250)
    assert checked >= 1                            # at least one plan was not trivial


def _agrees_with_twin(route, bot, cs, s, g, n: int) -> bool:
    """Assert that ``n`` runs of ``route``'s plan on ``bot`` succeed as often as its predicted
    p_success, within the two-sample bound at 99.9 %; whether the plan was not trivial.
    """
    z = norm.ppf(0.9995)
    k = sum(bool(execute(route.plan, bot, start=s, goal=g, cells=cs).success)
            for _ in range(n))
    p = (k + route.p_success * route.particles) / (n + route.particles)
    bound = z * math.sqrt(max(p * (1 - p), 1e-4) * (1 / n + 1 / route.particles))
    assert abs(k / n - route.p_success) <= bound, (s, g, k / n, route.p_success)
    return 0 < route.p_success < 1


# ============================================================================ selection
def test_reliable_plan_is_never_less_reliable_than_the_exact_plan(room):
    env, cs = room
    rel = ReliableNavigator(cs, ANGLES, "gauss:2", particles=400,
                            rng=np.random.default_rng(2))
    gains = []
    for s, g, exact in _pairs(cs, rel.exact, 5, seed=9):
        cands = rel.candidates(s, g)
        assert cands[0].plan == exact.plan                 # the exact plan is a candidate
        for c in cands:                                     # costs at the user's weights
            assert c.cost == pytest.approx(plan_cost(c.plan, cs.h, 1.0, 100.0), abs=1e-6)
        route = rel.plan(s, g)
        # on one fresh common particle set: the chosen plan is not worse than the exact
        # plan beyond the paired noise of the two estimates
        turns_rel = draw_turns("gauss:2", route.plan, 2000, np.random.default_rng(1),
                               cs.delta_deg)
        turns_ex = draw_turns("gauss:2", exact.plan, 2000, np.random.default_rng(1),
                              cs.delta_deg)
        a = rollout(cs, route.plan, s, g, turns_rel).success
        b = rollout(cs, exact.plan, s, g, turns_ex).success
        assert route.p_exact <= route.p_success + 4 * math.sqrt(0.25 / 400)
        assert a.mean() >= b.mean() - 4 * math.sqrt(0.5 / 2000), (s, g)
        gains.append(a.mean() - b.mean())
    assert np.mean(gains) >= 0


def test_noise_free_p_success_is_one_for_replaying_plans():
    env = envs.load("lab")
    cs = CellSpace(env)
    rel = ReliableNavigator(cs, ANGLES, "none", particles=50, rng=np.random.default_rng(0))
    for s, g, _ in _pairs(cs, rel.exact, 6, seed=4):
        route = rel.plan(s, g)
        assert route.p_success == 1.0 and route.chosen == 0
        assert route.p_success_ci[1] == 1.0
        run = execute(route.plan, KinematicRobot(env), start=s, goal=g, cells=cs)
        assert run.success


def test_step_plans_roll_out_as_the_twin_runs_them(room):
    # a step-model plan: rollout's verdict (noise-free) is the twin's, failures included
    env, cs = room
    step = Navigator(cs, ANGLES)
    verdicts = []
    for s, g, _ in _pairs(cs, ExactNavigator(cs, ANGLES), 12, seed=6):
        sr = step.plan(s, g)
        if sr is None:
            continue
        ro = rollout(cs, sr.plan, s, g, np.tile(np.asarray(sr.plan.turns, float), (1, 1)))
        run = execute(sr.plan, KinematicRobot(env), start=s, goal=g, cells=cs)
        assert bool(ro.success[0]) == run.success
        verdicts.append(run.success)
    assert False in verdicts                 # step plans fail in this room, and are seen to


# ============================================================================ CLI
def test_cli_plan_reliable_json(capsys):
    code = main(["plan", "lab", "--angles", "45,90,135", "--start", "289", "--goal", "364",
                 "--planner", "reliable", "--noise", "gauss:2", "--particles", "200",
                 "--json"])
    out = json.loads(capsys.readouterr().out)
    assert code == 0
    assert out["planner"] == "reliable" and out["particles"] == 200
    lo, hi = out["p_success_ci"]
    assert 0 <= lo <= out["p_success"] <= hi <= 1 and out["candidates"] >= 1
    assert main(["plan", "lab", "--angles", "45,90", "--start", "1", "--goal", "2",
                 "--planner", "reliable", "--particles", "0"]) == 2
    # run-plan plans with the noise it runs under (its --noise and --seed)
    assert main(["run-plan", "lab", "--angles", "45,90,135", "--start", "289", "--goal",
                 "364", "--planner", "reliable", "--noise", "gauss:2", "--quiet"]) in (0, 4)


def test_experiment_quick(tmp_path):
    import pandas as pd

    from experiments import nav_reliable
    assert nav_reliable.main(["--quick", "--pairs", "2", "--runs", "5", "--maps", "random1",
                              "--out", str(tmp_path)]) == 0
    pairs = pd.read_csv(tmp_path / "pairs.csv")
    assert len(pairs) == 4 and set(pairs.planner) == {"exact", "reliable"}
    summary = pd.read_csv(tmp_path / "summary.csv")
    assert (summary.ci_low <= summary.twin_success).all()
    assert (tmp_path / "success.png").stat().st_size > 0
    assert json.loads((tmp_path / "config.json").read_text())["quick"] is True


def test_registered_for_the_planner_comparison():
    # experiments.nav_montecarlo drives it like the other planners: one decision, a PlanRun
    from experiments.nav_planners import PLANNERS, NavConfig
    env = envs.load("lab")
    d = PLANNERS["reliable"](env, 68, 98, NavConfig(noise="gauss:2"), np.random.default_rng(0))
    run = d(KinematicRobot(env))
    assert d.decisions == 1 and d.plan.is_exact and run.success   # noise-free twin: replays


# ============================================================================ contact rule
# docs/model.md §14 with §9: a body whose bumper ignores glancing contacts (PyBullet's
# fitted rule) slides on; the candidates are planned and the particles flown under the rule.
@pytest.fixture(scope="module")
def glancing_room():
    """A random heptagon room with a square hole: walls off the cell grid, glancing flights."""
    env = random_polygon_room(np.random.default_rng(2))
    return env, CellSpace(env)


def test_a_rule_where_every_contact_bumps_gives_the_same_choice(glancing_room):
    # β = 0 closes the bumper for every front contact: the rule's code path (contact_flights,
    # slides that never start) must give the rule-free planner's candidates, choice and
    # estimates, particle for particle (the same seeds)
    env, cs = glancing_room
    kw = {"particles": 200}
    plain = ReliableNavigator(cs, ANGLES, "gauss:2", rng=np.random.default_rng(4), **kw)
    ruled = ReliableNavigator(cs, ANGLES, "gauss:2", rng=np.random.default_rng(4),
                              contact=ContactParams(0.0, 0.0), **kw)
    found = 0
    for s, g, _ in _pairs(cs, plain.exact, 2, seed=8):
        a, b = plain.plan(s, g), ruled.plan(s, g)
        assert b.plan == a.plan and b.chosen == a.chosen and b.candidates == a.candidates
        assert (b.p_success, b.p_exact) == (a.p_success, a.p_exact)
        found += 0 < a.p_success < 1
    assert found >= 1


def test_particles_replay_the_twin_with_the_rule_turn_for_turn(glancing_room):
    # the executor on KinematicRobot(contact=PYBULLET_CONTACT) with the particles' executed
    # turns (its own scalar slides, bumper arc and timeout): the same outcomes and final
    # poses; the rule-free rollout misjudges some of them (the rule matters here)
    env, cs = glancing_room
    nav = ExactNavigator(cs, ANGLES, contact=PYBULLET_CONTACT)
    outcomes, misjudged = [], 0
    for s, g, route in _pairs(cs, nav, 4, seed=5):
        for sigma in (0.3, 3.0):
            turns = draw_turns(TurnNoise.gauss(sigma), route.plan, 12,
                               np.random.default_rng(s), cs.delta_deg)
            ro = rollout(cs, route.plan, s, g, turns, contact=PYBULLET_CONTACT)
            free = rollout(cs, route.plan, s, g, turns)
            for i in range(len(turns)):
                bot = KinematicRobot(env, _Scripted(turns[i]), rng=0, contact=PYBULLET_CONTACT)
                run = execute(route.plan, bot, start=s, goal=g, cells=cs)
                assert run.success == bool(ro.success[i]), (s, g, sigma, i)
                if run.completed:
                    assert np.allclose(run.final_pose, ro.poses[i], atol=1e-6, rtol=0)
                outcomes.append(run.success)
                misjudged += run.success != bool(free.success[i])
    assert 0 < np.mean(outcomes) < 1
    assert misjudged >= 1


def test_noise_free_p_success_is_one_for_plans_that_replay_with_the_rule(glancing_room):
    env, cs = glancing_room
    rel = ReliableNavigator(cs, ANGLES, "none", particles=20, rng=np.random.default_rng(0),
                            contact=PYBULLET_CONTACT)
    for s, g, _ in _pairs(cs, rel.exact, 4, seed=4):
        route = rel.plan(s, g)
        run = execute(route.plan, KinematicRobot(env, contact=PYBULLET_CONTACT), start=s,
                      goal=g, cells=cs)
        assert run.success                    # replays in the twin with the rule ...
        assert route.p_success == 1.0 and route.chosen == 0   # ... and is predicted to


@pytest.mark.slow
def test_p_success_with_the_rule_agrees_with_twin_monte_carlo(glancing_room):
    # the twin with the rule and its own Gaussian draws: within the two-sample bound (99.9 %)
    env, cs = glancing_room
    rel = ReliableNavigator(cs, ANGLES, "gauss:3", particles=1000,
                            rng=np.random.default_rng(12), contact=PYBULLET_CONTACT)
    checked = 0
    for s, g, _ in _pairs(cs, rel.exact, 2, seed=7):
        route = rel.plan(s, g)
        bot = KinematicRobot(env, GaussianNoise(3.0), rng=np.random.default_rng(s + 1),
                             contact=PYBULLET_CONTACT)
        checked += _agrees_with_twin(route, bot, cs, s, g, 200)
    assert checked >= 1


def test_cli_plan_reliable_contact_pybullet(glancing_room, tmp_path, capsys):
    # --contact pybullet reaches the reliable planner (its plan is ReliableNavigator's with
    # the rule, seeded as the CLI seeds it); the step planner still refuses it (exit 2)
    env, cs = glancing_room
    path = tmp_path / "room.json"
    path.write_text(json.dumps(env.to_dict()))
    s, g, _ = _pairs(cs, ExactNavigator(cs, ANGLES, contact=PYBULLET_CONTACT), 1, seed=5)[0]
    args = ["plan", str(path), "--angles", "45,90,135", "--start", str(s), "--goal", str(g)]
    assert main([*args, "--planner", "reliable", "--noise", "gauss:0.3", "--contact",
                 "pybullet", "--particles", "100", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    cells = CellSpace(Environment.from_dict(env.to_dict()))
    route = ReliableNavigator(cells, ANGLES, "gauss:0.3", particles=100,
                              rng=np.random.default_rng([0, 20]),
                              contact=PYBULLET_CONTACT).plan(s, g)
    assert out["planner"] == "reliable" and out["noise"] == "gauss:0.3"
    assert tuple(out["angles"]) == route.plan.turns and out["p_success"] == route.p_success
    assert main([*args, "--contact", "pybullet"]) == 2
