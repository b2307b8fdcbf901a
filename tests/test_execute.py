"""Executors (docs/model.md §8, §21) on the kinematic twin, interface-only robots and the CLI."""

from __future__ import annotations

import json

import numpy as np
import pytest

import envs
from bouncesim.cli import main
from bouncesim.robots.base import CREATE2, BumpEvent, Robot, RobotError
from bouncesim.robots.kinematic import KinematicBatch, KinematicRobot
from bouncesim.robots.noise import GaussianNoise, SteppedNoise
from bouncesim.runs.execute import execute
from bouncesim.runs.trace import Trace
from envs import UserError
from planners.cells import CellSpace
from planners.navigation import Navigator
from planners.plan import Plan, PolicyMix

from .conftest import room


@pytest.fixture(scope="module")
def lab():
    return envs.load("lab")


@pytest.fixture(scope="module")
def lab_cells(lab):
    return CellSpace(lab)


class InterfaceOnly(Robot):
    """A robot that exposes nothing but the Robot interface (a hardware stand-in): it wraps a
    kinematic twin but has no place() and no true_pose().
    """

    def __init__(self, inner: Robot) -> None:
        self._inner = inner
        self.spec = inner.spec
        self.calls: list[str] = []

    def _log(self, name):
        self.calls.append(name)

    def drive(self, speed):
        self._log("drive")
        self._inner.drive(speed)

    def stop(self):
        self._log("stop")
        self._inner.stop()

    def bumper(self):
        self._log("bumper")
        return self._inner.bumper()

    def clock(self):
        return self._inner.clock()

    def wait(self, duration):
        self._log("wait")
        self._inner.wait(duration)

    def turn(self, angle_deg):
        self._log("turn")
        self._inner.turn(angle_deg)


# ------------------------------------------------------------------ Fig. 3 plans
@pytest.mark.parametrize("start,goal", [(8, 0), (103, 8)])
def test_fig3_plans_succeed_without_noise(lab, lab_cells, start, goal):
    route = Navigator(lab_cells, [90, 135]).plan(start, goal)
    assert route is not None
    run = execute(route.plan, KinematicRobot(lab), start=start, goal=goal, cells=lab_cells)
    assert run.success is True, run.reason
    assert run.completed and run.deviations == ()
    assert run.position_error == pytest.approx(0.0, abs=1e-6)
    assert run.heading_error == pytest.approx(0.0, abs=1e-9)
    assert run.bumps == route.plan.bumps
    assert run.trace.count("turn") == route.plan.bumps


def test_fig3_hand_written_plans(lab, lab_cells):
    # 8 -> 0: bump east, turn 90 (north, bump under the block), 90 (west), drive 8 cells,
    # bump the west wall, 90 (south, bump), 90 (east)
    run = execute(Plan.parse("90° 90° 00000000 90° 90°"), KinematicRobot(lab), start=8, goal=0)
    assert run.success
    times = [r.t for r in run.trace.events("bump")]
    turn = CREATE2.turn_time(90, 0.1)
    assert times[2] == pytest.approx(2 * turn + 8 * 0.34 / 0.2)
    # 103 -> 8: north at (7, 0) bumps, 135 -> 225 bumps, 135 -> 0, one step east, stop
    run = execute("135° 135° 0", KinematicRobot(lab), start=103, goal=8)
    assert run.success and run.final_pose[:2] == pytest.approx((2.89, 0.17), abs=1e-6)


def test_trailing_zeros_drive_by_clock_and_stop(lab, lab_cells):
    run = execute("000", KinematicRobot(lab), start=0, goal=3, cells=lab_cells)
    assert run.success and run.bumps == 0
    assert run.final_pose[0] == pytest.approx(0.17 + 3 * 0.34)
    assert run.elapsed == pytest.approx(3 * 0.34 / 0.2)


