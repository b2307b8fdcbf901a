"""``bouncesim run-plan``: plan from START to GOAL and execute the plan on a simulated robot."""

from __future__ import annotations

import argparse

import numpy as np

from envs import UserError
from planners.cells import CellSpace
from planners.navigation import Navigator

from .common import add_env_args, load_env, parse_angles, print_json
from .plan import add_planner_args, parse_config

__all__ = ["register", "run", "make_robot", "EXIT_FAILURE", "EXIT_NO_PATH"]

EXIT_NO_PATH = 3
EXIT_FAILURE = 4
ROBOTS = ("kinematic", "pybullet")


def register(sub) -> None:
    p = sub.add_parser(
        "run-plan", help="plan from START to GOAL and run the plan on a simulated robot",
        description="Find the shortest bouncing plan from START to GOAL (as `bouncesim plan` "
        "does) and execute it on a simulated robot (MODEL §8): drive until a bump, turn CCW "
        "by the next angle, and so on. Prints 'success' or 'failure: <reason>' with the "
        "final pose error. Exit status 0 on success, 4 on failure, 3 when there is no plan.",
        epilog="examples:\n"
        "  bouncesim run-plan lab --angles 90,135 --start 8 --goal 0\n"
        "  bouncesim run-plan lab --angles 90,135 --start 103 --goal 8 --noise gauss:1 "
        "--seed 3 --json\n"
        "  bouncesim run-plan lab --angles 90,135 --start 8 --goal 0 --robot pybullet "
        "--record run.mp4",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    add_env_args(p)
    add_planner_args(p)
    p.add_argument("--start", required=True, metavar="S", help="start: z or X,Y,DEG")
    p.add_argument("--goal", required=True, metavar="G", help="goal: z or X,Y,DEG")
    p.add_argument("--robot", choices=ROBOTS, default="kinematic",
                   help="simulated robot: the exact kinematic twin (default) or PyBullet")
    p.add_argument("--noise", default="none", metavar="SPEC",
                   help="rotation noise: none, gauss:SIGMA or model:eps=E,r=R [deg] "
                   "(default none)")
    p.add_argument("--seed", type=int, default=0, help="seed of the noise draws (default 0)")
    p.add_argument("--speed", type=float, default=0.2, metavar="V",
                   help="drive speed [m/s] (default 0.2)")
    p.add_argument("--back-off", type=float, default=0.0, metavar="M",
                   help="back off this far [m] after each bump before turning (default 0)")
    p.add_argument("--glance", type=float, default=None, metavar="DEG",
                   help="kinematic only: a wall met more than DEG from the heading does not "
                   "press the bumper, the robot slides along it (80 matches the PyBullet "
                   "bumper arc; default: every front contact is a bump)")
    p.add_argument("--record", metavar="FILE", default=None,
                   help="record a video of the run (pybullet only)")
    p.add_argument("--gui", action="store_true", help="show the PyBullet window (pybullet only)")
    p.add_argument("--trace", metavar="FILE.csv", default=None,
                   help="write the run's event trace as CSV")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=run)


def make_robot(kind: str, env, noise, rng, *, gui: bool = False, record=None,
               glance: float | None = None):
    """Build a simulated robot by name (``kinematic`` or ``pybullet``, imported lazily)."""
    if kind == "kinematic":
        if gui or record:
            raise UserError("--gui and --record need --robot pybullet.")
        from bouncesim.kinematic import KinematicRobot
        return KinematicRobot(env, noise=noise, rng=rng, glance_deg=glance)
    if kind == "pybullet":
        if glance is not None:
            raise UserError("--glance is for --robot kinematic (the PyBullet bumper has its "
                            "own 80° arc).")
        try:
            from bouncesim.pybullet_world import PyBulletRobot
        except ModuleNotFoundError as exc:
            raise UserError(f"--robot pybullet needs the simulation extra ({exc.name} is "
                            "missing): pip install -e '.[sim]'.") from None
        return PyBulletRobot(env, noise=noise, rng=rng, gui=gui, record=record)
    raise UserError(f"unknown robot {kind!r}; use {' or '.join(ROBOTS)}.")


def run(args) -> int:
    from bouncesim.execute import execute_plan
    from bouncesim.noise import parse_noise

    env = load_env(args)
    cells = CellSpace(env)
    nav = Navigator(cells, parse_angles(args.angles), args.w1, args.w2)
    start = parse_config(args.start, cells, "start")
    goal = parse_config(args.goal, cells, "goal")
    noise = parse_noise(args.noise, cells.delta_deg)
    if args.robot == "kinematic" and (args.gui or args.record):
        raise UserError("--gui and --record need --robot pybullet.")
    if args.robot != "kinematic" and args.glance is not None:
        raise UserError("--glance is for --robot kinematic (the PyBullet bumper has its own "
                        "80° arc).")
    route = nav.plan(start, goal)
    if route is None:
        if args.json:
            print_json({"start": start, "goal": goal, "plan": None, "cost": None,
                        "success": None, "reason": "no path"})
        else:
            print(f"{start} -> {goal}: no path with angles "
                  f"{', '.join(f'{a:g}°' for a in nav.angles)}")
        return EXIT_NO_PATH
    rng = np.random.default_rng(args.seed)
    robot = make_robot(args.robot, env, noise, rng, gui=args.gui, record=args.record,
                       glance=args.glance)
    with robot:
        result = execute_plan(route.plan, robot, env, start, goal, cells, speed=args.speed,
                              back_off=args.back_off)
    if args.trace:
        result.trace.to_csv(args.trace)
    if args.json:
        out = {"start": start, "goal": goal, "robot": args.robot, "noise": str(noise),
               "seed": args.seed, "glance": args.glance, "cost": route.cost}
        out.update(result.to_json())
        print_json(out)
    else:
        print(f"{start} -> {goal}: {route.plan}  (cost {route.cost:g})")
        err = ""
        if result.position_error is not None:
            err = (f" (final pose error {result.position_error:.3f} m, "
                   f"{result.heading_error:+.1f}°)")
        if result.deviations:
            err += f", {len(result.deviations)} deviation(s)"
        if result.success:
            print(f"success{err}")
        else:
            print(f"failure: {result.reason}{err}")
    return 0 if result.success else EXIT_FAILURE
