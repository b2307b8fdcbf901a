"""Feedback navigation that degrades gracefully (docs/model.md §15, the observation model
with declared error rates): a flipped side bit, a phantom bump or a missed bump moves a
converged belief no further than the reading says, no reading zeroes the belief, a surprising
reading mixes a re-initialised component in, and a body with a different bumper convention
(side from the nearest wall point) navigates like the twin.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import envs
from bouncesim.robots.kinematic import KinematicRobot
from bouncesim.runs.execute import navigate_feedback
from envs import Environment, UserError
from planners.cells import CellSpace
from planners.navigation.feedback import FeedbackConfig, ParticleFilter

RECT = Environment.from_dict({"name": "rect", "boundary": [[0, 0], [2, 0], [2, 2], [0, 2]],
                              "robot_radius": 0.17,
                              "discretization": {"cell_size": 0.25, "orientations": 8}})


def _converged(n=300, seed=0, **cfg):
    """A belief converged on (0.5, 1.0) facing east, with 1 cm and 1° of spread."""
    rng = np.random.default_rng(seed)
    poses = np.column_stack([0.5 + rng.normal(0, 0.01, n), 1.0 + rng.normal(0, 0.01, n),
                             rng.normal(0, 1.0, n)])
    return ParticleFilter(RECT, FeedbackConfig(particles=n, **cfg), rng, poses=poses)


def _mean_pose(pf):
    head = math.degrees(math.atan2(pf.weights @ np.sin(np.radians(pf.heading)),
                                   pf.weights @ np.cos(np.radians(pf.heading))))
    return pf.weights @ pf.pos, head


@pytest.mark.parametrize("left,right", [(True, False), (False, True)])
def test_one_flipped_side_bit_does_not_move_a_converged_belief(left, right):
    # the robot hits the east wall head on (both switches), but the reading says one side:
    # the twin's convention and the nearest-point one disagree exactly like this in corners.
    # Every particle predicts "both", so the wrong bit weighs them all alike: the belief
    # lands where a correct reading puts it, nothing is re-initialised.
    ref, flipped = _converged(), _converged()
    up_ref = ref.flight(1.33, True, True)
    up = flipped.flight(1.33, left, right)
    assert up.reinit == 0 and up.mixed == 0 and not up.lost
    assert up.loglik < up_ref.loglik - math.log(1 / 0.05) + 1      # surprising, not fatal
    (p0, h0), (p1, h1) = _mean_pose(ref), _mean_pose(flipped)
    assert np.allclose(p1, [2 - 0.17, 1.0], atol=0.01) and abs(h1) < 1.0
    assert np.linalg.norm(p1 - p0) < 0.005 and abs(h1 - h0) < 0.5


def test_no_reading_zeroes_the_belief():
    # a reading no particle can produce as a real bump (half the flight, the wrong side)
    # keeps every particle alive: as a phantom bump it is possible, so the belief survives
    pf = _converged(p_lost=0.0)
    pf.flight(0.66, True, False)
    assert np.all(pf.weights > 0) and pf.n == 300
    # ... and the phantom branch puts the robot where it stopped, mid-flight
    x, _ = _mean_pose(pf)
    assert x[0] == pytest.approx(0.5 + 0.66, abs=0.02)


def test_a_phantom_bump_is_not_taken_for_a_wall():
    # the belief is sure of the heading; a bump after 0.66 m (half the flight) can only be a
    # phantom: the robot is believed at 1.16 m, not at the wall, and the next real flight to
    # the wall (0.67 m) is explained without any re-initialisation
    pf = _converged()
    pf.flight(0.66, True, True)
    up = pf.flight(0.67, True, True)
    assert up.reinit == 0 and not up.lost and up.consistent > 150
    x, h = _mean_pose(pf)
    assert x == pytest.approx([1.83, 1.0], abs=0.01)


def test_a_bump_without_a_closed_switch_is_read_for_its_distance_only():
    # a body may stop on a glancing contact and report a bump with neither switch closed
    pf = _converged()
    up = pf.flight(1.33, False, False)
    assert up.side == "none" and up.reinit == 0
    x, h = _mean_pose(pf)
    assert x == pytest.approx([1.83, 1.0], abs=0.01) and abs(h) < 1


def test_a_missed_bump_keeps_the_belief_at_the_wall():
    # no bump within the timeout: the robot pushed on against the wall (p_miss); the belief
    # stays at its contacts
    pf = _converged()
    up = pf.missed(4.0)
    assert up.side == "missed" and up.reinit == 0
    x, h = _mean_pose(pf)
    assert x == pytest.approx([1.83, 1.0], abs=0.01) and abs(h) < 1


def test_declared_rates_are_checked():
    for bad in ({"p_side": 0.7}, {"p_phantom": -0.1}, {"p_miss": 1.0},
                {"p_phantom": 0.6, "p_miss": 0.5}, {"p_lost": 1.0}):
        with pytest.raises(UserError):
            FeedbackConfig(**bad)


def test_health_is_reported_for_every_bump():
    env = envs.load("lab")
    run = navigate_feedback(KinematicRobot(env), env, 8, 0, None, np.random.default_rng(0),
                            angles=(90, 135))
    assert run.success and run.updates
    for u in run.updates:
        assert u.ess > 0 and math.isfinite(u.loglik) and 0 <= u.mixed <= 1


@pytest.mark.parametrize("rule", ["touched", "nearest"])
def test_both_bumper_conventions_navigate_a_rectilinear_room(rule):
    # a room with corners everywhere, where the nearest-point bumper reports one side while
    # the twin reports both: the belief is not thrown away and every run arrives
    room = Environment.from_dict({
        "name": "corners", "boundary": [[0, 0], [2.72, 0], [2.72, 2.04], [0, 2.04]],
        "obstacles": [[[0.68, 0.68], [1.36, 0.68], [1.36, 1.02], [0.68, 1.02]],
                      [[1.7, 1.36], [2.04, 1.36], [2.04, 2.04], [1.7, 2.04]]],
        "robot_radius": 0.17, "discretization": {"cell_size": 0.34, "orientations": 8}})
    cs = CellSpace(room)
    rng = np.random.default_rng(5)
    ok = 0
    for _ in range(6):
        s, g = (int(v) for v in rng.choice(cs.N, 2, replace=False))
        run = navigate_feedback(KinematicRobot(room, side_rule=rule), room, s, g, None,
                                np.random.default_rng(s), cells=cs)
        ok += bool(run.success) or run.reason.startswith("gave up") and run.no_plan > 0
        assert run.reinits <= 1, (rule, s, g, run.reason)
    assert ok >= 5


# ---------------------------------------------------------------- turn scale, unknown start
L_ROOM = Environment.from_dict({
    "name": "l-room", "boundary": [[0, 0], [3.06, 0], [3.06, 1.36], [1.70, 1.36], [1.70, 2.38],
                                   [0, 2.38]],
    "obstacles": [[[0.68, 1.36], [1.02, 1.36], [1.02, 1.70], [0.68, 1.70]]],
    "robot_radius": 0.17, "discretization": {"cell_size": 0.34, "orientations": 8}})


def test_the_turn_factor_estimate_converges_on_a_body_with_a_known_factor():
    # the body turns 8 % too far (and 2° of scatter); the filter is told only that the
    # factor lies within 1 ± 0.1: every particle carries one, and the runs end with the
    # estimate within 0.02 of 1.08 and a spread far below the prior's (0.1/√3 = 0.058)
    from bouncesim.robots.noise import parse_noise
    env = envs.load("lab")
    cs = CellSpace(env)
    for i, (s, g) in enumerate([(8, 0), (103, 40), (200, 17)]):
        body = KinematicRobot(env, parse_noise("gauss:2,factor=1.08", cs.delta_deg),
                              np.random.default_rng(100 + i))
        run = navigate_feedback(body, env, s, g, "gauss:2,scale=0.1",
                                np.random.default_rng(i), cells=cs)
        f, sd, b, _ = run.turn_estimate
        assert abs(f - 1.08) < 0.02 and sd < 0.02 and b == 0.0, (s, g, run.turn_estimate)
        assert run.to_json()["turn_factor"] == pytest.approx(f, abs=1e-5)


def test_an_unknown_start_localizes_in_a_small_asymmetric_room():
    # the body is put at random poses and the navigator is told nothing: it turns angles
    # that localize, then navigates (noise-free twin, nearest-point bumper)
    cs = CellSpace(L_ROOM)
    rng = np.random.default_rng(0)
    localized = arrived = 0
    for i in range(4):
        body = KinematicRobot(L_ROOM, side_rule="nearest")
        body.place(*L_ROOM.random_pose(rng))
        run = navigate_feedback(body, L_ROOM, None, 20, None, np.random.default_rng(i),
                                cells=cs)
        assert run.start_pose is None
        localized += run.bumps_to_localize is not None
        arrived += bool(run.success)
    assert localized >= 3 and arrived >= 2


def test_cli_runs_an_unknown_start_with_an_unknown_turn_scale(tmp_path, capsys):
    import json

    from bouncesim.cli import main
    path = tmp_path / "l-room.json"
    path.write_text(json.dumps(L_ROOM.to_dict()))
    argv = ["run-plan", str(path), "--angles", "45,90,135", "--planner", "feedback",
            "--noise", "gauss:2,scale=0.1", "--start", "unknown", "--goal", "20",
            "--seed", "3", "--json"]
    code = main(argv)
    out = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert code in (0, 4) and out["start"] == "unknown" and len(out["true_start"]) == 3
    assert out["bumps_to_localize"] is None or out["bumps_to_localize"] >= 1
    assert 0.9 <= out["turn_factor"] <= 1.1 and out["turn_factor_sd"] < 0.058
    # a planner that needs its start refuses the unknown one in one sentence
    assert main(argv[:4] + ["--planner", "exact", "--start", "unknown", "--goal", "20"]) == 2
    err = capsys.readouterr().err.strip()
    assert "closed-loop planner" in err and err.count("\n") == 0


def test_an_unknown_start_reaches_its_goal_on_the_create2_emulator(tmp_path, capsys):
    import json

    from bouncesim.cli import main
    path = tmp_path / "l-room.json"
    path.write_text(json.dumps(L_ROOM.to_dict()))
    code = main(["run-plan", str(path), "--angles", "45,90,135", "--planner", "feedback",
                 "--start", "unknown", "--goal", "20", "--seed", "3", "--robot", "emulator",
                 "--lockstep", "--json", "--quiet"])
    out = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert code == 0 and out["success"] and out["bumps_to_localize"] >= 1


# ---------------------------------------------------------------- plans with margin
def test_the_clearance_rule_rejects_a_zero_clearance_flight():
    from planners.navigation.feedback.search import grazes
    corner = [(1.0, 1.0)]
    r = 0.17
    # flying east along y = 1 − r − 1e-6: the disk passes the corner 1 µm clear
    assert grazes(0.0, 1.0 - r - 1e-6, 1.0, 0.0, 2.0, corner, r, 0.005, 0.0)
    # 1 cm clear is enough at σ = 0, not with 2° of spread 1 m before the corner
    assert not grazes(0.0, 1.0 - r - 0.01, 1.0, 0.0, 2.0, corner, r, 0.005, 0.0)
    assert grazes(0.0, 1.0 - r - 0.01, 1.0, 0.0, 2.0, corner, r, 0.005, math.radians(2))
    # the corner it bumps into, or one behind or beyond the flight, is not passed
    assert not grazes(0.0, 1.0 - r, 1.0, 0.0, 2.0, corner, r, 0.005, 0.0)
    assert not grazes(1.5, 1.0 - r - 1e-6, 1.0, 0.0, 2.0, corner, r, 0.005, 0.0)
    assert not grazes(0.0, 1.0 - r - 1e-6, 1.0, 0.0, 0.9, corner, r, 0.005, 0.0)


def test_plans_from_a_pose_keep_their_clearance():
    # a room with a pillar off the grid: every flight after a turn of every plan found from
    # random poses passes every corner at least 5 mm clear (or touches it: its bump)
    from planners.navigation.feedback import FeedbackNavigator
    from planners.navigation.feedback.search import grazes
    room = Environment.from_dict({
        "name": "pillar", "boundary": [[0, 0], [2.72, 0], [2.72, 2.04], [0, 2.04]],
        "obstacles": [[[1.2, 0.8], [1.55, 0.8], [1.55, 1.15], [1.2, 1.15]]],
        "robot_radius": 0.17, "discretization": {"cell_size": 0.34, "orientations": 8}})
    cs = CellSpace(room)
    rng = np.random.default_rng(4)
    checked = 0
    for goal in rng.choice(cs.N, 6, replace=False):
        fnav = FeedbackNavigator(cs, (45, 90, 135), int(goal), FeedbackConfig())
        verts, r = fnav.walls.verts, fnav.walls.r
        for z in rng.choice(cs.N, 4, replace=False):
            x, y, th = cs.pose(int(z))
            for cand in fnav.plans_from(x, y, th, 50.0)[:3]:
                px, py, head = x, y, th
                for j, (a, f) in enumerate(zip((0.0, *cand.angles), cand.flights)):
                    head += a
                    ux, uy = math.cos(math.radians(head)), math.sin(math.radians(head))
                    if j > 0:
                        assert not grazes(px, py, ux, uy, f, verts, r, 0.005 - 1e-9, 0.0)
                        checked += 1
                    px, py = px + f * ux, py + f * uy
    assert checked > 10