def test_trailing_diagonal_zeros_drive_the_step_models_distance(lab, lab_cells):
    # 24 = (p 24, east); one step east, bump, 135° to north-west, two diagonal steps: each
    # moves to the diagonal neighbour's centre, so the run drives 2·√2·h and ends on 183
    run = execute("0 135° 00", KinematicRobot(lab), start=24, goal=183, cells=lab_cells)
    assert run.success and run.deviations == ()
    assert run.position_error == pytest.approx(0.0, abs=1e-6)
    assert run.final_pose[:2] == pytest.approx(lab_cells.pose(183)[:2], abs=1e-6)
    # a start pose fixes the heading of every run as well
    run = execute("0 135° 00", KinematicRobot(lab), start=lab_cells.pose(24), goal=183,
                  cells=lab_cells)
    assert run.success
    with pytest.raises(UserError, match="start"):
        execute("0 135° 00", KinematicRobot(lab), start=None, goal=183, cells=lab_cells)


@pytest.mark.parametrize("name,K", [("lab", 8), ("fig1", 8), ("complex", 16),
                                    ("complex", 360)])
def test_step_offsets_agree_with_the_step_table(name, K):
    # run_length rests on one grid offset per orientation: every forward move of the step
    # table must move by exactly that offset, and n moves by n·h·|offset| between centres
    cs = CellSpace(envs.load(name, orientations=K))
    z = np.flatnonzero(cs.forward >= 0)
    p, k = cs.pk(z)
    p2, _ = cs.pk(cs.forward[z])
    assert np.array_equal(cs.cells_ij[p2] - cs.cells_ij[p], cs.step_offsets[k])
    dist = np.hypot(*(cs.centres[p2] - cs.centres[p]).T)
    assert np.allclose(dist, [cs.run_length(kk, 1) for kk in k], atol=1e-12)


def test_deviation_is_logged_and_run_goes_on(lab, lab_cells):
    # from (0, 0) facing east the wall is 8 cells away: a plan expecting 3 is 5 cells late
    run = execute("000 90°", KinematicRobot(lab), start=0, goal=None, cells=lab_cells)
    assert run.completed and run.success is None
    (dev,) = run.deviations
    assert dev.kind == "late" and dev.expected == pytest.approx(1.02)
    assert dev.travelled == pytest.approx(2.72, abs=1e-6)
    assert run.trace.count("deviation") == 1
    # one cell off is tolerated
    run = execute("0000000 90°", KinematicRobot(lab), start=0, goal=None, cells=lab_cells)
    assert run.deviations == ()
    # early
    run = execute("00000000000 90°", KinematicRobot(lab), start=0, goal=None, cells=lab_cells,
                  max_factor=5)
    assert [d.kind for d in run.deviations] == ["early"]


def test_no_bump_ends_the_run_with_a_reason(lab, lab_cells):
    run = execute("0 90°", KinematicRobot(lab), start=0, goal=9, cells=lab_cells, max_factor=1.0)
    assert run.success is False and not run.completed
    # a segment of n zeros may drive max_factor * (n + 2) * h = 3 * 0.34 m
    assert run.reason.startswith("no bump within 1.02 m")
    assert run.trace.count("no_bump") == 1


def test_success_checks_cell_and_heading(lab, lab_cells):
    run = execute("0", KinematicRobot(lab), start=0, goal=2, cells=lab_cells)
    assert run.success is False and "outside the goal cell" in run.reason
    assert run.position_error == pytest.approx(0.34)
    goal_north = int(lab_cells.z(1, 2))
    run = execute("0", KinematicRobot(lab), start=0, goal=goal_north, cells=lab_cells)
    assert run.success is False and "heading off by -90.0°" in run.reason
    # a start pose off the centre still succeeds inside the goal cell
    run = execute("0", KinematicRobot(lab), start=(0.25, 0.2, 10.0), goal=1, cells=lab_cells)
    assert run.success and run.heading_error == pytest.approx(10.0)


def test_back_off(lab, lab_cells):
    run = execute("90°", KinematicRobot(lab), start=8, goal=None, cells=lab_cells, back_off=0.01)
    x, y, h = run.final_pose
    assert x == pytest.approx(2.88, abs=1e-6) and h == 90.0
    assert run.trace.count("back_off") == 1


