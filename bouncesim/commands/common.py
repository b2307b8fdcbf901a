"""Argument helpers shared by the sub-commands."""

from __future__ import annotations

import argparse
import json
import sys

import envs
from envs import UserError

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
    return envs.load(args.env, cell_size=args.cell_size, orientations=args.orientations)


def parse_angles(text: str) -> list[float]:
    """'45,90,135' -> [45.0, 90.0, 135.0]; duplicates and junk are errors."""
    out = []
    for tok in str(text).replace(" ", "").split(","):
        if not tok:
            continue
        try:
            out.append(float(tok.rstrip("°")))
        except ValueError:
            raise UserError(f"--angles takes numbers of degrees separated by commas, "
                            f"got {tok!r}.") from None
    if not out:
        raise UserError("--angles needs at least one bouncing angle.")
    if len(set(out)) != len(out):
        raise UserError(f"--angles lists an angle twice ({text}).")
    return out


def print_json(obj, file=None) -> None:
    print(json.dumps(obj, separators=(", ", ": "), ensure_ascii=False),
          file=file or sys.stdout)
