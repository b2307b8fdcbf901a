"""The Create 3 path: the emulated-time loop, the emulator (answered through iRobot's own SDK
when it is installed), the adapter Create3Robot, its faults, and the same plans as on the
Create 2 emulator and the twin.

Everything runs in lockstep (emulated time) except the one ``realtime`` test, so the results
do not depend on how busy the machine is.
"""

from __future__ import annotations

import asyncio
import json
import math
import struct
import subprocess
import sys

import numpy as np
import pytest
from shapely.geometry import LineString, Point

import envs
from bouncesim.robots import make_robot
from bouncesim.robots.base import RobotError
from bouncesim.robots.create3 import (
    Create3Emulator,
    Deadlock,
    Packet,
    VirtualTimeLoop,
    bump_event,
    pose_of,
)
from bouncesim.robots.noise import GaussianNoise
from bouncesim.runs.execute import execute
from envs import UserError
from planners.cells import CellSpace
from planners.navigation.exact import ExactNavigator

LAB = envs.load("lab")
START = (0.51, 0.51, 0.0)


def _free_run(env, x, y, heading_deg):
    """Distance [m] the disk's centre can move from (x, y) along the heading before the disk
    touches a wall: an independent ray cast on shapely's eroded free space.
    """
    cspace = env.free_space.buffer(-env.robot_radius)
    u = (math.cos(math.radians(heading_deg)), math.sin(math.radians(heading_deg)))
    ray = LineString([(x, y), (x + 10 * u[0], y + 10 * u[1])])
    hit = ray.intersection(cspace.boundary)
    pts = [hit] if hit.geom_type == "Point" else list(getattr(hit, "geoms", []))
    return min(Point(x, y).distance(p) for p in pts)


# ---------------------------------------------------------------- the emulated clock
def test_virtual_loop_sleeps_take_no_wall_time_and_order_timers():
    loop = VirtualTimeLoop()
    seen = []

    async def sleeper(d):
        await asyncio.sleep(d)
        seen.append((d, loop.time()))

    async def main():
        await asyncio.gather(sleeper(3.0), sleeper(1.0), sleeper(86400.0))
    try:
        loop.run_until_complete(main())
    finally:
        loop.close()
    assert seen == [(1.0, 1.0), (3.0, 3.0), (86400.0, 86400.0)]


def test_virtual_loop_polling_lets_time_move_and_a_deadlock_is_one_sentence():
    loop = VirtualTimeLoop()
    flag = []

    async def poll():                   # the SDK's completer: sleep(0) until a flag is set
        loop.call_later(2.5, flag.append, True)
        while not flag:
            await asyncio.sleep(0)
        return loop.time()
    try:
        assert loop.run_until_complete(poll()) == 2.5
        with pytest.raises(Deadlock, match="can never happen"):
            loop.run_until_complete(loop.create_future())
    finally:
        loop.close()


# ---------------------------------------------------------------- the emulator, packet by packet
def test_emulator_answers_pose_turn_and_bump_in_the_sdk_frame():
    emu = Create3Emulator(LAB, start=START, reflex=False, slowdown=False)
    assert emu.connect(0.0)
    emu.receive(Packet.simple(1, 16, 1).to_bytes(), 0.0)
    battery, first = emu.due(0.0)
    assert Packet.from_bytes(battery).device == 14
    assert pose_of(Packet.from_bytes(first)) == (0.0, 0.0, 90.0)
    emu.receive(Packet.wheel_speeds(20, 20, 2).to_bytes(), 0.0)     # 0.2 m/s east
    run = _free_run(LAB, *START)
    emu.advance(run / 0.2 + 0.1)
    (bump,) = emu.due(run / 0.2 + 0.1)
    ms, left, right = bump_event(Packet.from_bytes(bump))
    assert (left, right) == (True, True)
    assert ms == pytest.approx(run / 0.2 * 1000, abs=1.0)        # the contact time, not a tick
    emu.receive(Packet.turn(90, 3, left=True).to_bytes(), 10.0)
    emu.advance(12.0)
    answers = [Packet.from_bytes(r) for r in emu.due(12.0)]
    turn = [p for p in answers if (p.device, p.command, p.inc) == (1, 12, 3)]
    assert len(turn) == 1
    x, y, h = pose_of(turn[0])
    assert (x, y, h) == pytest.approx((0.0, run * 100, 180.0), abs=0.1)   # cm, deg
    assert emu.body.true_pose()[2] % 360 == pytest.approx(90.0)