def test_interface_only_robot_runs_plans(lab, lab_cells):
    inner = KinematicRobot(lab)
    inner.place(*lab_cells.pose(8))                  # "the human placed it"
    bot = InterfaceOnly(inner)
    run = execute("90° 90° 00000000 90° 90°", bot, start=8, goal=0, cells=lab_cells)
    assert run.completed and run.success is None
    assert "unknown" in run.reason
    assert run.final_pose is None and run.position_error is None
    assert inner.true_pose()[:2] == pytest.approx((0.17, 0.17), abs=1e-6)  # it did get there
    assert set(bot.calls) <= {"drive", "stop", "bumper", "wait", "turn"}
    frame = run.trace.to_frame()
    assert frame["x"].isna().all()


def test_robot_error_ends_the_run(lab):
    class Failing(KinematicRobot):
        def turn(self, angle_deg):
            raise RobotError("lost the serial link")
    run = execute("90°", Failing(lab), start=8, goal=8)
    assert run.success is False and run.reason == "robot error: lost the serial link"


def test_bad_inputs_are_user_errors(lab):
    with pytest.raises(UserError):
        execute("90°", KinematicRobot(lab), start=8, goal=0, speed=0.0)
    with pytest.raises(UserError):
        execute("90°", KinematicRobot(lab), start=8, goal=0, speed=1.0)
    with pytest.raises(UserError):
        execute("90°", KinematicRobot(lab), start=8, goal=0, back_off=-1)
    with pytest.raises(UserError):
        execute("90°", KinematicRobot(lab), start=999, goal=0)


def test_noisy_runs_are_deterministic(lab):
    def once(seed):
        bot = KinematicRobot(lab, GaussianNoise(3.0), np.random.default_rng(seed))
        return execute("135° 135° 0", bot, start=103, goal=8)
    a, b = once(4), once(4)
    assert a.final_pose == b.final_pose and a.reason == b.reason
    assert [r.t for r in a.trace] == [r.t for r in b.trace]


def test_trace_csv_round_trip(tmp_path, lab):
    run = execute("90° 90° 00000000 90° 90°", KinematicRobot(lab), start=8, goal=0)
    path = run.trace.to_csv(tmp_path / "t.csv")
    import pandas as pd
    df = pd.read_csv(path)
    assert list(df.columns) == list(Trace.COLUMNS)
    assert df["event"].tolist()[0] == "start" and df["event"].tolist()[-2:] == ["stop",
                                                                                "outcome"]
    assert df["detail"].iloc[-1] == "success: reached the goal"
    assert (df["event"] == "bump").sum() == 4
    assert np.allclose(df["t"], run.trace.to_frame()["t"], atol=1e-6)
    with pytest.raises(ValueError):
        Trace().add(0, None, "teleport")


# ------------------------------------------------------------------ policy mixes
def test_mix_run_on_the_twin_matches_the_batch(lab, lab_cells):
    """One twin driven through the Robot interface and one batch robot from the same start
    with the same noise stream visit exactly the same cells.
    """
    noise = SteppedNoise(45, 0.7, 45)
    for z0 in (5, 100, 250):
        bot = KinematicRobot(lab, noise, np.random.default_rng(z0))
        run = execute(135.0, bot, steps=400, epoch=50, rng=np.random.default_rng(0), start=z0,
                      cells=lab_cells, record_trace=False)
        batch = KinematicBatch(lab, 1, np.random.default_rng(z0), starts=[z0])
        res = batch.run(135.0, 400, noise=noise)
        assert run.steps == 400 and run.reason == "finished"
        assert np.array_equal(run.counts, res.counts)
        assert run.dropped == res.dropped and run.bumps == res.bumps
        assert np.allclose(run.final_pose[:2], batch.pos[0], atol=1e-9)


