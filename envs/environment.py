"""Environments: polygons, validation, free space and segment checks (docs/model.md §1, §2, §4).

An :class:`Environment` holds the outer wall polygon W, the obstacle polygons, the robot
radius [m] and the discretisation (cell size [m], number of orientations K). It answers the
geometric questions the rest of the project asks, vectorised over many points or segments:

- :meth:`Environment.points_free`: is the robot disk centred at each point inside E?
- :meth:`Environment.segments_free`: can the disk slide along each segment without touching
  a wall?

Examples
--------
>>> env = Environment.from_dict({"boundary": [[0, 0], [1.02, 0], [1.02, 0.68], [0, 0.68]],
...                              "robot_radius": 0.17,
...                              "discretization": {"cell_size": 0.34, "orientations": 8}})
>>> bool(env.points_free([[0.17, 0.17]])[0])       # touching two walls exactly is allowed
True
>>> bool(env.points_free([[0.10, 0.17]])[0])
False
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field, replace
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np
import shapely
from numpy.typing import ArrayLike
from shapely.geometry import Polygon
from shapely.validation import explain_validity

from .errors import InvalidEnvironment, UserError

__all__ = ["MAX_GRID_CELLS", "Environment", "InvalidEnvironment", "grid_shape"]

_TOP_KEYS = {"name", "description", "boundary", "obstacles", "robot_radius",
             "discretization", "meta"}
_DISC_KEYS = {"cell_size", "orientations"}
# Grids above this many cells are refused outright (at ~370 bytes per cell to validate, tens
# of GB); a caller with a memory budget passes a smaller max_grid_cells.
MAX_GRID_CELLS = 2**27


def _polygon(coords: Any, what: str) -> Polygon:
    try:
        arr = np.asarray(coords, dtype=float)
    except (TypeError, ValueError):
        raise InvalidEnvironment(f"{what} must be a list of [x, y] pairs of numbers.") from None
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise InvalidEnvironment(f"{what} must be a list of [x, y] pairs of numbers.")
    if not np.all(np.isfinite(arr)):
        raise InvalidEnvironment(f"{what} has a coordinate that is not a finite number.")
    if len(arr) > 1 and np.allclose(arr[0], arr[-1]):
        arr = arr[:-1]  # a closed ring repeats its first vertex
    if len(np.unique(arr, axis=0)) < 3:
        raise InvalidEnvironment(f"{what} has fewer than 3 distinct vertices.")
    poly = Polygon(arr)
    if not poly.is_valid:
        raise InvalidEnvironment(f"{what} is self-intersecting ({explain_validity(poly)}).")
    if poly.area <= 0:
        raise InvalidEnvironment(f"{what} has zero area.")
    return poly


@dataclass(frozen=True, eq=False)
class Environment:
    """A validated workspace with a disk robot and a discretisation.

    Parameters
    ----------
    name, description : str
    boundary : Polygon
        Outer wall polygon W [m].
    obstacles : tuple of Polygon
        Obstacles inside W [m]; they may touch W's boundary and each other.
    robot_radius : float
        Radius of the disk robot [m].
    cell_size : float
        Edge of a square position cell h [m].
    orientations : int
        Number of discrete headings K (>= 4).
    meta : dict
        Free-form data carried along from the file.
    max_grid_cells : int
        Refuse a cell size whose grid has more cells than this (default
        :data:`MAX_GRID_CELLS`); a caller with a memory budget passes a smaller bound.
    """

    name: str
    description: str
    boundary: Polygon
    obstacles: tuple[Polygon, ...]
    robot_radius: float
    cell_size: float
    orientations: int
    meta: dict = field(default_factory=dict)
    source: str | None = None
    max_grid_cells: int = field(default=MAX_GRID_CELLS, repr=False)

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_dict(cls, data: dict, *, name: str | None = None, source: str | None = None,
                  max_grid_cells: int = MAX_GRID_CELLS) -> Environment:
        """Validate a parsed env file (docs/model.md §2) and build the environment."""
        if not isinstance(data, dict):
            raise InvalidEnvironment("an environment file must hold a JSON/YAML object.")
        unknown = sorted(set(data) - _TOP_KEYS)
        if unknown:
            raise InvalidEnvironment(
                f"unknown top-level key(s) {', '.join(map(repr, unknown))}; "
                f"allowed are {', '.join(sorted(_TOP_KEYS))} (put free-form data under 'meta').")
        if "boundary" not in data:
            raise InvalidEnvironment("the environment has no 'boundary' polygon.")
        boundary = _polygon(data["boundary"], "the boundary")
        obstacles = []
        raw_obs = data.get("obstacles", []) or []
        if not isinstance(raw_obs, list):
            raise InvalidEnvironment("'obstacles' must be a list of polygons.")
        for i, coords in enumerate(raw_obs):
            poly = _polygon(coords, f"obstacle {i}")
            if not boundary.buffer(1e-9).covers(poly):
                raise InvalidEnvironment(f"obstacle {i} lies (partly) outside the boundary.")
            obstacles.append(poly)
        radius = data.get("robot_radius", 0.17)
        disc = data.get("discretization", {}) or {}
        if not isinstance(disc, dict):
            raise InvalidEnvironment("'discretization' must be an object.")
        unknown = sorted(set(disc) - _DISC_KEYS)
        if unknown:
            raise InvalidEnvironment(
                f"unknown discretization key(s) {', '.join(map(repr, unknown))}; "
                "allowed are cell_size and orientations.")
        meta = data.get("meta", {}) or {}
        if not isinstance(meta, dict):
            raise InvalidEnvironment("'meta' must be an object.")
        env = cls(name=str(data.get("name") or name or "unnamed"),
                  description=str(data.get("description", "")),
                  boundary=boundary, obstacles=tuple(obstacles),
                  robot_radius=radius,
                  cell_size=disc.get("cell_size", 2 * radius if _is_num(radius) else 0.34),
                  orientations=disc.get("orientations", 8),
                  meta=dict(meta), source=source, max_grid_cells=max_grid_cells)
        return env

    @classmethod
    def from_file(cls, path: str | Path, *, max_grid_cells: int = MAX_GRID_CELLS
                  ) -> Environment:
        """Load a JSON (or YAML) env file."""
        path = Path(path)
        try:
            text = path.read_text()
        except FileNotFoundError:
            raise InvalidEnvironment(f"no environment file at {path}.") from None
        except OSError as exc:
            raise InvalidEnvironment(f"cannot read {path}: {exc.strerror}.") from None
        if path.suffix.lower() in {".yaml", ".yml"}:
            import yaml
            try:
                data = yaml.safe_load(text)
            except yaml.YAMLError as exc:
                mark = getattr(exc, "problem_mark", None)
                where = f"line {mark.line + 1}: " if mark is not None else ""
                what = getattr(exc, "problem", None) or str(exc).splitlines()[0]
                raise InvalidEnvironment(
                    f"{path} is not valid YAML ({where}{what}).") from None
        else:
            try:
                data = json.loads(text)
            except json.JSONDecodeError as exc:
                raise InvalidEnvironment(
                    f"{path} is not valid JSON (line {exc.lineno}: {exc.msg}).") from None
        return cls.from_dict(data, name=path.stem, source=str(path),
                             max_grid_cells=max_grid_cells)

    def __post_init__(self) -> None:
        if not _is_num(self.robot_radius) or self.robot_radius <= 0:
            raise InvalidEnvironment(
                f"robot_radius must be a positive number of metres, got {self.robot_radius!r}.")
        if not _is_num(self.cell_size) or self.cell_size <= 0:
            raise InvalidEnvironment(
                f"cell_size must be a positive number of metres, got {self.cell_size!r}.")
        k = self.orientations
        if isinstance(k, bool) or not isinstance(k, (int, np.integer)) and not (
                isinstance(k, float) and k.is_integer()):
            raise InvalidEnvironment(f"orientations must be a whole number, got {k!r}.")
        if int(k) < 4:
            raise InvalidEnvironment(f"orientations must be at least 4, got {k}.")
        object.__setattr__(self, "orientations", int(k))
        object.__setattr__(self, "robot_radius", float(self.robot_radius))
        object.__setattr__(self, "cell_size", float(self.cell_size))
        rows, cols = grid_shape(self.bounds, self.cell_size)
        if rows * cols > self.max_grid_cells:
            raise InvalidEnvironment(
                f"a {self.cell_size:g} m cell size gives a grid of {rows * cols:.3g} cells "
                f"over a {self.bounds[2] - self.bounds[0]:.3g} x "
                f"{self.bounds[3] - self.bounds[1]:.3g} m workspace, more than the "
                f"{self.max_grid_cells} allowed; use a larger cell size (or, in the "
                "command line, a larger --max-memory).")
        if self.free_space.is_empty:
            raise InvalidEnvironment("the obstacles cover the whole workspace.")
        if not self.grid_centres_free().any():
            raise InvalidEnvironment(
                f"no cell centre is free for a robot of radius {self.robot_radius} m "
                f"at cell size {self.cell_size} m.")

    def with_discretization(self, cell_size: float | None = None,
                            orientations: int | None = None) -> Environment:
        """A copy with another cell size [m] and/or orientation count."""
        return replace(self,
                       cell_size=self.cell_size if cell_size is None else cell_size,
                       orientations=self.orientations if orientations is None else orientations)

    def to_dict(self) -> dict:
        """The env-file form of this environment (round-trips through :meth:`from_dict`)."""
        def ring(p: Polygon) -> list:
            return [list(map(float, xy)) for xy in p.exterior.coords[:-1]]
        out = {"name": self.name, "description": self.description,
               "boundary": ring(self.boundary),
               "obstacles": [ring(o) for o in self.obstacles],
               "robot_radius": self.robot_radius,
               "discretization": {"cell_size": self.cell_size,
                                  "orientations": self.orientations}}
        if self.meta:
            out["meta"] = self.meta
        return out

    # ------------------------------------------------------------------ geometry
    @property
    def tol(self) -> float:
        """Distance tolerance [m]: 1e-9 * max(cell_size, 1) (docs/model.md §4)."""
        return 1e-9 * max(self.cell_size, 1.0)

    @cached_property
    def free_space(self):
        """E = W minus the union of the obstacles (a shapely geometry) [m]."""
        e = self.boundary
        if self.obstacles:
            e = e.difference(shapely.union_all(self.obstacles))
        shapely.prepare(e)
        return e

    @cached_property
    def walls(self):
        """The boundary of E as (multi)line geometry: every wall the robot can touch."""
        b = self.free_space.boundary
        shapely.prepare(b)
        return b

    @cached_property
    def wall_segments(self) -> np.ndarray:
        """All wall edges as an (n, 2, 2) array [m] (for vectorised ray casts)."""
        parts = shapely.get_parts(self.walls)
        segs = []
        for line in parts:
            c = np.asarray(line.coords)
            segs.append(np.stack([c[:-1], c[1:]], axis=1))
        return np.concatenate(segs, axis=0)

    @cached_property
    def cspace(self):
        """The free configuration space for the robot centre: E eroded by the radius."""
        return self.free_space.buffer(-self.robot_radius, quad_segs=32)

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """(xmin, ymin, xmax, ymax) of W [m]."""
        return tuple(float(v) for v in self.boundary.bounds)

    @property
    def origin(self) -> tuple[float, float]:
        """Lower-left corner (x0, y0) of W's bounding box: the grid origin [m]."""
        b = self.bounds
        return b[0], b[1]

    @property
    def grid_shape(self) -> tuple[int, int]:
        """(rows, columns) of the grid: ceil(height / h), ceil(width / h)."""
        rows, cols = grid_shape(self.bounds, self.cell_size)
        return int(rows), int(cols)

    def points_free(self, points: ArrayLike) -> np.ndarray:
        """Whether the robot disk centred at each point lies inside E (docs/model.md §4).

        Parameters
        ----------
        points : array_like, shape (n, 2) [m]

        Returns
        -------
        ndarray of bool, shape (n,)
        """
        pts = np.asarray(points, dtype=float).reshape(-1, 2)
        geoms = shapely.points(pts)
        inside = shapely.covers(self.free_space, geoms)
        out = np.zeros(len(pts), dtype=bool)
        if inside.any():
            d = shapely.distance(geoms[inside], self.walls)
            out[inside] = d >= self.robot_radius - self.tol
        return out

    def random_pose(self, rng: np.random.Generator) -> tuple[float, float, float]:
        """A pose uniform over the robot's free space, with a uniform heading:
        (x [m], y [m], heading [deg]), every draw from ``rng``.

        >>> from envs import load
        >>> x, y, h = load("lab").random_pose(np.random.default_rng(0))
        >>> bool(load("lab").points_free([[x, y]])[0]) and 0 <= h < 360
        True
        """
        x0, y0, x1, y1 = self.bounds
        for _ in range(10_000):
            pts = rng.uniform([x0, y0], [x1, y1], size=(64, 2))
            free = pts[self.points_free(pts)]
            if len(free):
                return float(free[0, 0]), float(free[0, 1]), float(rng.uniform(0.0, 360.0))
        raise UserError(f"{self.name} has no free space for the robot.")

    def segments_free(self, starts: ArrayLike, ends: ArrayLike) -> np.ndarray:
        """Whether the disk can slide along each segment [start, end] without a wall.

        The segment is free when it stays at distance >= radius - tol from every wall and its
        end point is covered by E (docs/model.md §7).
        """
        a = np.asarray(starts, dtype=float).reshape(-1, 2)
        b = np.asarray(ends, dtype=float).reshape(-1, 2)
        out = shapely.covers(self.free_space, shapely.points(b))
        if out.any():
            segs = shapely.linestrings(np.stack([a[out], b[out]], axis=1))
            out[out] = shapely.distance(segs, self.walls) >= self.robot_radius - self.tol
        return out

    def grid_centres_free(self) -> np.ndarray:
        """(rows, columns) boolean grid: which cell centres are free."""
        nrows, ncols = self.grid_shape
        x0, y0 = self.origin
        h = self.cell_size
        jj, ii = np.mgrid[0:nrows, 0:ncols]
        pts = np.stack([x0 + (ii.ravel() + 0.5) * h, y0 + (jj.ravel() + 0.5) * h], axis=1)
        return self.points_free(pts).reshape(nrows, ncols)

    def __repr__(self) -> str:
        return (f"Environment(name={self.name!r}, obstacles={len(self.obstacles)}, "
                f"robot_radius={self.robot_radius}, cell_size={self.cell_size}, "
                f"orientations={self.orientations})")


def grid_shape(bounds, cell_size: float) -> tuple[float, float]:
    """(rows, columns) of the grid over ``bounds`` (xmin, ymin, xmax, ymax) [m] at cell size
    [m]: ceil(height / h), ceil(width / h), at least 1; ``inf`` where the count overflows.

    >>> grid_shape((0.0, 0.0, 3.06, 2.72), 0.34)
    (8, 9)
    """
    x0, y0, x1, y1 = bounds
    h = float(cell_size)

    def count(extent: float):
        n = extent / h
        # Guard against 3.06 / 0.34 = 9.000000000000002 giving 10 columns.
        return max(1, math.ceil(n - 1e-9)) if math.isfinite(n) else math.inf
    return count(y1 - y0), count(x1 - x0)


def _is_num(x: Any) -> bool:
    return isinstance(x, (int, float, np.integer, np.floating)) and not isinstance(x, bool) \
        and math.isfinite(float(x))