def test_emulator_reflex_backs_off_and_slowdown_slows_near_walls():
    fast = Create3Emulator(LAB, start=START, reflex=False, slowdown=False)
    slow = Create3Emulator(LAB, start=START, reflex=True, slowdown=True)
    run = _free_run(LAB, *START)
    for emu in (fast, slow):
        emu.connect(0.0)
        emu.receive(Packet.wheel_speeds(20, 20, 0).to_bytes(), 0.0)
    t_fast = run / 0.2
    t_slow = (run - 0.15) / 0.2 + 0.15 / 0.1             # 0.1 m/s in the last 0.15 m
    for emu in (fast, slow):
        emu.advance(t_slow + 1.0)
    bumps = {id(e): [bump_event(Packet.from_bytes(r)) for r in e.due(t_slow + 1.0)]
             for e in (fast, slow)}
    fast_bumps = [b for b in bumps[id(fast)] if b is not None]
    slow_bumps = [b for b in bumps[id(slow)] if b is not None]
    assert fast_bumps[0][0] == pytest.approx(t_fast * 1000, abs=1.0)
    assert slow_bumps[0][0] == pytest.approx(t_slow * 1000, abs=20.0)      # tick: 15 ms
    assert slow_bumps[1][1:] == (False, False)            # the reflex released the bumper
    assert fast.body.true_pose()[0] == pytest.approx(START[0] + run)
    assert slow.body.true_pose()[0] == pytest.approx(START[0] + run - 0.02, abs=1e-6)
    assert slow.body.actual_wheels() == (0.0, 0.0)        # reflex over: stopped


# ---------------------------------------------------------------- an unmodified SDK script
# Each script runs in its own Python process, as a user's script does: the SDK's Robot keeps
# class-wide state and replaces the signal handlers, and ending a script the SDK's way (raise
# SystemExit in a handler) leaves CPython 3.11's parser recursion counter off in that process.
SCRIPT = """
import json, sys
import envs
from irobot_edu_sdk.robots import event, Create3
from bouncesim.robots.create3 import EmulatorBackend

backend = EmulatorBackend(envs.load("lab"), start={start}, {options})
robot = Create3(backend)
log = []

@event(robot.when_bumped, [])
async def bumped(robot):
    await robot.set_wheel_speeds(0, 0)
    p = await robot.get_position()
    log.append(("bump", p.x, p.y, p.heading))
    await robot.turn_left(90)
    p = await robot.get_position()
    log.append(("turned", p.x, p.y, p.heading))
    raise SystemExit

@event(robot.when_play)
async def play(robot):
    p = await robot.get_position()
    log.append(("start", p.x, p.y, p.heading))
    await robot.set_wheel_speeds(20, 20)

robot.play()
print(json.dumps({{"log": log, "pose": backend.true_pose()}}), file=sys.stderr)
"""