def test_policy_mix_in_epochs_on_the_twin_matches_the_batch(lab, lab_cells):
    """The same for a policy mix executed in epochs: one Generator feeds the epoch draws and
    the turn noise of both (the batch draws them from its own rng in the same order), so the
    single robot and a one-robot batch share every step (the step rule of envs.motion).
    """
    mix = PolicyMix((45.0, 135.0, 270.0), (0.3, 0.5, 0.2))
    noise = SteppedNoise(45, 0.7, 45)
    for z0 in (7, 120, 300):
        g = np.random.default_rng(z0)
        bot = KinematicRobot(lab, noise, g)
        run = execute(mix, bot, steps=600, epoch=7, rng=g, start=z0, cells=lab_cells,
                      record_trace=False)
        batch = KinematicBatch(lab, 1, np.random.default_rng(z0), starts=[z0])
        res = batch.run(mix, 600, epoch=7, noise=noise)
        assert run.steps == 600 and run.reason == "finished" and len(run.epoch_angles) == 86
        assert len(set(run.epoch_angles)) == 3
        assert np.array_equal(run.counts, res.counts)
        assert run.dropped == res.dropped and run.bumps == res.bumps
        assert np.allclose(run.final_pose[:2], batch.pos[0], atol=1e-9)
        assert run.final_pose[2] == pytest.approx(float(batch.heading[0]), abs=1e-9)


def test_mix_epochs_follow_alpha(lab):
    mix = PolicyMix((90.0, 135.0, 180.0), (0.2, 0.5, 0.3))
    run = execute(mix, KinematicRobot(lab), steps=3000, epoch=3, rng=np.random.default_rng(1),
                  record_trace=False)
    angles = np.array(run.epoch_angles)
    assert len(angles) == 1000
    for a, p in zip(mix.angles, mix.alpha):
        # 5 standard errors of a frequency from 1000 epochs
        assert abs(np.mean(angles == a) - p) <= 5 * np.sqrt(p * (1 - p) / 1000)
    assert run.counts.sum() + run.dropped == 3000
    assert run.coverage.sum() == pytest.approx(1.0)


def test_mix_step_counting_by_hand():
    # 3 x 1 corridor at K = 4 facing east from cell 0 with 180° bounces:
    # steps start (or bump) in cells 0, 1, 2 (bump, turn west), 2, 1, 0 (bump), 0, 1, 2 (bump), 2
    env = room(3, 1, K=4)
    run = execute(180.0, KinematicRobot(env), steps=10, epoch=10, rng=np.random.default_rng(0),
                  start=0)
    assert run.counts.tolist() == [3, 3, 4]
    assert run.bumps == 3
    steps = [r.event for r in run.trace if r.event in ("step", "bump")]
    assert steps == ["step", "step", "bump", "step", "step", "bump", "step", "step", "bump",
                     "step"]


def test_stuck_robot_ends_the_run(lab):
    class Wedged(KinematicRobot):
        def drive_until_bump(self, speed, timeout):
            return BumpEvent(True, True, True, 0.0)
    run = execute(90.0, Wedged(lab), steps=1000, epoch=10, rng=np.random.default_rng(0),
                  max_stuck=20)
    assert run.reason == "stuck: 21 bumps in a row without moving"
    assert run.steps == 21
    # without the limit the budget ends the run
    run = execute(90.0, Wedged(lab), steps=100, epoch=10, rng=np.random.default_rng(0))
    assert run.reason == "finished" and run.steps == 100 and run.bumps == 100


def test_mix_on_interface_only_robot_has_no_histogram(lab, lab_cells):
    inner = KinematicRobot(lab)
    run = execute(135.0, InterfaceOnly(inner), steps=50, epoch=10, rng=np.random.default_rng(0),
                  cells=lab_cells)
    assert run.counts is None and run.coverage is None and run.steps == 50


# ------------------------------------------------------------------ CLI
def test_cli_success(capsys):
    assert main(["run-plan", "lab", "--angles", "90,135", "--start", "8", "--goal", "0"]) == 0
    out = capsys.readouterr().out
    assert "90° 90° 00000000 90° 90°" in out and "success" in out


def test_cli_json_and_trace(tmp_path, capsys):
    trace = tmp_path / "trace.csv"
    rc = main(["run-plan", "lab", "--angles", "90,135", "--start", "2.55,0.17,90", "--goal",
               "8", "--json", "--trace", str(trace)])
    assert rc == 0
    out = json.loads(capsys.readouterr().out)
    assert out["success"] is True and out["plan"] == "135° 135° 0" and out["start"] == 103
    assert trace.exists()


