"""Environments: load by catalogue name or path, validate, and answer geometric queries.

>>> import envs
>>> sorted(envs.names())
['complex', 'fig1', 'lab', 'studio']
>>> envs.load("lab").cell_size
0.34
"""

from __future__ import annotations

from pathlib import Path

from .environment import Environment
from .errors import InvalidEnvironment, UserError

__all__ = ["CATALOG_DIR", "Environment", "InvalidEnvironment", "UserError", "load", "names"]

CATALOG_DIR = Path(__file__).with_name("catalog")


def names() -> list[str]:
    """Names of the environments in the catalogue."""
    return sorted(p.stem for p in CATALOG_DIR.glob("*.json"))


def load(name_or_path: str | Path | dict, *, cell_size: float | None = None,
         orientations: int | None = None, max_grid_cells: int | None = None) -> Environment:
    """Load a catalogue environment by name, an env file by path, or an env given as a dict.

    Parameters
    ----------
    name_or_path : str, Path or dict
        A catalogue name (see :func:`names`), a path to a JSON/YAML env file, or the env
        file's content as a dict (:meth:`Environment.from_dict`).
    cell_size : float, optional
        Override the file's cell size [m].
    orientations : int, optional
        Override the file's number of orientations K.
    max_grid_cells : int, optional
        Refuse a grid with more cells (default ``environment.MAX_GRID_CELLS``).
    """
    kw = {} if max_grid_cells is None else {"max_grid_cells": int(max_grid_cells)}
    if isinstance(name_or_path, dict):
        env = Environment.from_dict(name_or_path, **kw)
    elif str(name_or_path) in names():
        env = Environment.from_file(CATALOG_DIR / f"{name_or_path}.json", **kw)
    elif Path(name_or_path).suffix or Path(name_or_path).exists():
        env = Environment.from_file(Path(name_or_path), **kw)
    else:
        raise InvalidEnvironment(
            f"{str(name_or_path)!r} is neither a catalogue environment "
            f"({', '.join(names())}) nor an existing file.")
    if cell_size is not None or orientations is not None:
        env = env.with_discretization(cell_size, orientations)
    return env
