"""The discrete cell model: free cells, configuration indices and the step table
(docs/model.md §4, §6, §7).

Position index p numbers the free cells row-major from the bottom; configuration index
z = k * P + p with orientation k = 0..K-1 at heading 360° k / K. The step table says, for every
configuration, where a forward step of one cell length lands (or that it bumps).

Examples
--------
>>> from envs import Environment
>>> env = Environment.from_dict({"boundary": [[0, 0], [1.02, 0], [1.02, 0.34], [0, 0.34]],
...                              "robot_radius": 0.17,
...                              "discretization": {"cell_size": 0.34, "orientations": 4}})
>>> cs = CellSpace(env)
>>> cs.P, cs.N
(3, 12)
>>> cs.forward[:3].tolist()          # facing east: 0 -> 1 -> 2 -> bump
[1, 2, -1]
>>> int(cs.rotate(2, 90.0))          # a 90° bump at p=2 facing east turns to face north
5
>>> cs.turn([[2], [0]], [1, 2]).tolist()   # turns by 1 and 2 steps of cells 2 and 0
[[5, 8], [3, 6]]
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np
import shapely

from envs import Environment, UserError
from envs.motion import grid_index, unit_rad

from .resources import DEFAULT_MAX_MEMORY, check_memory

__all__ = ["AngleError", "BODY_SNAP_M", "CellSpace", "angle_steps"]

BODY_SNAP_M = 0.005
"""[m] A body's centre this close outside the C-space is counted at the nearest C-space point
(:meth:`CellSpace.cell_of_body`, docs/model.md §22): a physics body's disk is 2 mm smaller
than the model's robot and its contacts penetrate a little, so at a wall it stands 1–3 mm
beyond the model's contact."""


class AngleError(UserError):
    """A bouncing angle that is not a multiple of 360°/K in (0°, 360°)."""


def angle_steps(angle_deg: float, K: int, what: str = "bouncing angle",
                allow_zero: bool = False) -> int:
    """Convert an angle [deg] to a whole number of orientation steps Δ = 360°/K.

    Raises :class:`AngleError` (one sentence naming the allowed multiples) otherwise.

    >>> angle_steps(135, 8)
    3
    >>> angle_steps(100, 8)  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    planners.cells.AngleError: bouncing angle 100° is not allowed ... multiple of 45° ...
    """
    delta = 360.0 / K
    try:
        a = float(angle_deg)
    except (TypeError, ValueError):
        raise AngleError(f"{what} {angle_deg!r} is not a number of degrees.") from None
    steps = a / delta
    n = round(steps) if math.isfinite(steps) else -1
    lo = 0 if allow_zero else 1
    ok = math.isfinite(a) and abs(steps - n) <= 1e-9 * max(1.0, abs(steps)) and lo <= n < K
    if not ok:
        if allow_zero:
            raise AngleError(
                f"{what} {_fmt(a)}° is not allowed with {K} orientations: use a multiple of "
                f"{_fmt(delta)}° between 0° and {_fmt(360 - delta)}°.")
        raise AngleError(
            f"{what} {_fmt(a)}° is not allowed with {K} orientations: use a multiple of "
            f"{_fmt(delta)}° between {_fmt(delta)}° and {_fmt(360 - delta)}°.")
    return int(n)


def _fmt(x: float) -> str:
    if not math.isfinite(x) or abs(x - round(x)) > 1e-9:
        return f"{x:g}"
    return str(int(round(x)))