def _run_script(tmp_path, start, options):
    """Run the plain SDK bounce script (drive; on a bump stop, report, turn left 90°,
    report) in a fresh interpreter; returns its log and the body's final pose.
    """
    pytest.importorskip("irobot_edu_sdk")
    path = tmp_path / "bounce.py"
    path.write_text(SCRIPT.format(start=start, options=options))
    done = subprocess.run([sys.executable, str(path)], capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
    (line,) = [x for x in done.stderr.splitlines() if x.startswith('{"log"')]
    record = json.loads(line)
    return [tuple(e) for e in record["log"]], record["pose"]


def test_sdk_script_runs_unchanged_against_the_emulator(tmp_path):
    log, (x, y, h) = _run_script(tmp_path, START, 'time="lockstep"')
    run = _free_run(LAB, *START)
    (_, x0, y0, h0), (_, xb, yb, hb), (_, xt, yt, ht) = log
    assert (x0, y0, h0) == (0.0, 0.0, 90.0)
    # the robot ships with its reflex on: it reported the bump at the wall, then backed off
    assert (xb, yb, hb) == pytest.approx((0.0, run * 100, 90.0), abs=0.15)
    assert ht == pytest.approx(hb + 90.0)                # turn_left(90) adds 90° to heading
    assert (xt, yt) == pytest.approx((xb, yb - 2.0), abs=0.15)   # the 2 cm reflex
    assert x == pytest.approx(START[0] + run - 0.02, abs=1e-3) and h % 360 == pytest.approx(90)


@pytest.mark.realtime
def test_sdk_script_in_real_time(tmp_path):
    start = (2.0, 0.51, 0.0)                              # 0.21 m from the wall: ~1 s
    log, _ = _run_script(tmp_path, start, 'time="real", reflex=False')
    run = _free_run(LAB, *start)
    assert [entry[0] for entry in log] == ["start", "bump", "turned"]
    assert log[1][2] == pytest.approx(run * 100, abs=0.5)
    assert log[2][3] == pytest.approx(180.0)


# ---------------------------------------------------------------- the adapter
def _c3(env=LAB, **kw):
    return make_robot("create3-emulator", env, **kw)


def test_adapter_bump_distance_and_turn_are_the_twin_s():
    with _c3() as bot:
        bot.place(*START)
        ev = bot.drive_until_bump(0.2, 60.0)
        run = _free_run(LAB, *START)
        assert ev.bumped and (ev.left, ev.right) == (True, True)
        assert ev.elapsed == pytest.approx(run / 0.2, abs=1e-9)
        bot.turn(90.0)
        assert bot.true_pose()[2] % 360 == pytest.approx(90.0)
        assert bot.get_position()[2] == pytest.approx(180.0)     # 90 at start, +90
        ev = bot.drive_until_bump(0.2, 2.0)                      # 1.13 m free: times out
        assert not ev.bumped and ev.elapsed == pytest.approx(2.0)


def test_clock_turns_match_rotate_turns():
    poses = []
    for turn in ("rotate", "clock"):
        with _c3(turn=turn) as bot:
            bot.place(0.51, 0.51, 10.0)
            bot.turn(135.0)
            bot.turn(-45.0)
            poses.append(bot.true_pose())
    assert poses[0] == pytest.approx(poses[1], abs=1e-6)
    assert poses[0][2] % 360 == pytest.approx(100.0)
    assert poses[0][:2] == pytest.approx((0.51, 0.51))


@pytest.mark.parametrize("fault, act, message", [
    ("disconnect@1", "drive", "lost the link to the Create 3"),
    ("stall-left@1", "drive", "left wheel motor stalled"),
    ("drop-response@1", "turn", "did not answer command 1/12"),
])
def test_faults_are_one_sentence_and_the_robot_stops(fault, act, message):
    bot = _c3(faults=[fault])
    emu = bot.backend.emulator
    bot.place(*START)
    bot.wait(1.5)
    with pytest.raises(RobotError, match=message) as info:
        if act == "drive":
            bot.drive_until_bump(0.2, 60.0)
        else:
            bot.turn(90.0)
    text = str(info.value)
    assert text.endswith(".") and "\n" not in text and text.count(". ") == 0
    bot.close()
    emu.advance(emu.body.t + 5.0)
    assert emu.body.actual_wheels() == (0.0, 0.0)
    before = emu.body.true_pose()
    emu.advance(emu.body.t + 5.0)
    assert emu.body.true_pose() == before                     # stopped, not drifting


def test_garbage_is_counted_and_the_run_goes_on():
    with _c3(faults=["garbage@0.5"]) as bot:
        bot.place(*START)
        ev = bot.drive_until_bump(0.2, 60.0)
        assert ev.bumped and bot.dropped == 1


def test_a_robot_that_never_connects_is_one_sentence_not_a_hang():
    with pytest.raises(RobotError, match=r"no Create 3 answered within 20 s"):
        _c3(faults=["no-connect"])


def test_options_and_faults_are_checked():
    with pytest.raises(UserError, match="unknown fault 'lift'"):
        _c3(faults=["lift@1"])
    with pytest.raises(UserError, match="rotate' or 'clock"):
        _c3(turn="encoders")
    with pytest.raises(UserError, match="takes no option 'port'"):
        _c3(port="/dev/null")
    with pytest.raises(UserError, match="a real Create 3 brings its own"):
        pytest.importorskip("irobot_edu_sdk")
        make_robot("create3", LAB, noise=GaussianNoise(2.0), rng=0)


# ---------------------------------------------------------------- the same plans
def test_exact_plan_and_noisy_runs_match_the_twin():
    cells = CellSpace(LAB)
    route = ExactNavigator(cells, (90.0, 135.0)).plan(103, 8)
    for seed in (0, 1, 2):
        results = []
        for kind, kw in (("kinematic", {"glance_deg": 80.0}), ("create3-emulator", {})):
            noise = GaussianNoise(2.0)
            with make_robot(kind, LAB, noise=noise, rng=np.random.default_rng(seed),
                            **kw) as bot:
                results.append(execute(route.plan, bot, start=route.start, goal=route.goal,
                                       cells=cells))
        twin, c3 = results
        assert c3.success == twin.success
        assert c3.final_pose == pytest.approx(twin.final_pose, abs=1e-6)


def test_cli_done_when(capsys):
    from bouncesim.cli import main
    assert main(["run-plan", "lab", "--angles", "90,135", "--start", "8", "--goal", "0",
                 "--robot", "create3-emulator", "--json", "--quiet"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["success"] and out["robot"] == "create3-emulator" and out["bumps"] == 4


@pytest.mark.parametrize("argv, message", [
    (["--robot", "create3-emulator", "--lockstep"], "--time-scale and --lockstep are for "
     "--robot emulator, not create3-emulator."),
    (["--robot", "create3-emulator", "--turn", "encoders"], "--turn encoders is for --robot "
     "create2 or emulator, not create3-emulator."),
    (["--robot", "emulator", "--name", "x"], "--name is for --robot create3, not emulator."),
])
def test_cli_refuses_flags_of_other_robots(argv, message, capsys):
    from bouncesim.cli import main
    assert main(["run-plan", "lab", "--angles", "90", "--start", "8", "--goal", "0"] + argv) == 2
    assert message in capsys.readouterr().err


def test_bump_event_payload_is_the_protocol_s():
    emu = Create3Emulator(LAB, start=(2.0, 0.51, 0.0), reflex=False, slowdown=False)
    emu.connect(0.0)
    emu.receive(Packet.wheel_speeds(10, 10, 0).to_bytes(), 0.0)
    emu.advance(5.0)
    raw = [Packet.from_bytes(r) for r in emu.due(5.0)][-1]
    assert (raw.device, raw.command) == (12, 0)
    (ms,) = struct.unpack(">I", raw.payload[:4])
    assert raw.payload[4] == 0xC0 and ms > 0


@pytest.mark.slow
def test_nav_create3_quick_plans_end_where_the_twin_ends_them(tmp_path):
    pytest.importorskip("serial")
    import pandas as pd

    from experiments import nav_create3
    assert nav_create3.main(["--quick", "--out", str(tmp_path)]) == 0
    poses = pd.read_csv(tmp_path / "poses.csv")
    plans = poses[poses["query"] != "feedback"]
    assert len(plans) == 8 and plans["success_create3-emulator"].all()
    assert (plans["gap_m_create3-emulator"] < 1e-6).all()
    assert (plans["gap_deg_create3-emulator"] < 1e-6).all()
    assert (plans["gap_deg_emulator"] < 0.5).all()           # encoder turns: ~0.2°
    assert json.loads((tmp_path / "config.json").read_text())["bodies"][-1] == \
        "create3-emulator"


def test_sigterm_stops_the_robot(tmp_path):
    script = tmp_path / "term.py"
    script.write_text(
        "import os, signal, sys\n"
        "import envs\n"
        "from bouncesim.robots import make_robot\n"
        "bot = make_robot('create3-emulator', envs.load('lab'))\n"
        "try:\n"
        "    with bot:\n"
        "        bot.place(0.51, 0.51, 0.0)\n"
        "        bot.drive(0.2)\n"
        "        os.kill(os.getpid(), signal.SIGTERM)\n"
        "        bot.wait(1.0)\n"
        "finally:\n"
        "    print(bot.backend.emulator.body.actual_wheels(), file=sys.stderr)\n")
    done = subprocess.run([sys.executable, str(script)], capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 143
    assert done.stderr.strip().splitlines()[-1] == "(0.0, 0.0)"
