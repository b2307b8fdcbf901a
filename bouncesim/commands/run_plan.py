"""``bouncesim run-plan``: plan from START to GOAL and execute the plan on a robot (simulated,
emulated, or a real Create 2 or Create 3).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from bouncesim.robots import KINDS, make_robot
from bouncesim.robots.noise import parse_noise
from bouncesim.runs.execute import check_speed, execute, place_if_simulated
from envs import UserError
from planners.navigation import planner_class

from .common import (
    FIGURE_FORMATS,
    add_contact_arg,
    add_env_args,
    add_output,
    flush_warnings,
    load_env,
    make_cells,
    make_rng,
    print_json,
    progress,
    report_written,
    write_config,
)
from .plan import add_planner_args, make_planner_of, parse_config

__all__ = ["register", "run", "EXIT_FAILURE", "EXIT_NO_PATH"]

EXIT_NO_PATH = 3
EXIT_FAILURE = 4
ROBOTS = KINDS


def register(sub) -> None:
    """Add the ``run-plan`` sub-command to the CLI's sub-parsers."""
    p = sub.add_parser(
        "run-plan", help="plan from START to GOAL and run the plan on a robot",
        description="Find the shortest bouncing plan from START to GOAL (as `bouncesim plan` "
        "does) and execute it on a robot (docs/model.md §21): drive until a bump, turn CCW "
        "by the next angle, and so on. Prints 'success' or 'failure: <reason>' with the "
        "final pose error. A real Create 2 has no pose: a plan it completes prints "
        "'finished' (check the goal by eye). Exit status 0 on success (or a completed plan "
        "on hardware), 4 on failure, 3 when there is no plan. One progress line per plan "
        "segment goes to stderr (--quiet: none).",
        epilog="examples:\n"
        "  bouncesim run-plan lab --angles 90,135 --start 8 --goal 0\n"
        "  bouncesim run-plan lab --angles 90,135 --start 103 --goal 8 --noise gauss:1 "
        "--seed 3 --json\n"
        "    (exits 4: with any rotation noise this plan ends one cell from the goal)\n"
        "  bouncesim run-plan lab --angles 90,135 --start 8 --goal 0 --robot pybullet "
        "--record run.mp4\n"
        "  bouncesim run-plan lab --angles 90,135 --start 8 --goal 0 --robot mujoco\n"
        "  bouncesim run-plan lab --angles 90,135 --start 8 --goal 0 --robot emulator\n"
        "  bouncesim run-plan lab --angles 90,135 --start 8 --goal 0 --robot create2 "
        "--port /dev/ttyUSB0",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    add_env_args(p)
    add_planner_args(p)
    add_contact_arg(p, auto=True, what=" the planner assumes (pybullet: the rule --robot "
                    "pybullet follows)", auto_text="feedback: the robot's own declared rule "
                    "at --speed (PyBullet's, MuJoCo's; none for the twin and real robots), "
                    "exact and reliable: off")
    p.add_argument("--turn-sigma", type=float, default=None, metavar="DEG",
                   help="closed-loop planners (feedback): the turn noise σ [deg] the filter "
                   "assumes (default: the σ of --noise; set it on a real robot)")
    p.add_argument("--start", required=True, metavar="S",
                   help="start: z or X,Y,DEG; unknown (--planner feedback): the robot does not "
                   "know where it starts (a simulated body is put at a random pose from "
                   "--seed) and localizes from its bumps first")
    p.add_argument("--goal", required=True, metavar="G", help="goal: z or X,Y,DEG")
    p.add_argument("--robot", choices=ROBOTS, default="kinematic",
                   help="the exact kinematic twin (default), PyBullet, MuJoCo (extra "
                   "mujoco), a real Create 2 over its Open Interface (create2, needs "
                   "--port), the Create 2 adapter driving an in-process OI emulator through "
                   "a real serial transport "
                   "(emulator), a real Create 3 over Bluetooth through iRobot's SDK "
                   "(create3, extra create3), or the Create 3 adapter on an in-process "
                   "emulator the SDK can also talk to, in emulated time (create3-emulator)")
    p.add_argument("--port", default=None, metavar="PORT",
                   help="create2: serial port or pyserial URL (/dev/ttyUSB0, COM3, "
                   "socket://127.0.0.1:8765); emulator: pty (default) or tcp")
    p.add_argument("--turn", choices=("encoders", "rotate", "clock"), default=None,
                   help="how a real or emulated robot turns in place: create2/emulator by "
                   "the wheel encoders (encoders, their default); create3/create3-emulator "
                   "by the robot's own turn command (rotate, their default); any of them by "
                   "the clock alone (clock, the paper's robot)")
    p.add_argument("--name", default=None, metavar="NAME",
                   help="create3: the robot's Bluetooth name (default: the first Create 3 "
                   "found)")
    p.add_argument("--full", action="store_true",
                   help="create2/emulator: drive in Full mode (no cliff, wheel-drop or "
                   "charger stops by the robot itself) instead of Safe")
    p.add_argument("--sensing", choices=("stream", "query"), default="stream",
                   help="create2/emulator: read the sensors from a stream (default) or by "
                   "Query List")
    p.add_argument("--wheel-base", type=float, default=None, metavar="M",
                   help="create2/emulator: effective wheel base [m] used to time or measure "
                   "turns (calibration; default 0.235)")
    p.add_argument("--link-timeout", type=float, default=None, metavar="S",
                   help="create2/emulator: seconds of listening without a valid sensor frame "
                   "before the link counts as lost and the robot is stopped (default 0.5; "
                   "raise it for a slow USB adapter or a heavily loaded host)")
    p.add_argument("--time-scale", type=float, default=1.0, metavar="X",
                   help="emulator only: run the emulated robot X times faster than real "
                   "time (default 1)")
    p.add_argument("--lockstep", action="store_true",
                   help="emulator only: run the emulated clock in lockstep with the adapter "
                   "(it moves only when the adapter reads the sensors): as fast as the host "
                   "allows, and the same result on a busy machine")
    p.add_argument("--fault", action="append", default=[], metavar="KIND[@S]",
                   help="emulators only: inject a fault S seconds after the first drive "
                   "(emulator: wheel-drop, charger, stall-left, stall-right, drop-byte, "
                   "garbage, mute) or after connecting (create3-emulator: disconnect, "
                   "drop-response, stall-left, stall-right, garbage, no-connect); "
                   "repeatable")
    p.add_argument("--noise", default="none", metavar="SPEC",
                   help="rotation noise: none, gauss:SIGMA or model:eps=E,r=R [deg], "
                   "optionally with ,scale=S,bias=B (a constant turn factor unknown within "
                   "1 ± S and offset within ±B: the simulated body draws one per run, the "
                   "feedback filter estimates it) or ,factor=F,offset=O (a body that turns "
                   "F·φ + O) (default none)")
    p.add_argument("--seed", type=int, default=0, help="seed of the noise draws (default 0)")
    p.add_argument("--speed", type=float, default=0.2, metavar="V",
                   help="drive speed [m/s] (default 0.2)")
    p.add_argument("--back-off", type=float, default=0.0, metavar="M",
                   help="back off this far [m] after each bump before turning (default 0)")
    p.add_argument("--glance", type=float, default=None, metavar="DEG",
                   help="kinematic only: a wall met more than DEG from the heading does not "
                   "press the bumper, the robot slides along it (80 matches the PyBullet "
                   "bumper arc; default: every front contact is a bump)")
    add_output(p, "--record", as_path=False, metavar="FILE", default=None,
               help="record a video of the run (pybullet only)")
    p.add_argument("--gui", action="store_true", help="show the PyBullet window (pybullet only)")
    add_output(p, "--trace", as_path=False, metavar="FILE.csv", default=None,
               help="write the run's event trace as CSV (every file written gets the run's "
               "provenance beside it: FILE.config.json with the command line, seed, map hash, "
               "versions and git revision)")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--quiet", action="store_true",
                   help="no progress lines (one per plan segment, on stderr)")
    add_output(p, "--plot", as_path=False, metavar="FILE.png|.svg|.pdf", default=None,
               suffixes=FIGURE_FORMATS,
               help="draw the executed path on the map, over the planned path (cell centres) "
               "of a planner that plans ahead")
    p.set_defaults(func=run)


