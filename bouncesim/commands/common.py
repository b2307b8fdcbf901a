"""Argument helpers shared by the sub-commands."""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

import numpy as np

import envs
from bouncesim.runs.options import parse_angles
from envs import UserError
from planners.cells import CellSpace
from planners.resources import max_grid_cells, parse_memory

__all__ = ["add_env_args", "load_env", "make_cells", "make_rng", "max_memory", "parse_angles",
           "print_json", "writable_path"]


def add_env_args(p: argparse.ArgumentParser) -> None:
    """ENV plus the --cell-size / --orientations overrides."""
    p.add_argument("env", metavar="ENV",
                   help="catalogue name (%s) or path to an env file" % ", ".join(envs.names()))
    p.add_argument("--cell-size", type=float, default=None, metavar="M",
                   help="override the file's cell size [m]")
    p.add_argument("--orientations", type=int, default=None, metavar="K",
                   help="override the file's number of orientations")
    p.add_argument("--max-memory", default="4G", metavar="SIZE",
                   help="refuse, before allocating, a job whose estimated peak memory "
                   "exceeds SIZE (e.g. 500M, 2G; default 4G)")


def max_memory(args: argparse.Namespace) -> int:
    """--max-memory in bytes."""
    return parse_memory(args.max_memory)


def load_env(args: argparse.Namespace) -> envs.Environment:
    """ENV with the overrides; a grid too large for --max-memory is refused before it is
    built.
    """
    return envs.load(args.env, cell_size=args.cell_size, orientations=args.orientations,
                     max_grid_cells=max_grid_cells(max_memory(args)))


def make_cells(args: argparse.Namespace, env: envs.Environment) -> CellSpace:
    """The cell space of ENV, refusing a step table above --max-memory."""
    return CellSpace(env, max_memory=max_memory(args))


def make_rng(seed) -> np.random.Generator:
    """The random generator of --seed (a non-negative integer)."""
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise UserError(f"--seed must be a non-negative integer, got {seed}.")
    return np.random.default_rng(seed)


def writable_path(path, what: str = "--out", folder: bool = False) -> Path:
    """Check that an output file (or, with ``folder``, a folder, created here) can be
    written, before any long work; :class:`UserError` in one sentence otherwise.
    """
    if not str(path).strip():           # Path("") would be the current folder
        raise UserError(f"{what} needs a {'folder' if folder else 'file'} name.")
    p = Path(path)
    try:
        if folder:
            p.mkdir(parents=True, exist_ok=True)
            probe_dir = p
        else:
            if p.is_dir():
                raise UserError(f"{what} {p} is a folder, not a file.")
            p.parent.mkdir(parents=True, exist_ok=True)
            probe_dir = p.parent
            if p.exists():
                open(p, "a").close()
        with tempfile.TemporaryFile(dir=probe_dir):
            pass
    except (OSError, ValueError) as exc:
        reason = getattr(exc, "strerror", None) or str(exc)
        raise UserError(f"cannot write {what} {p} ({reason}).") from None
    return p


def print_json(obj, file=None) -> None:
    """Print ``obj`` as one line of JSON (non-ASCII kept, e.g. ``°``)."""
    print(json.dumps(obj, separators=(", ", ": "), ensure_ascii=False),
          file=file or sys.stdout)
