"""The closed-loop value of the feedback navigator (docs/model.md §15, "Deciding by value"):
the contact-state transitions against the twin's own flights, the value iteration against a
plain recursion, the stop values on a hand-computed case, the value against the success of
its own policy simulated in the twin, and the decision rule built on it.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
import shapely
import shapely.ops

from bouncesim.robots.kinematic import KinematicRobot
from bouncesim.robots.noise import parse_noise
from bouncesim.runs.execute import navigate_feedback
from envs import Environment, UserError
from planners.cells import CellSpace
from planners.navigation.feedback import FeedbackConfig, FeedbackNavigator, ParticleFilter
from planners.navigation.feedback.value import transitions

RECT = Environment.from_dict({"name": "rect", "boundary": [[0, 0], [2, 0], [2, 2], [0, 2]],
                              "robot_radius": 0.17,
                              "discretization": {"cell_size": 0.25, "orientations": 8}})
L_ROOM = Environment.from_dict({
    "name": "l-room", "boundary": [[0, 0], [3.06, 0], [3.06, 1.36], [1.70, 1.36], [1.70, 2.38],
                                   [0, 2.38]],
    "obstacles": [[[0.68, 1.36], [1.02, 1.36], [1.02, 1.70], [0.68, 1.70]]],
    "robot_radius": 0.17, "discretization": {"cell_size": 0.34, "orientations": 8}})
ANGLES = [45, 90, 135]


def _nav(env, goal, sigma, **cfg):
    return FeedbackNavigator(CellSpace(env), ANGLES, goal,
                             FeedbackConfig(turn_sigma_deg=sigma, **cfg))


def test_each_stored_flight_lands_where_the_twin_flies():
    # independent evidence: the twin body (its own flight code) flown from the node's start
    # point with the node's turn error ends in the state the table stores, for random states
    fnav = _nav(RECT, 40, 3.0, heading_step_deg=5.0, value_nodes=3)
    tr = transitions(fnav.nav, 3.0, 5.0, 3)
    assert tr.offsets.tolist() == pytest.approx([-3 * 0.9674216, 0.0, 3 * 0.9674216])
    rng = np.random.default_rng(0)
    body = KinematicRobot(RECT)
    checked = 0
    for s in rng.choice(tr.nxt.shape[1], 60, replace=False):
        b, j = divmod(int(s), tr.n_head)
        i, q = int(rng.integers(len(ANGLES))), int(rng.integers(3))
        x, y = tr.points[q, b]
        heading = j * tr.step_deg + ANGLES[i] + tr.offsets[q]
        try:
            body.place(x, y, heading)
        except UserError:            # a bin point on a rounded corner, 1e-9 m inside
            continue
        ev = body.drive_until_bump(0.2, 100.0)
        assert ev.bumped
        X, Y, th = body.true_pose()
        assert int(tr.state(np.array([[X, Y]]), np.array([th]))[0]) == tr.nxt[i, s, q]
        checked += 1
    assert checked >= 50


def test_the_value_iteration_is_the_plain_recursion():
    # V_t(s) = max_φ max(stop(s, φ), γ Σ_q V_{t−1}(next) / M), written out state by state
    fnav = _nav(RECT, 40, 2.0, heading_step_deg=15.0, value_nodes=3, gamma=0.9,
                value_horizon=3)
    vt = fnav.value
    tr, stop = vt.tr, vt.stop.astype(float)
    S = tr.nxt.shape[1]
    V = [[max(stop[a, s] for a in range(3)) for s in range(S)]]
    for _ in range(3):
        prev = V[-1]
        V.append([max(max(stop[a, s], 0.9 * sum(prev[n] for n in tr.nxt[a, s]) / 3)
                      for a in range(3)) for s in range(S)])
    np.testing.assert_allclose(vt.V, np.array(V), atol=1e-6)
    assert np.all(np.diff(vt.V, axis=0) >= -1e-7)        # more flights never hurt
    assert 0 <= vt.V.min() and vt.V.max() <= 1


def test_stop_values_by_hand_in_a_square_room():
    # 2 m room, h = 0.25: the goal is cell x ∈ [0.25, 0.5], y ∈ [0.25, 0.5] facing 0°. A
    # robot at the west wall's contact line x = 0.17 heading 270° that turns by 90° faces
    # east: its final drive ends in the cell when y ∈ [0.25, 0.5] and never from y = 1;
    # turned by 45° it faces 315°, outside 0° ± 22.5°. Noise-free, a stop either succeeds
    # or it does not
    cs = CellSpace(RECT)
    goal = cs.config_of_pose(0.375, 0.375, 0.0)
    assert tuple(round(v, 3) for v in cs.pose(goal)) == (0.375, 0.375, 0.0)
    fnav = FeedbackNavigator(cs, ANGLES, goal, FeedbackConfig(decision="value"))
    vt = fnav.value
    tr = vt.tr
    assert not tr.offsets.any()                      # noise-free: flights differ by start
    west = np.array([[0.17 + 1e-9, 0.4], [0.17 + 1e-9, 1.0]])
    s = tr.state(west, np.array([270.0, 270.0]))
    i90 = ANGLES.index(90)
    assert vt.stop[i90, s].tolist() == [1.0, 0.0]
    assert vt.stop[ANGLES.index(45), s].tolist() == [0.0, 0.0]     # faces 315°: heading off


def test_a_stop_that_runs_into_its_bump_in_the_goal_cell():
    # by hand: a 2.04 m room of 0.34 m = 2r cells, whose south-east cell's centre
    # (1.87, 0.17) is the C-space corner; the goal faces 0° there. A robot on the south
    # wall's contact line at x = 0.51, heading 270°, turns by 90° to face east: the point of
    # its flight nearest the centre is the corner itself, 1.36 m on, where the flight bumps
    # (CONTACT_GAP short of it). The final drive runs into that bump and stops in the cell:
    # a success, which the table counts with stop_at_bump, from every node's start point.
    # The rule before asked for a drive no longer than the flight, which round-off at the
    # 1e-9 m gap decided (3 of the 7 nodes here), so a goal in a corner looked nearly
    # unreachable (lab's 103 → 8 flew 80 bumps in 5 of 5 noisy runs)
    env = Environment.from_dict({"boundary": [[0, 0], [2.04, 0], [2.04, 2.04], [0, 2.04]],
                                 "robot_radius": 0.17,
                                 "discretization": {"cell_size": 0.34, "orientations": 8}})
    cs = CellSpace(env)
    goal = cs.config_of_pose(1.87, 0.17, 0.0)
    fnav = FeedbackNavigator(cs, ANGLES, goal, FeedbackConfig(decision="value"))
    vt = fnav.value
    s = vt.tr.state(np.array([[0.51, 0.17 + 1e-9]]), np.array([270.0]))
    assert float(vt.stop[ANGLES.index(90), s][0]) == 1.0
    assert float(vt.stop[ANGLES.index(45), s][0]) == 0.0          # faces 315°: heading off


PILLAR = Environment.from_dict({
    "name": "pillar", "boundary": [[0, 0], [2.5, 0], [2.5, 2], [0, 2]],
    "obstacles": [[[1.1, 0.8], [1.5, 0.9], [1.4, 1.3], [1.0, 1.2]]],
    "robot_radius": 0.17, "discretization": {"cell_size": 0.25, "orientations": 8}})


def _place_near(body, p, heading):
    """Place the twin at ``p``, or, where the twin refuses it (a bin point on a pillar's
    rounded corner, whose polygon lies up to a few µm inside the true clearance), pushed
    straight out from the nearest wall point to the clearance r + 1e-7 m.
    """
    try:
        body.place(float(p[0]), float(p[1]), heading)
        return
    except UserError:
        pass
    env = body.env
    wall = np.array(shapely.ops.nearest_points(env.walls, shapely.Point(*p))[0].coords[0])
    out = np.asarray(p, dtype=float) - wall
    q = wall + out / np.hypot(*out) * (env.robot_radius + 1e-7)
    assert np.hypot(*(q - p)) < 1e-4
    body.place(float(q[0]), float(q[1]), heading)


@pytest.mark.parametrize("goal_pose", [(1.625, 0.375, 0.0), (0.875, 1.375, 90.0),
                                       (2.125, 1.625, 45.0)])
def test_stop_values_are_what_the_twin_does_node_by_node(goal_pose):
    # independent evidence: every node of a stop (its start point, its heading with the
    # stop's turn error, the drive to the point nearest the goal cell's centre) driven by
    # the twin body by clock, which stops at its own bump: the share of nodes that end in
    # the goal cell with the heading in range is the table's stop value, on random states
    # with a stop value above 0 and random ones near the goal heading, in a room with a
    # slanted pillar (at most 2 % of the states may differ: ends within round-off of the
    # cell's border; measured: 80 of 80 agree for each goal, while the rule before, which
    # held the drive to the transition flight's, agreed on 74 and 77 for two of them)
    cs = CellSpace(PILLAR)
    goal = cs.config_of_pose(*goal_pose)
    fnav = FeedbackNavigator(cs, ANGLES, goal, FeedbackConfig(turn_sigma_deg=3.0,
                                                              decision="value"))
    vt, tr = fnav.value, fnav.value.tr
    x0, y0, x1, y1 = fnav.box
    centre = np.array([(x0 + x1) / 2, (y0 + y1) / 2])
    rng = np.random.default_rng(5)
    i_s = np.argwhere(vt.stop > 0)
    near = np.argwhere(np.abs((np.arange(vt.stop.shape[1]) % tr.n_head) * tr.step_deg
                              + np.array(ANGLES)[:, None] - fnav.goal_heading + 180) % 360
                       - 180 <= 30)
    picks = np.vstack([i_s[rng.choice(len(i_s), 40, replace=False)],
                       near[rng.choice(len(near), 40, replace=False)]])
    body = KinematicRobot(PILLAR)
    agree = total = 0
    for i, s in picks:
        b, j = divmod(int(s), tr.n_head)
        t = j * tr.step_deg + ANGLES[i]
        u = np.array([math.cos(math.radians(t)), math.sin(math.radians(t))])
        ok = 0
        for q, off in enumerate(vt.stop_offsets):
            p = tr.points[q, b]
            d = max(float((centre - p) @ u), 0.0)
            _place_near(body, p, t + off)
            if d > 0:
                body.drive_until_bump(0.2, d / 0.2)
            X, Y, th = body.true_pose()
            dh = abs((th - fnav.goal_heading + 180) % 360 - 180)
            ok += (x0 <= X <= x1 and y0 <= Y <= y1 and dh <= cs.delta_deg / 2) / len(
                vt.stop_offsets)
        agree += abs(ok - float(vt.stop[i, s])) < 1e-6
        total += 1
    assert total == 80 and agree >= 0.98 * total, (agree, total)


@pytest.mark.parametrize("extra", [0.0, 1.0])
def test_stop_values_widen_the_turn_error_by_stop_extra(extra):
    # by hand: at the west wall's contact line (x = 0.17), heading 270°, a turn by 90° faces
    # east; the goal cell x ∈ [1.0, 1.25], y ∈ [0.25, 0.5] facing 0° lies d = 0.955 m on
    # (its centre's x less 0.17). Node q starts at its own point (x, y_q) of the bin and
    # turns by s·z_q, z_q the normal quantile at (q + ½)/7, s = √(1 + extra²)·σ; it ends in
    # the cell when |y_q − 0.375 + d·sin(s·z_q)| ≤ 0.125 (its x moves by d·(1 − cos) < 1 cm)
    sig = 4.0
    cs = CellSpace(RECT)
    goal = cs.config_of_pose(1.125, 0.375, 0.0)
    fnav = FeedbackNavigator(cs, ANGLES, goal, FeedbackConfig(turn_sigma_deg=sig,
                                                              stop_extra=extra))
    vt = fnav.value
    s = int(vt.tr.state(np.array([[0.17 + 1e-9, 0.375]]), np.array([270.0]))[0])
    b = s // vt.tr.n_head
    spread = math.hypot(sig, extra * sig)
    z = [-1.4652338, -0.7916386, -0.3661064, 0.0, 0.3661064, 0.7916386, 1.4652338]
    ok = [abs(vt.tr.points[q, b, 1] - 0.375 + 0.955 * math.sin(math.radians(spread * zq)))
          <= 0.125 for q, zq in enumerate(z)]
    assert float(vt.stop[ANGLES.index(90), s]) == pytest.approx(np.mean(ok), abs=1e-6)
    # a known state (extra 0) stops for sure; a belief's stop (extra 1) misses on the
    # outer node that turns left: 5.66° · 1.465 = 8.3° carries the robot 0.138 m north of
    # its start at y = 0.378, past 0.5 (the outer node turning right starts at 0.414 and
    # ends at 0.276, inside)
    assert np.mean(ok) == pytest.approx(1.0 if extra == 0 else 6 / 7)


def test_the_value_is_what_its_own_policy_achieves_in_the_twin():
    # predicted against simulated: a robot that knows its contact state after every bump
    # and follows the table's best action (stop or fly on) succeeds about as often as
    # V_t(s) says. Bound: 120 runs give a binomial σ ≤ 0.046, and the table averages each
    # value over its bin while a run starts from one point of it (measured differences
    # 0.02–0.10): every start within 0.18, the mean within 0.08
    sig, H = 3.0, 6
    fnav = _nav(L_ROOM, 20, sig, gamma=1.0, stop_extra=0.0)     # stops from a known state
    vt, tr = fnav.value, fnav.value.tr
    body = KinematicRobot(L_ROOM, parse_noise(f"gauss:{sig}", fnav.cells.delta_deg),
                          np.random.default_rng(1))
    x0, y0, x1, y1 = fnav.box
    centre, half = np.array([(x0 + x1) / 2, (y0 + y1) / 2]), (x1 - x0) / 2

    def run(x, y, th, t):
        body.place(x, y, th)
        while True:
            s = int(tr.state(np.array([[x, y]]), np.array([th]))[0])
            cont = vt.V[t - 1][tr.nxt[:, s]] @ tr.weights if t > 0 else np.zeros(3)
            i = int(np.argmax(np.maximum(vt.stop[:, s], cont)))
            body.turn(ANGLES[i])
            if vt.stop[i, s] >= cont[i]:
                u = np.array([math.cos(math.radians(th + ANGLES[i])),
                              math.sin(math.radians(th + ANGLES[i]))])
                d = max(float((centre - [x, y]) @ u), 0.0)
                bumped = d > 0 and body.drive_for(0.2, d / 0.2).bumped
                X, Y, TH = body.true_pose()
                off = abs((TH - fnav.goal_heading + 180) % 360 - 180)
                return (not bumped and half - np.abs(np.array([X, Y]) - centre).max() >= 0
                        and off <= fnav.cells.delta_deg / 2)
            body.drive_until_bump(0.2, 100.0)
            x, y, th = body.true_pose()
            t -= 1

    rng = np.random.default_rng(5)
    diffs = []
    for s in rng.permutation(np.flatnonzero(vt.V[H] > 0.2)):
        b, j = divmod(int(s), tr.n_head)
        x, y = fnav.nav.boundary.points(np.array([b]), np.array([0.5]))[0]
        try:
            ok = [run(x, y, j * tr.step_deg, H) for _ in range(120)]
        except UserError:
            continue
        diffs.append(float(vt.V[H][s]) - float(np.mean(ok)))
        if len(diffs) == 6:
            break
    assert len(diffs) == 6
    assert max(abs(d) for d in diffs) <= 0.18, diffs
    assert abs(float(np.mean(diffs))) <= 0.08, diffs


def test_a_value_decision_stops_when_the_goal_is_on_the_current_flight():
    # the robot at (0.5, 1) facing south, known exactly: its flight passes the goal cell
    # below it, so the final drive (mass 1) beats any bump
    cs = CellSpace(RECT)
    z = cs.config_of_pose(0.625, 0.375, 270.0)
    fnav = FeedbackNavigator(cs, ANGLES, z, FeedbackConfig(turn_sigma_deg=2.0))
    assert fnav.by_value
    rng = np.random.default_rng(0)
    pf = ParticleFilter(RECT, fnav.cfg, rng, poses=[[0.625, 1.0, 270.0]] * 50)
    (cand,) = fnav.choose(pf, rng, bumped=False, left=40)
    assert cand.angles == () and cand.p_success == pytest.approx(1.0)
    assert cand.final_m == pytest.approx(1.0 - 0.375, abs=0.13)


def test_auto_decides_by_plan_without_noise_and_by_value_with_it():
    cs = CellSpace(RECT)
    assert not FeedbackNavigator(cs, ANGLES, 40, FeedbackConfig()).by_value
    assert FeedbackNavigator(cs, ANGLES, 40, FeedbackConfig(turn_sigma_deg=1.0)).by_value
    assert FeedbackNavigator(cs, ANGLES, 40, FeedbackConfig(turn_scale=0.05)).by_value
    assert not FeedbackNavigator(cs, ANGLES, 40,
                                 FeedbackConfig(turn_sigma_deg=1.0, decision="plan")).by_value
    with pytest.raises(UserError, match="decision"):
        FeedbackConfig(decision="greedy")
    with pytest.raises(UserError, match="gamma"):
        FeedbackConfig(gamma=0.0)
    with pytest.raises(UserError, match="stop_extra"):
        FeedbackConfig(stop_extra=-1.0)
    with pytest.raises(UserError, match="value_particles"):
        FeedbackConfig(value_particles=2.5)


def test_the_transitions_are_built_once_per_map_and_noise():
    cs = CellSpace(RECT)
    a = FeedbackNavigator(cs, ANGLES, 40, FeedbackConfig(turn_sigma_deg=2.0)).value
    b = FeedbackNavigator(cs, ANGLES, 41, FeedbackConfig(turn_sigma_deg=2.0)).value
    c = FeedbackNavigator(cs, ANGLES, 41, FeedbackConfig(turn_sigma_deg=3.0)).value
    assert a.tr is b.tr and b.tr is not c.tr
    assert not np.array_equal(a.stop, b.stop)


@pytest.mark.parametrize("rule", ["touched", "nearest"])
def test_value_decisions_reach_goals_under_noise_on_two_bodies(rule):
    # σ = 3° on the L-room (not a map the rule was chosen on), two bumper conventions:
    # at least 8 of 10 seeded runs reach the goal (measured: 10 and 10)
    env, cs, done = L_ROOM, CellSpace(L_ROOM), 0
    for i in range(10):
        rng = np.random.default_rng(i)
        body = KinematicRobot(env, parse_noise("gauss:3", 45.0), rng.spawn(1)[0],
                              side_rule=rule)
        run = navigate_feedback(body, env, 5, 20, "gauss:3", rng, cells=cs)
        done += run.success
    assert done >= 8


def test_plan_decisions_ignore_the_value_settings():
    # decision="plan" is the rule before the value: its candidates carry no stop threshold
    # (final_min decides) and no value table is built, so the value's settings change nothing
    env = L_ROOM
    runs = []
    for cfg in (FeedbackConfig(decision="plan"), replace(FeedbackConfig(decision="plan"),
                                                         gamma=0.5, value_nodes=3)):
        rng = np.random.default_rng(3)
        body = KinematicRobot(env, parse_noise("gauss:2", 45.0), rng.spawn(1)[0])
        runs.append(navigate_feedback(body, env, 5, 20, "gauss:2", rng, config=cfg))
    assert runs[0].plan.turns == runs[1].plan.turns
    assert runs[0].plan.final_m == runs[1].plan.final_m
    assert all(math.isnan(p) or 0 <= p <= 1 for p in runs[0].p_success)


def test_the_value_bound_of_the_robustness_experiment():
    # nav_robustness --bound: per run the state-known value from the first bump, with γ = 1
    # at least the discounted one the navigator uses, pooled over the runs of each cell
    import pandas as pd

    from experiments.nav_robustness import ANGLES as EXP_ANGLES
    from experiments.nav_robustness import _cells, value_bound
    runs = pd.DataFrame({"env": "lab", "map_seed": 0, "planner": "feedback", "body": "twin",
                         "condition": "sigma2", "start": [20, 20, 8], "goal": [300, 300, 0],
                         "success": [True, False, True]})
    t = value_bound(runs)
    pooled = t[t.env == "all"].iloc[0]
    assert pooled.runs == 3 and pooled.success == pytest.approx(2 / 3)
    cs = _cells("lab", 0)
    own = []
    for s, g in ((20, 300), (20, 300), (8, 0)):
        fnav = FeedbackNavigator(cs, EXP_ANGLES, g, FeedbackConfig(turn_sigma_deg=2.0))
        x, y, th = cs.pose(s)
        body = KinematicRobot(cs.env)
        body.place(x, y, th)
        body.drive_until_bump(0.2, 100.0)
        X, Y, TH = body.true_pose()
        own.append(float(fnav.value.values(np.array([[X, Y]]), np.array([TH]), 39)[0]))
    assert 0 <= np.mean(own) <= pooled.bound <= 1