def run(args) -> int:
    """Run ``bouncesim run-plan``: plan, execute on the chosen body; exit status (4: failed)."""
    env = load_env(args)
    cells = make_cells(args, env)
    cls = planner_class(args.planner)
    unknown_start = str(args.start).strip().lower() == "unknown"
    if unknown_start and not cls.closed_loop:
        raise UserError(f"--start unknown needs a closed-loop planner (--planner feedback); "
                        f"the {args.planner} planner plans from a known start.")
    start = None if unknown_start else parse_config(args.start, cells, "start")
    goal = parse_config(args.goal, cells, "goal")
    noise = parse_noise(args.noise, cells.delta_deg)
    _check_robot_flags(args)
    if args.link_timeout is not None and not 0 < args.link_timeout < float("inf"):
        raise UserError(f"--link-timeout must be a positive number of seconds, got "
                        f"{args.link_timeout:g}.")
    if args.robot in ("create2", "create3") and not noise.exact:
        body = {"create2": "Create 2", "create3": "Create 3"}[args.robot]
        raise UserError(f"--noise is for simulated robots; a real {body} brings its own.")
    if cls.closed_loop:
        return _run_closed_loop(args, env, cells, start, goal, noise)
    if args.turn_sigma is not None:
        raise UserError("--turn-sigma is for closed-loop planners (--planner feedback).")
    nav = make_planner_of(args, cells)
    route = nav.plan(start, goal)
    if route is None:
        if args.json:
            print_json({"start": start, "goal": goal, "plan": None, "cost": None,
                        "success": None, "reason": "no path"})
        else:
            print(f"{start} -> {goal}: no path with angles "
                  f"{', '.join(f'{a:g}°' for a in nav.angles)}")
        return EXIT_NO_PATH
    rng = make_rng(args.seed)
    say = progress(args)
    robot = make_robot(args.robot, env, noise=noise, rng=rng, **_robot_options(args))
    with robot:
        check_speed(args.speed, robot)          # the last user error before the robot moves
        flush_warnings()
        if say:
            say(f"running {len(route.plan.segments())} segment(s) on the {args.robot} robot")
        result = execute(route.plan, robot, start=start, goal=goal, cells=cells,
                         speed=args.speed, back_off=args.back_off,
                         on_segment=say and (lambda seg: say(str(seg))))
        if getattr(robot, "recorder", None) is not None and len(result.trace):
            # the video's overlay: goal, plan segment, and the run's clock (trace t = 0)
            robot.recorder.annotate_plan(
                route.plan, result.trace, goal=result.goal_pose,
                t0=robot.clock() - result.trace[-1].t,
                title=f"{env.name}: {start} → {goal} (green: goal, orange: path so far)")
    written = _save_outputs(args, env, cells, result, route.path or route.poses,
                            f"{env.name}: {route.start} → {route.goal}, plan {route.plan}")
    # hardware: the plan ran to its end but nothing can tell whether the goal was reached
    unknown = result.final_pose is None and result.reason.startswith("plan finished")
    if args.json:
        out = {"start": start, "goal": goal, "robot": args.robot, "noise": str(noise),
               "seed": args.seed, "glance": args.glance, "cost": route.cost}
        out.update(result.to_json())
        print_json(out)
    else:
        print(f"{start} -> {goal}: {route.plan.exact_text()}  (cost {route.cost:.6g})")
        err = ""
        if result.position_error is not None:
            err = (f" (final pose error {result.position_error:.3f} m, "
                   f"{result.heading_error:+.1f}°)")
        if result.deviations:
            err += f", {len(result.deviations)} deviation(s)"
        if result.success:
            print(f"success{err}")
        elif unknown:
            print(f"finished{err}: the robot reports no pose; check the goal by eye")
        else:
            print(f"failure: {result.reason}{err}")
    if not (result.success or unknown or noise.exact or args.quiet):
        say("note: with rotation noise a run can miss the goal; exit status 4 reports that "
            "outcome, it is not an error")
    report_written(written, args)
    return 0 if result.success or unknown else EXIT_FAILURE


