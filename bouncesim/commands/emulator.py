"""``bouncesim emulator``: serve an emulated Create 2 (Open Interface) on a pty or TCP port."""

from __future__ import annotations

import argparse
import signal
import sys
import threading
import time

from envs import UserError

from .common import add_env_args, flush_warnings, load_env, make_cells, make_rng
from .plan import parse_config

__all__ = ["register", "run"]


def register(sub) -> None:
    """Add the ``emulator`` sub-command to the CLI's sub-parsers."""
    p = sub.add_parser(
        "emulator", help="serve an emulated Create 2 Open Interface on a pty or TCP port",
        description="Run an emulated iRobot Create 2 that speaks the Open Interface byte "
        "protocol, moving in ENV (kinematic twin, 80° glancing bumper arc), until Ctrl-C. "
        "Connect the hardware path to the printed port: `bouncesim run-plan ENV ... --robot "
        "create2 --port PORT`. Place the emulated robot with --start where the plan starts "
        "(on hardware a person places the robot).",
        epilog="examples:\n"
        "  bouncesim emulator lab --port 8765 --start 8\n"
        "  bouncesim run-plan lab --angles 90,135 --start 8 --goal 0 --robot create2 "
        "--port socket://127.0.0.1:8765\n"
        "  bouncesim emulator lab --start 8 --fault wheel-drop@3   (a pty; prints its path)",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    add_env_args(p)
    p.add_argument("--port", default="pty", metavar="PORT",
                   help="pty (default: a new pseudo-terminal, its path is printed) or a TCP "
                   "port number on --host (0: any free port)")
    p.add_argument("--host", default="127.0.0.1",
                   help="TCP address to listen on (default 127.0.0.1, this machine only)")
    p.add_argument("--start", default=None, metavar="S",
                   help="initial pose: configuration z or X,Y,DEG (default: cell 0 facing "
                   "east)")
    p.add_argument("--time-scale", type=float, default=1.0, metavar="X",
                   help="emulated seconds per real second (default 1; the controller must "
                   "use the same scale, so keep 1 for `run-plan --robot create2`)")
    p.add_argument("--noise", default="none", metavar="SPEC",
                   help="body slip per in-place turn: none, gauss:SIGMA or "
                   "model:eps=E,r=R [deg] (default none)")
    p.add_argument("--seed", type=int, default=0, help="seed of the noise and faults")
    p.add_argument("--angle-bug", action="store_true",
                   help="report packet 20 (angle) scaled by 0.324056, as firmware <= 3.4.0")
    p.add_argument("--fault", action="append", default=[], metavar="KIND[@S]",
                   help="inject a fault S seconds after the first drive command: "
                   "wheel-drop, charger, stall-left, stall-right, drop-byte, garbage, mute "
                   "(repeatable)")
    p.add_argument("--duration", type=float, default=None, metavar="S",
                   help="stop after S seconds of real time (default: run until Ctrl-C)")
    p.add_argument("--quiet", action="store_true",
                   help="do not log events (connections, mode changes, faults) to stderr")
    p.set_defaults(func=run)


def run(args) -> int:
    """Run ``bouncesim emulator``: serve an emulated Create 2 until Ctrl-C; exit status."""
    from bouncesim.robots.create2 import OIEmulator, parse_fault
    from bouncesim.robots.noise import parse_noise

    env = load_env(args)
    cells = make_cells(args, env)
    start = None
    if args.start is not None:
        start = cells.pose(parse_config(args.start, cells, "start"))
    if args.port == "pty":
        transport, port = "pty", 0
    else:
        try:
            port = int(args.port)
        except ValueError:
            raise UserError(f"--port takes 'pty' or a TCP port number, got {args.port!r}.") \
                from None
        if not 0 <= port <= 65535:
            raise UserError(f"TCP port {port} is outside 0-65535.")
        transport = "tcp"
    if args.duration is not None and not args.duration > 0:
        raise UserError(f"--duration must be a positive number of seconds, got "
                        f"{args.duration:g}.")
    noise = parse_noise(args.noise, cells.delta_deg)
    faults = [parse_fault(f) for f in args.fault]

    def log(line: str) -> None:
        print(line, file=sys.stderr, flush=True)

    emu = OIEmulator(env, transport=transport, host=args.host, port=port,
                     time_scale=args.time_scale, noise=noise,
                     rng=make_rng(args.seed), angle_bug=args.angle_bug,
                     faults=faults, start=start, log=None if args.quiet else log)
    def on_sigterm(signum, frame):
        raise KeyboardInterrupt

    previous = None
    if threading.current_thread() is threading.main_thread():
        previous = signal.signal(signal.SIGTERM, on_sigterm)
    flush_warnings()
    emu.start()
    x, y, h = emu.true_pose()
    print(f"OI emulator for {env.name}: robot at ({x:.3f}, {y:.3f}) facing {h:g}°", flush=True)
    print(f"connect to: {emu.url}", flush=True)
    print("stop with Ctrl-C", flush=True)
    try:
        end = None if args.duration is None else time.monotonic() + args.duration
        while end is None or time.monotonic() < end:
            time.sleep(0.1)
    except KeyboardInterrupt:
        pass
    finally:
        emu.close()
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)
        x, y, h = emu.true_pose()
        print(f"emulator stopped; robot at ({x:.3f}, {y:.3f}) facing {h:.1f}°", flush=True)
    return 0
