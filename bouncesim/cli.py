"""The ``bouncesim`` command line: one sub-command per module in :mod:`bouncesim.commands`.

Every error a user can cause is printed as one sentence with exit status 2; a planning query
with no path exits with 3; a robot run that fails exits with 4.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys

from bouncesim.robots.base import RobotError
from envs import UserError

__all__ = ["build_parser", "main"]

# Sub-command modules, in the order --help lists them. Each defines
# ``register(subparsers)``, which adds a parser whose ``func(args)`` returns the exit status.
COMMAND_MODULES = [
    "bouncesim.commands.info",
    "bouncesim.commands.plan",
    "bouncesim.commands.allpairs",
    "bouncesim.commands.coverage",
    "bouncesim.commands.run_plan",
    "bouncesim.commands.validate",
    "bouncesim.commands.emulator",
]

EPILOG = """\
ENV is a catalogue name (lab, fig1, complex) or a path to a JSON/YAML env file.
Angles are in degrees and must be multiples of 360/K (K = orientations).

examples:
  bouncesim info lab --json
  bouncesim plan lab --angles 45,90,135 --start 8 --goal 0
  bouncesim plan lab --angles 90,135 --start 2.89,0.17,0 --goal 0.17,0.17,0 --json
  bouncesim allpairs fig1 --angles 45,90,135 --out results/allpairs_fig1
"""


def build_parser() -> argparse.ArgumentParser:
    """The ``bouncesim`` argument parser with every built command registered."""
    parser = argparse.ArgumentParser(
        prog="bouncesim",
        description="Plan, analyse and simulate minimalist bump-and-clock robots.",
        epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMAND_MODULES:
        importlib.import_module(name).register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run the ``bouncesim`` command line; returns the exit status (2: a user error)."""
    # the commands write figure files only: without a user choice, no GUI backend
    os.environ.setdefault("MPLBACKEND", "Agg")
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        return int(args.func(args) or 0)
    except UserError as exc:
        print(f"bouncesim: error: {exc}", file=sys.stderr)
        return 2
    except RobotError as exc:                   # e.g. no robot answering on the port
        print(f"bouncesim: robot error: {exc}", file=sys.stderr)
        return 4
    except KeyboardInterrupt:
        print("bouncesim: interrupted.", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
