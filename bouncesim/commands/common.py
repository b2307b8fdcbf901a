"""Argument helpers shared by the sub-commands."""

from __future__ import annotations

import argparse
import json
import sys

import envs
from bouncesim.runs.options import parse_angles

__all__ = ["add_env_args", "load_env", "parse_angles", "print_json"]


def add_env_args(p: argparse.ArgumentParser) -> None:
    """ENV plus the --cell-size / --orientations overrides."""
    p.add_argument("env", metavar="ENV",
                   help="catalogue name (%s) or path to an env file" % ", ".join(envs.names()))
    p.add_argument("--cell-size", type=float, default=None, metavar="M",
                   help="override the file's cell size [m]")
    p.add_argument("--orientations", type=int, default=None, metavar="K",
                   help="override the file's number of orientations")


def load_env(args: argparse.Namespace) -> envs.Environment:
    """The environment named by ``--env`` with the ``--cell-size`` and ``--orientations``
    overrides.
    """
    return envs.load(args.env, cell_size=args.cell_size, orientations=args.orientations)


def print_json(obj, file=None) -> None:
    """Print ``obj`` as one line of JSON (non-ASCII kept, e.g. ``°``)."""
    print(json.dumps(obj, separators=(", ", ": "), ensure_ascii=False),
          file=file or sys.stdout)