def test_cli_failure_exit_4(capsys):
    rc = main(["run-plan", "lab", "--angles", "90,135", "--start", "8", "--goal", "0",
               "--noise", "gauss:2", "--seed", "1"])
    assert rc == 4
    assert "failure: " in capsys.readouterr().out


def test_cli_glance_makes_the_noisy_corridor_passable(capsys):
    args = ["run-plan", "lab", "--angles", "90,135", "--start", "8", "--goal", "0",
            "--noise", "gauss:1", "--seed", "0"]
    assert main(args) == 4                   # the front-half bumper bumps in the corridor
    assert main([*args, "--glance", "80"]) == 0
    assert main([*args, "--glance", "95"]) == 2


def test_cli_no_path_exit_3(capsys):
    assert main(["run-plan", "lab", "--angles", "180", "--start", "0", "--goal", "96"]) == 3


@pytest.mark.parametrize("extra,msg", [
    (["--noise", "gauss:x"], "gauss"),
    (["--gui"], "pybullet"),
    (["--record", "x.gif"], "pybullet"),
    (["--speed", "2"], "speed"),
    (["--noise", "model:eps=5,r=0.8"], "multiple"),
])
def test_cli_user_errors(capsys, extra, msg):
    rc = main(["run-plan", "lab", "--angles", "90,135", "--start", "8", "--goal", "0", *extra])
    assert rc == 2
    err = capsys.readouterr().err
    assert err.startswith("bouncesim: error: ") and msg in err and err.count("\n") == 1


@pytest.mark.parametrize("name", ["bouncesim.robots.noise", "bouncesim.robots.kinematic",
                                  "bouncesim.runs.execute", "bouncesim.runs.trace"])
def test_docstring_examples(name):
    import doctest
    import importlib
    result = doctest.testmod(importlib.import_module(name), optionflags=doctest.ELLIPSIS)
    assert result.attempted > 0 and result.failed == 0


def test_a_bump_spins_the_shorter_way(lab, lab_cells):
    """docs/model.md §21: a bump by 315° is a 45° clockwise spin (the body is told −45°), one
    by 135° a counter-clockwise spin; the twin reaches the same headings either way.
    """
    told = []

    class Spy(KinematicRobot):
        def turn(self, angle_deg):
            told.append(float(angle_deg))
            super().turn(angle_deg)
    for angle, spin in ((315.0, -45.0), (135.0, 135.0), (180.0, 180.0)):
        told.clear()
        run = execute(angle, Spy(lab), steps=60, epoch=60, rng=np.random.default_rng(0),
                      start=5, cells=lab_cells, record_trace=False)
        assert run.bumps > 0 and set(told) == {spin}
        ref = KinematicBatch(lab, 1, np.random.default_rng(5), starts=[5]).run(angle, 60)
        assert np.array_equal(run.counts, ref.counts)


def test_a_feedback_filter_commands_the_shorter_spin(lab):
    # a known factor f = 0.9 (no scatter): the command for an actual 300° is the spin
    # −60 / 0.9, and the particles turn by f times it, −60°; 175° needs a spin of 194.4°,
    # commanded as such (the body spins as told); without a factor 315° is commanded −45°
    from planners.navigation.feedback.config import FeedbackConfig
    from planners.navigation.feedback.filter import ParticleFilter
    pf = ParticleFilter(lab, FeedbackConfig(turn_factor=0.9, particles=4),
                        np.random.default_rng(0), start=(1.0, 1.0, 100.0))
    assert pf.command_for(300.0) == pytest.approx(-60.0 / 0.9)
    assert pf.command_for(175.0) == pytest.approx(175.0 / 0.9)
    pf.turn(pf.command_for(300.0))
    assert np.allclose(pf.heading, 40.0)
    plain = ParticleFilter(lab, FeedbackConfig(particles=4), np.random.default_rng(0),
                           start=(1.0, 1.0, 100.0))
    assert plain.command_for(315.0) == -45.0 and plain.command_for(90.0) == 90.0