@dataclass(frozen=True, eq=False)
class CellSpace:
    """Free position cells, configuration indices and the forward-step table of an environment.

    Attributes
    ----------
    env : Environment
    h : float            cell size [m]
    K : int              orientations
    P, N : int           free position cells, configurations (N = K * P)
    cells_ij : (P, 2)    column i and row j of each free cell
    centres : (P, 2)     cell centres [m]
    index_grid : (rows, cols) int array, p of each grid cell or -1 when not free
    forward : (N,) int array, z' after a forward move from z, or -1 for a bump
    max_memory : int, str or None
        Refuse (:class:`envs.UserError`) to build the step table when its estimated peak
        memory exceeds this many bytes (or a size such as ``"2G"``; None: no limit); see
        :mod:`planners.resources`.
    """

    env: Environment
    max_memory: int | str | None = DEFAULT_MAX_MEMORY

    # ------------------------------------------------------------------ cells
    @property
    def h(self) -> float:
        """Cell size [m]."""
        return self.env.cell_size

    @property
    def K(self) -> int:
        """Number of orientations."""
        return self.env.orientations

    @property
    def delta_deg(self) -> float:
        """Orientation step Δ = 360° / K [deg]."""
        return 360.0 / self.K

    @cached_property
    def index_grid(self) -> np.ndarray:
        """(rows, cols) grid of position indices p, -1 where the cell centre is not free."""
        free = self.env.grid_centres_free()
        grid = np.full(free.shape, -1, dtype=np.int64)
        grid[free] = np.arange(int(free.sum()))  # row-major from the bottom row
        return grid

    @cached_property
    def cells_ij(self) -> np.ndarray:
        """(P, 2) grid column and row (i, j) of each free position cell."""
        jj, ii = np.nonzero(self.index_grid >= 0)
        return np.stack([ii, jj], axis=1)

    @property
    def P(self) -> int:
        """Number of free position cells."""
        return int(self.cells_ij.shape[0])

    @property
    def N(self) -> int:
        """Number of configurations, K · P."""
        return self.K * self.P

    @cached_property
    def origin(self) -> np.ndarray:
        """(2,) the grid's origin [m]: the lower-left corner of cell (0, 0)."""
        return np.asarray(self.env.origin, dtype=float)

    @cached_property
    def centres(self) -> np.ndarray:
        """(P, 2) centre [m] of each free position cell."""
        x0, y0 = self.env.origin
        return np.column_stack([x0 + (self.cells_ij[:, 0] + 0.5) * self.h,
                                y0 + (self.cells_ij[:, 1] + 0.5) * self.h])

    @cached_property
    def headings(self) -> np.ndarray:
        """Heading of each orientation k [rad]."""
        return 2 * np.pi * np.arange(self.K) / self.K

    @cached_property
    def units(self) -> np.ndarray:
        """(K, 2) unit heading vector of each orientation k (axis headings exact, §7)."""
        u = unit_rad(self.headings)
        u.flags.writeable = False
        return u

    # ------------------------------------------------------------------ indices
    def z(self, p, k):
        """Configuration index z = k * P + p."""
        return np.asarray(k) * self.P + np.asarray(p)

    def pk(self, z):
        """(p, k) of configuration index z."""
        z = np.asarray(z)
        return z % self.P, z // self.P

    def pose(self, z) -> tuple[float, float, float]:
        """(x [m], y [m], heading [deg]) of configuration z's cell centre."""
        p, k = self.pk(int(z))
        x, y = self.centres[p]
        return float(x), float(y), float(k * self.delta_deg)

    def cell_of_point(self, xy) -> np.ndarray:
        """P of the grid cell containing each point (§4, :func:`envs.motion.grid_index`), or
        -1 outside the free cells.
        """
        g = grid_index(xy, self.env.origin, self.h, self.index_grid.shape)
        return self._p_of_grid_index[g]

    def cell_of_body(self, xy) -> np.ndarray:
        """:meth:`cell_of_point` of a body's centres (docs/model.md §22): a centre outside
        the C-space by at most :data:`BODY_SNAP_M` is counted at the nearest C-space point,
        1e-6 m inside it, where the model's robot would stand.

        A room 1.53 m deep: its C-space ends at y = 1.36 m, a cell border; a body 2 mm beyond
        it lies in the row above, which is no cell, and is counted in the row below:

        >>> from envs import Environment
        >>> cs = CellSpace(Environment.from_dict({"boundary": [[0, 0], [1.36, 0], [1.36, 1.53],
        ...     [0, 1.53]], "robot_radius": 0.17, "discretization": {"cell_size": 0.34}}))
        >>> below = int(cs.cell_of_point([[0.5, 1.35]])[0])
        >>> out = [[0.5, 1.362]]
        >>> int(cs.cell_of_point(out)[0]), int(cs.cell_of_body(out)[0]) == below
        (-1, True)
        """
        pts = np.array(xy, dtype=float).reshape(-1, 2)
        cspace = self.env.cspace
        out = np.flatnonzero(~shapely.contains_xy(cspace, pts[:, 0], pts[:, 1]))
        if out.size:
            near = out[shapely.distance(shapely.points(pts[out]), cspace) <= BODY_SNAP_M]
            if near.size:
                q = shapely.get_coordinates(shapely.shortest_line(
                    cspace, shapely.points(pts[near]))).reshape(-1, 2, 2)[:, 0]
                v = q - pts[near]
                v /= np.maximum(np.hypot(v[:, 0], v[:, 1]), 1e-300)[:, None]
                pts[near] = q + 1e-6 * v
        return self.cell_of_point(pts)

    @cached_property
    def _p_of_grid_index(self) -> np.ndarray:
        """P of every flat grid index, then -1 (what grid index -1, outside, looks up)."""
        return np.append(self.index_grid.ravel(), -1)

    def orientation_of(self, heading_deg) -> np.ndarray:
        """Nearest orientation k of each heading [deg]."""
        return np.round(np.asarray(heading_deg, dtype=float) / self.delta_deg).astype(
            np.int64) % self.K

    def config_of_pose(self, x: float, y: float, heading_deg: float) -> int:
        """Configuration z of a pose (x, y [m], heading [deg]), or -1 if its cell is not free."""
        p = int(self.cell_of_point([[x, y]])[0])
        if p < 0:
            return -1
        return int(self.z(p, int(self.orientation_of(heading_deg))))

    def rotate(self, z, angle_deg: float):
        """Configuration after an in-place CCW turn by angle_deg (a multiple of Δ)."""
        return self.turn(z, angle_steps(angle_deg, self.K, allow_zero=True))

    def turn(self, z, steps):
        """Configuration after an in-place CCW turn by ``steps`` orientation steps (whole
        numbers; z and steps broadcast, so a column of bump cells against a row of turns
        gives every bump's destinations).
        """
        p, k = self.pk(z)
        return self.z(p, (k + np.asarray(steps)) % self.K)

    def angle_steps(self, angle_deg: float, what: str = "bouncing angle") -> int:
        """An angle [deg] as a whole number of orientation steps Δ (UserError otherwise)."""
        return angle_steps(angle_deg, self.K, what)

    # ------------------------------------------------------------------ step table
    @cached_property
    def forward(self) -> np.ndarray:
        """Forward-step table: z' after one step from z, or -1 where the robot bumps (§7)."""
        P, K, h = self.P, self.K, self.h
        if P == 0:
            return np.zeros(0, dtype=np.int64)
        check_memory(self, max_memory=self.max_memory)
        u = self.units                                                           # (K, 2)
        c = np.broadcast_to(self.centres[None, :, :], (K, P, 2)).reshape(-1, 2)  # z order
        uu = np.repeat(u, P, axis=0)
        d = c + h * uu
        dest = self.cell_of_point(d + 1e-6 * h * uu)
        ok = dest >= 0
        ok[ok] = self.env.segments_free(c[ok], d[ok])
        k_of_z = np.repeat(np.arange(K), P)
        out = np.full(self.N, -1, dtype=np.int64)
        out[ok] = k_of_z[ok] * P + dest[ok]
        return out

    @cached_property
    def step_offsets(self) -> np.ndarray:
        """(K, 2) int: the grid offset (di, dj) of a forward move at each orientation (§7).

        A forward move from the centre of cell (i, j) lands in the cell containing
        c + (1 + 1e-6)·h·u_k, which is cell (i + di, j + dj) with
        di = floor(½ + (1 + 1e-6)·cos θ_k) and dj = floor(½ + (1 + 1e-6)·sin θ_k), the same
        for every cell (the grid is translation invariant). K = 8: (1, 0), (1, 1), (0, 1), …
        """
        return np.floor(0.5 + (1 + 1e-6) * self.units).astype(np.int64)

    def run_length(self, k: int, n: int) -> float:
        """[m] distance between the centres of the cells where n forward moves at orientation
        k start and end: n·h·|(di, dj)| (§21: how far a run of n zeros drives).

        >>> from envs import Environment
        >>> env = Environment.from_dict({"boundary": [[0, 0], [1.02, 0], [1.02, 1.02],
        ...     [0, 1.02]], "robot_radius": 0.17,
        ...     "discretization": {"cell_size": 0.34, "orientations": 8}})
        >>> cs = CellSpace(env)
        >>> round(cs.run_length(0, 2), 6), round(cs.run_length(1, 2), 6)   # east, north-east
        (0.68, 0.961665)
        """
        di, dj = self.step_offsets[int(k) % self.K]
        return float(n) * self.h * math.hypot(int(di), int(dj))

    @property
    def bumps(self) -> np.ndarray:
        """Boolean (N,): configurations whose forward step is a bump."""
        return self.forward < 0

    def __repr__(self) -> str:
        return f"CellSpace({self.env.name!r}, P={self.P}, K={self.K}, N={self.N}, h={self.h})"