_ROBOT_FLAGS = (
    # (flags, set in args?, the robots they are for)
    ("--gui and --record", lambda a: a.gui or a.record, ("pybullet",)),
    ("--glance", lambda a: a.glance is not None, ("kinematic",)),
    ("--port, --full, --sensing, --wheel-base and --link-timeout",
     lambda a: a.port or a.full or a.sensing != "stream" or a.wheel_base is not None or
     a.link_timeout is not None, ("create2", "emulator")),
    ("--time-scale and --lockstep", lambda a: a.time_scale != 1.0 or a.lockstep,
     ("emulator",)),
    ("--fault", lambda a: a.fault, ("emulator", "create3-emulator")),
    ("--name", lambda a: a.name, ("create3",)),
    ("--turn encoders", lambda a: a.turn == "encoders", ("create2", "emulator")),
    ("--turn rotate", lambda a: a.turn == "rotate", ("create3", "create3-emulator")),
    ("--turn clock", lambda a: a.turn == "clock",
     ("create2", "emulator", "create3", "create3-emulator")),
)


def _check_robot_flags(args) -> None:
    """Refuse, in one sentence, a flag that the chosen ``--robot`` does not take."""
    for flags, given, robots in _ROBOT_FLAGS:
        if given(args) and args.robot not in robots:
            verb = "is" if " and " not in flags else "are"
            names = " or ".join(robots)
            raise UserError(f"{flags} {verb} for --robot {names}, not {args.robot}.")


def _robot_options(args) -> dict:
    """The options of :func:`bouncesim.robots.make_robot` for ``--robot``."""
    if args.robot == "kinematic":
        return {"glance_deg": args.glance}
    if args.robot == "pybullet":
        return {"gui": args.gui, "record": args.record}
    if args.robot == "mujoco":
        return {}
    if args.robot in ("create3", "create3-emulator"):
        options = {"turn": args.turn or "rotate"}
        if args.robot == "create3":
            return {**options, "name": args.name}
        return {**options, "faults": args.fault}
    options = {"mode": "full" if args.full else "safe", "turn": args.turn or "encoders",
               "sensing": args.sensing, "wheel_base": args.wheel_base}
    if args.link_timeout is not None:
        options["link_timeout"] = args.link_timeout
    if args.robot == "create2":
        if not args.port:
            raise UserError("--robot create2 needs --port (e.g. /dev/ttyUSB0).")
        return {**options, "port": args.port}
    transport = args.port or "pty"
    if transport not in ("pty", "tcp"):
        raise UserError(f"--robot emulator takes --port pty or tcp, got {args.port!r}.")
    return {**options, "transport": transport, "time_scale": args.time_scale,
            "faults": args.fault, "lockstep": args.lockstep}


def _save_outputs(args, env, cells, result, path, title: str) -> list[Path]:
    """--trace, --plot (the planned route ``path``, if any, against the executed trace; a
    hardware run has no poses to draw) and --record, each with the run's provenance beside it
    in ``NAME.config.json``; returns the files written.
    """
    written = []
    if args.trace:
        result.trace.to_csv(args.trace)
        written.append(Path(args.trace))
    if args.plot:
        if any(r.x == r.x for r in result.trace.rows):      # NaN poses only: hardware
            from bouncesim.plots import plan_vs_executed, save_figure
            status = "success" if result.success else "failure"
            written.append(save_figure(
                plan_vs_executed(env, cells, path, result.trace, goal=result.goal_pose,
                                 title=f"{title}; executed: {status}"), args.plot, dpi=150))
        else:
            print("bouncesim: note: --plot skipped, the robot reports no poses.",
                  file=sys.stderr)
    if getattr(args, "record", None) and Path(args.record).is_file():
        written.append(Path(args.record))
    for config in dict.fromkeys(p.with_suffix(".config.json") for p in written):
        written.append(write_config(config, args, env))
    return written


# ------------------------------------------------- closed-loop planners (docs/model.md §15)
def _run_closed_loop(args, env, cells, start: int, goal: int, noise) -> int:
    """``run-plan`` with a closed-loop planner (feedback): its policy decides after every bump
    in the one run loop (:func:`bouncesim.runs.execute.execute`).
    """
    declared = noise if args.turn_sigma is None else float(args.turn_sigma)
    robot_rng, planner_rng = make_rng(args.seed).spawn(2)
    planner = make_planner_of(args, cells, rng=planner_rng, noise=declared)
    say = progress(args)
    robot = make_robot(args.robot, env, noise=noise, rng=robot_rng, **_robot_options(args))
    with robot:
        check_speed(args.speed, robot)
        flush_warnings()
        true_start = None
        if start is None:           # unknown: a simulated body goes to a random pose
            true_start = env.random_pose(make_rng(args.seed).spawn(3)[2])
            if not place_if_simulated(robot, true_start):
                true_start = None   # hardware: wherever a person put it
        if say:
            say(f"{args.planner} navigation on the {args.robot} robot"
                + (" from an unknown start" if start is None else ""))
        result = execute(planner.policy(start, goal), robot, cells=cells, speed=args.speed,
                         back_off=args.back_off)
    written = _save_outputs(args, env, cells, result, None,
                            f"{env.name}: {'unknown' if start is None else start} → {goal}, "
                            f"{args.planner} navigation")
    unknown = result.final_pose is None and result.completed
    if args.json:
        out = {"start": "unknown" if start is None else start, "goal": goal,
               "robot": args.robot, "noise": str(noise), "seed": args.seed,
               "glance": args.glance}
        if true_start is not None:
            out["true_start"] = [round(v, 6) for v in true_start]
        out.update(result.to_json())
        print_json(out)
    else:
        print(f"{'unknown' if start is None else start} -> {goal}: {args.planner}, executed "
              f"{result.plan.exact_text()}")
        ms = max(result.decision_ms, default=0.0)
        err = "" if result.position_error is None else (
            f" (final pose error {result.position_error:.3f} m, {result.heading_error:+.1f}°)")
        status = ("success" if result.success else "finished" if unknown
                  else f"failure: {result.reason}")
        print(f"{status}{err}; {result.bumps} bump(s), slowest decision {ms:.1f} ms")
        if start is None:
            where = ("never localized" if result.bumps_to_localize is None
                     else f"localized after {result.bumps_to_localize} bump(s)")
            print(f"unknown start: {where}")
        if planner.turn_model["scale"] or planner.turn_model["bias"]:
            f, sf, b, sb = result.turn_estimate
            print(f"turn estimate: factor {f:.3f} ± {sf:.3f}, offset {b:+.2f}° ± {sb:.2f}°")
    report_written(written, args)
    return 0 if result.success or unknown else EXIT_FAILURE

