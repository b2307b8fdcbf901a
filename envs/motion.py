"""The motion layer: how a disk robot moves, stops and is counted (docs/model.md §4, §6, §7, §8).

Pure geometry on numpy, the bottom layer under the planners (the step model, the sampled and
event coverage models) and the simulators (the kinematic twin, the executor's step counting),
so that model and simulation see bitwise the same flights, steps and cells. One home each:

- the contact constants ``CONTACT_GAP``, ``BUMP_RANGE``, ``STEP_TOL``, ``APPROACH_MIN``,
  ``GRAZE_TOL`` (docs/model.md §8);
- :func:`unit` / :func:`unit_rad`: unit heading vectors, axis headings exact;
- :class:`WallCaster` (all walls, vectorised over rays x walls, and a scalar path),
  :class:`LocalCaster` (only the walls near each ray origin, exact for short rays) and
  :func:`casters` (both, cached per environment): exact ray casts of the disk;
- :func:`drive_distance`: how far a drive goes before a contact stops it;
- :func:`step`: the step rule of docs/model.md §8 (the step's length and whether it is a bump
  step), and :func:`flight_steps`, the same rule along a straight flight;
- :func:`grid_index`: point → grid cell (docs/model.md §4).

Ray casts. The robot is a disk of radius r whose centre moves inside the C-space (E eroded by
r). A straight drive is a ray cast against the walls *grown into capsules*: the disk centred
at c touches a wall segment AB exactly when dist(c, AB) = r, so the first contact along the
ray c + t u is the first entry of the ray into one of the capsules {p : dist(p, AB) <= r}.
Each capsule is the union of a rectangle (the segment's two offset sides) and two disks (its
end points), so the entry distance has a closed form (no polygonal approximation of the
rounded corners, unlike ``env.cspace``).

- A drive stops ``CONTACT_GAP`` = 1e-9 m (along the ray) before the computed contact.
- A side is hit only when the motion approaches its line (rate > 1e-12 per metre), a wall
  corner only when the ray passes closer than r − 1e-7 m.

>>> import envs
>>> full, local = casters(envs.load("lab"))
>>> round(float(full.cast([[0.51, 0.51]], unit([90.0]))[0]), 6)    # 2.04 - 0.17 - 0.51
1.36
>>> length, bump = step(drive_distance(np.array([1.36, 0.2, 0.34 - 5e-7])), 0.34)
>>> length.round(4).tolist(), bump.tolist()       # the last one ends 5e-7 m short of h
([0.34, 0.2, 0.34], [False, True, False])
>>> grid_index([[0.5, 0.1], [0.34, 0.34], [-0.1, 0.2]], (0.0, 0.0), 0.34, (6, 6)).tolist()
[1, 7, -1]
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property, lru_cache

import numpy as np

from .environment import Environment
from .errors import UserError

__all__ = ["WallCaster", "LocalCaster", "casters", "unit", "unit_rad", "drive_distance",
           "step", "flight_steps", "grid_index", "cast_scalar", "CONTACT_GAP", "BUMP_RANGE",
           "STEP_TOL", "APPROACH_MIN", "GRAZE_TOL", "CENTRE_ZONE_DEG"]

CONTACT_GAP = 1e-9
"""[m] a drive stops this far (along the ray) short of the exact contact."""
BUMP_RANGE = 1e-6
"""[m] the bumper reads closed when forward motion is blocked within this distance."""
STEP_TOL = 1e-6
"""[m] a step whose drive reaches the wall within this of the full length h is a forward step
(the robot ends touching the wall and bumps at the start of the next step)."""
APPROACH_MIN = 1e-12
"""a side is approached only when u . n exceeds this [1/m of travel]."""
GRAZE_TOL = 1e-7
"""[m] a corner is hit only when the ray passes closer than r - this."""
CENTRE_ZONE_DEG = 10.0
"""[deg] a contact within ± this of straight ahead closes both bumper switches; further left
(right) only the left (right) one (the twin's and PyBullet's bumper sides, and what the
feedback filter expects)."""
_APPROACH_MIN = APPROACH_MIN
_GRAZE_TOL = GRAZE_TOL


# ============================================================================ headings
def unit_rad(theta_rad) -> np.ndarray:
    """Unit heading vector(s) (..., 2) of heading(s) [rad]; |components| < 1e-12 snap to 0
    so that axis-aligned headings are exact (cos 90° would otherwise be 6e-17).
    """
    th = np.asarray(theta_rad, dtype=float)
    u = np.stack([np.cos(th), np.sin(th)], axis=-1)
    u[np.abs(u) < 1e-12] = 0.0
    return u


def unit(heading_deg) -> np.ndarray:
    """Unit heading vector(s) (..., 2) of heading(s) [deg] (:func:`unit_rad`).

    >>> unit([0.0, 90.0, 225.0]).round(6).tolist()
    [[1.0, 0.0], [0.0, 1.0], [-0.707107, -0.707107]]
    """
    return unit_rad(np.radians(np.asarray(heading_deg, dtype=float)))


# ============================================================================ steps
def drive_distance(contact):
    """[m] how far a drive goes along a ray whose exact contact is ``contact`` [m] away: it
    stops ``CONTACT_GAP`` short, max(t − CONTACT_GAP, 0) (inf when nothing is ahead).
    A Python float stays a float (the scalar path of one robot); arrays are vectorised.
    """
    if isinstance(contact, (float, int)):
        return max(contact - CONTACT_GAP, 0.0)
    return np.maximum(np.asarray(contact, dtype=float) - CONTACT_GAP, 0.0)


def step(free, h: float):
    """The step rule (docs/model.md §8): one step drives h by the clock or until a bump.

    Parameters
    ----------
    free : float or array   distance [m] the robot can drive before a contact stops it
                            (:func:`drive_distance` of the cast; inf when nothing is ahead)
    h : float               step length [m]

    Returns
    -------
    length : the step's drive [m], min(max(free, 0), h)
    bump : True for a bump step (length < h − STEP_TOL: the move to contact, then the turn);
           False for a forward step (a drive ending within STEP_TOL short of h leaves the robot
           touching the wall; it bumps at the start of the next step)

    >>> step(0.3399995, 0.34)[1], step(0.339998, 0.34)[1], step(float("inf"), 0.34)
    (False, True, (0.34, False))
    """
    length = np.clip(free, 0.0, h)
    bump = length < h - STEP_TOL
    if np.ndim(length) == 0:
        return float(length), bool(bump)
    return length, bump


def flight_steps(free, h: float) -> np.ndarray:
    """Forward steps of a straight flight with ``free`` [m] to drive, under :func:`step`.

    The flight is floor(free/h) whole steps, plus one more when the remainder passes the step
    rule (at least h − STEP_TOL of it free); then comes one bump step at the contact. This is
    floor((free + STEP_TOL)/h) up to rounding at that threshold.

    >>> flight_steps([0.0, 0.34, 0.3399995, 0.68 - 2e-6, 1.0], 0.34).tolist()
    [0, 1, 1, 1, 2]
    """
    d = np.asarray(free, dtype=float)
    whole = np.floor(d / h)
    _, bump = step(d - whole * h, h)
    return (whole + np.logical_not(bump)).astype(np.int64)


# ============================================================================ cells
def grid_index(xy, origin, h: float, shape) -> np.ndarray:
    """Flat index j·cols + i of the grid cell (i, j) holding each point, or −1 outside.

    docs/model.md §4: i = floor((x − x0)/h), j = floor((y − y0)/h); a point on a cell border
    belongs to the cell above / to the right of it.

    Parameters
    ----------
    xy : (n, 2) points [m]
    origin : (x0, y0) [m]   the grid's lower-left corner
    h : float               cell size [m]
    shape : (rows, cols)    the grid's shape
    """
    pts = np.asarray(xy, dtype=float).reshape(-1, 2)
    x0, y0 = origin
    rows, cols = shape
    i = np.floor((pts[:, 0] - x0) / h).astype(np.int64)
    j = np.floor((pts[:, 1] - y0) / h).astype(np.int64)
    ok = (i >= 0) & (i < cols) & (j >= 0) & (j < rows)
    return np.where(ok, j * cols + i, -1)


# ============================================================================ ray casts
def cast_scalar(sides, verts, r, r2, graze, x, y, ux, uy, within=None):
    """The capsule ray cast for one disk over lists of sides (Ax, Ay, ex, ey, L) and corners
    (Vx, Vy): the contact distance, or with ``within`` the wall points touched within it.
    """
    best = math.inf
    hits = [] if within is not None else None
    for Ax, Ay, ex, ey, L in sides:
        rx = x - Ax
        ry = y - Ay
        s0 = ry * ex - rx * ey
        un = uy * ex - ux * ey
        a = -un if s0 >= 0 else un
        if not a > _APPROACH_MIN:
            continue
        t = (abs(s0) - r) / a
        if t < 0.0:
            t = 0.0
        lam = rx * ex + ry * ey + t * (ux * ex + uy * ey)
        if 0.0 <= lam <= L:
            if hits is None:
                if t < best:
                    best = t
            elif t <= within:
                cx, cy = x + t * ux - Ax, y + t * uy - Ay
                k = min(max(cx * ex + cy * ey, 0.0), L)
                hits.append((Ax + k * ex, Ay + k * ey, (Ax, Ay, ex, ey, L)))
    for Vx, Vy in verts:
        vx = x - Vx
        vy = y - Vy
        b = vx * ux + vy * uy
        if not b < 0.0:
            continue
        disc = r2 - (vx * vx + vy * vy - b * b)
        if not disc > graze:
            continue
        t = -b - math.sqrt(disc)
        if t < 0.0:
            t = 0.0
        if hits is None:
            if t < best:
                best = t
        elif t <= within:
            hits.append((Vx, Vy, None))
    return best if hits is None else hits


class WallCaster:
    """First contact of a moving disk with a set of wall segments, vectorised.

    Parameters
    ----------
    segments : (m, 2, 2) array   wall segments [m] (e.g. ``env.wall_segments``)
    radius : float               disk radius r [m]

    Notes
    -----
    For a ray c + t u (|u| = 1, t >= 0) and a segment AB with unit direction e, unit normal n
    and length L, the contact distance is the minimum of

    - side: t = (|s0| − r) / a with s0 = (c − A)·n and approach rate a = −sign(s0) (u·n) > 0,
      valid when the foot point's coordinate λ = (c + t u − A)·e lies in [0, L];
    - corner V (every segment end point): t = −b − sqrt(r² − ρ²) with b = (c − V)·u < 0 and
      ρ² = |c − V|² − b² < r² (the ray's squared distance from V);

    clamped at 0 (a disk already touching and moving in hits at once).
    """

    def __init__(self, segments, radius: float) -> None:
        seg = np.asarray(segments, dtype=float).reshape(-1, 2, 2)
        d = seg[:, 1] - seg[:, 0]
        length = np.hypot(d[:, 0], d[:, 1])
        keep = length > 1e-12
        seg, d, length = seg[keep], d[keep], length[keep]
        self.segments = seg
        self.r = float(radius)
        self.A = seg[:, 0].copy()
        self.L = length
        self.e = d / length[:, None]
        self.n = np.column_stack([-self.e[:, 1], self.e[:, 0]])
        self.vertices = np.unique(seg.reshape(-1, 2), axis=0)
        # the walls as the compiled kernels read them (envs/_contact_kernel.py, the feedback
        # filter's flights): one row (Ax, Ay, ex, ey, L) per side, one (x, y) per corner
        self.kernel_sides = np.ascontiguousarray(np.column_stack([self.A, self.e, self.L]))
        self.kernel_corners = np.ascontiguousarray(self.vertices, dtype=float)
        # Row vectors for broadcasting against (n_rays, 1) columns.
        self._Ax, self._Ay = self.A[:, 0][None], self.A[:, 1][None]
        self._ex, self._ey = self.e[:, 0][None], self.e[:, 1][None]
        self._nx, self._ny = self.n[:, 0][None], self.n[:, 1][None]
        self._Lr = self.L[None]
        self._Vx, self._Vy = self.vertices[:, 0][None], self.vertices[:, 1][None]
        self.r2 = self.r * self.r
        self.graze = self.r * self.r - (self.r - _GRAZE_TOL) ** 2
        # Python floats for the scalar path (one robot): same formulas, same rounding
        self.side_list = [tuple(float(v) for v in row) for row in
                           np.column_stack([self.A, self.e, self.L])]
        self.vert_list = [(float(x), float(y)) for x, y in self.vertices]

    @property
    def n_features(self) -> int:
        """Segments (sides) followed by vertices (corners)."""
        return len(self.L) + len(self.vertices)

    def feature_distances(self, pos, u) -> np.ndarray:
        """(n_rays, n_features) contact distance [m] along each ray per feature (inf: never).

        Parameters
        ----------
        pos : (n, 2) ray origins (disk centres) [m]
        u : (n, 2) unit directions
        """
        pos = np.asarray(pos, dtype=float).reshape(-1, 2)
        u = np.asarray(u, dtype=float).reshape(-1, 2)
        return np.concatenate(self._sides(pos, u) + self._corners(pos, u), axis=1)

    def _sides(self, pos, u):
        px, py = pos[:, 0:1], pos[:, 1:2]
        ux, uy = u[:, 0:1], u[:, 1:2]
        rx = px - self._Ax
        ry = py - self._Ay
        s0 = rx * self._nx + ry * self._ny
        un = ux * self._nx + uy * self._ny
        a = np.where(s0 >= 0, -un, un)               # approach rate towards the line
        ok = a > _APPROACH_MIN
        with np.errstate(divide="ignore", invalid="ignore"):
            t = np.maximum((np.abs(s0) - self.r) / a, 0.0)
            lam = rx * self._ex + ry * self._ey + t * (ux * self._ex + uy * self._ey)
        ok &= (lam >= 0.0) & (lam <= self._Lr)
        return (np.where(ok, t, np.inf),)

    def _corners(self, pos, u):
        px, py = pos[:, 0:1], pos[:, 1:2]
        ux, uy = u[:, 0:1], u[:, 1:2]
        vx = px - self._Vx
        vy = py - self._Vy
        b = vx * ux + vy * uy
        rho2 = vx * vx + vy * vy - b * b
        disc = self.r2 - rho2
        ok = (b < 0.0) & (disc > self.graze)
        with np.errstate(invalid="ignore"):
            t = np.maximum(-b - np.sqrt(disc), 0.0)
        return (np.where(ok, t, np.inf),)

    def cast(self, pos, u) -> np.ndarray:
        """(n,) distance [m] each disk can travel along its ray before touching a wall."""
        pos = np.asarray(pos, dtype=float).reshape(-1, 2)
        u = np.asarray(u, dtype=float).reshape(-1, 2)
        (ts,) = self._sides(pos, u)
        (tc,) = self._corners(pos, u)
        return np.minimum(ts.min(axis=1), tc.min(axis=1))

    def cast_one(self, x: float, y: float, ux: float, uy: float,
                 within: float | None = None):
        """Scalar :meth:`cast` for one disk (plain Python floats, bitwise the same numbers).

        Returns the contact distance [m]; with ``within`` [m], instead the list of wall points
        (x, y, side) the disk touches when moving up to ``within`` along (ux, uy); side is the
        segment (Ax, Ay, ex, ey, L) or None for a corner.
        """
        return cast_scalar(self.side_list, self.vert_list, self.r, self.r2, self.graze,
                            x, y, ux, uy, within)

    def contact_points(self, pos, u, within: float = BUMP_RANGE) -> list[tuple]:
        """For one disk: the wall points (x, y) it touches moving ``within`` [m] along u."""
        x, y = (float(v) for v in np.asarray(pos, dtype=float).reshape(2))
        ux, uy = (float(v) for v in np.asarray(u, dtype=float).reshape(2))
        return [(px, py) for px, py, _ in self.cast_one(x, y, ux, uy, within)]


class LocalCaster:
    """:class:`WallCaster` restricted to the walls near each ray origin, for short rays.

    The bounding box of the walls is cut into a fine grid (cell ``g``); every fine cell keeps
    the sides and corners within ``reach + g/√2`` of its centre, with ``reach = max_dist + r``.
    A disk starting anywhere in the fine cell can only touch those within ``max_dist``, so
    :meth:`cast` is exact below ``max_dist`` and returns some value >= ``max_dist`` (possibly
    inf) otherwise. Per-cell parameter tables are padded with inert features.

    Parameters
    ----------
    caster : WallCaster
    max_dist : float   longest ray that must be exact [m]
    fine : float, optional   fine-grid cell [m] (default r / 2, but at least max_dist / 4
                             and 1/1024 of the walls' extent, so a tiny robot radius does
                             not make the grid explode; exactness does not depend on it)
    """

    def __init__(self, caster: WallCaster, max_dist: float, fine: float | None = None) -> None:
        self.caster = caster
        self.max_dist = float(max_dist)
        r = caster.r
        seg = caster.segments
        lo = np.minimum(seg[:, 0], seg[:, 1]).min(axis=0)
        hi = np.maximum(seg[:, 0], seg[:, 1]).max(axis=0)
        g = (float(fine) if fine is not None
             else max(r / 2, self.max_dist / 4, float((hi - lo).max()) / 1024))
        self.g = g
        self.x0, self.y0 = float(lo[0]), float(lo[1])
        self.nx = max(1, int(math.ceil((hi[0] - lo[0]) / g)))
        self.ny = max(1, int(math.ceil((hi[1] - lo[1]) / g)))
        jj, ii = np.mgrid[0:self.ny, 0:self.nx]
        cen = np.column_stack([self.x0 + (ii.ravel() + 0.5) * g,
                               self.y0 + (jj.ravel() + 0.5) * g])
        reach = self.max_dist + r + g * math.sqrt(0.5) + 1e-9
        # point-segment distances (F, m) and point-vertex distances (F, v)
        rel = cen[:, None, :] - caster.A[None]
        lam = np.clip((rel * caster.e[None]).sum(-1), 0.0, caster.L[None])
        foot = caster.A[None] + lam[..., None] * caster.e[None]
        ds = np.hypot(*(cen[:, None, :] - foot).transpose(2, 0, 1))
        dv = np.hypot(*(cen[:, None, :] - caster.vertices[None]).transpose(2, 0, 1))
        near_s, near_v = ds <= reach, dv <= reach
        ks, kv = max(1, int(near_s.sum(1).max())), max(1, int(near_v.sum(1).max()))
        F = len(cen)
        far = 1e12
        # sides: rows Ax, Ay, ex, ey, L; padding never approaches (n = 0)
        side = np.zeros((F, 5, ks))
        side[:, 0, :] = far
        side[:, 1, :] = far
        corner = np.full((F, 2, kv), far)
        for f in range(F):
            s_idx = np.flatnonzero(near_s[f])
            side[f, 0, :len(s_idx)] = caster.A[s_idx, 0]
            side[f, 1, :len(s_idx)] = caster.A[s_idx, 1]
            side[f, 2, :len(s_idx)] = caster.e[s_idx, 0]
            side[f, 3, :len(s_idx)] = caster.e[s_idx, 1]
            side[f, 4, :len(s_idx)] = caster.L[s_idx]
            v_idx = np.flatnonzero(near_v[f])
            corner[f, 0, :len(v_idx)] = caster.vertices[v_idx, 0]
            corner[f, 1, :len(v_idx)] = caster.vertices[v_idx, 1]
        self._side, self._corner = side, corner
        self.k_sides, self.k_corners = ks, kv

    @cached_property
    def _scalar_lists(self):
        sides = [[tuple(row) for row in cell if row[0] < 1e11]
                 for cell in self._side.transpose(0, 2, 1).tolist()]
        verts = [[tuple(row) for row in cell if row[0] < 1e11]
                 for cell in self._corner.transpose(0, 2, 1).tolist()]
        return sides, verts

    def cast_one(self, x: float, y: float, ux: float, uy: float,
                 within: float | None = None):
        """Scalar :meth:`cast` for one disk: exact below ``max_dist`` (else >= it); with
        ``within`` <= ``max_dist``, the wall points touched within that distance.
        """
        i = min(max(int((x - self.x0) / self.g), 0), self.nx - 1)
        j = min(max(int((y - self.y0) / self.g), 0), self.ny - 1)
        sides, verts = self._scalar_lists
        f = j * self.nx + i
        c = self.caster
        return cast_scalar(sides[f], verts[f], c.r, c.r2, c.graze, x, y, ux, uy, within)

    def fine_cell(self, pos: np.ndarray) -> np.ndarray:
        """Index of the fine grid cell of each (n, 2) position (clipped to the grid)."""
        i = np.clip(((pos[:, 0] - self.x0) / self.g).astype(np.int64), 0, self.nx - 1)
        j = np.clip(((pos[:, 1] - self.y0) / self.g).astype(np.int64), 0, self.ny - 1)
        return j * self.nx + i

    def cast(self, pos, u) -> np.ndarray:
        """(n,) contact distance [m]: exact when below ``max_dist``, else >= ``max_dist``."""
        pos = np.asarray(pos, dtype=float).reshape(-1, 2)
        u = np.asarray(u, dtype=float).reshape(-1, 2)
        f = self.fine_cell(pos)
        r = self.caster.r
        px, py = pos[:, 0:1], pos[:, 1:2]
        ux, uy = u[:, 0:1], u[:, 1:2]
        S = self._side[f]
        Ax, Ay, ex, ey, L = S[:, 0], S[:, 1], S[:, 2], S[:, 3], S[:, 4]
        rx = px - Ax
        ry = py - Ay
        s0 = rx * (-ey) + ry * ex
        un = uy * ex - ux * ey
        a = np.where(s0 >= 0, -un, un)
        with np.errstate(divide="ignore", invalid="ignore"):
            t = np.maximum((np.abs(s0) - r) / a, 0.0)
            lam = rx * ex + ry * ey + t * (ux * ex + uy * ey)
        ok = (a > _APPROACH_MIN) & (lam >= 0.0) & (lam <= L)
        ts = np.where(ok, t, np.inf).min(axis=1)
        C = self._corner[f]
        vx = px - C[:, 0]
        vy = py - C[:, 1]
        b = vx * ux + vy * uy
        disc = self.caster.r2 - (vx * vx + vy * vy - b * b)
        ok = (b < 0.0) & (disc > self.caster.graze)
        with np.errstate(invalid="ignore"):
            tc = np.where(ok, -b - np.sqrt(np.maximum(disc, 0.0)), np.inf)
        return np.maximum(np.minimum(ts, tc.min(axis=1)), 0.0)


@lru_cache(maxsize=32)
def casters(env: Environment, step: float | None = None) -> tuple[WallCaster, LocalCaster]:
    """The (cached) full and local casters of an environment; local range ``step`` [m]
    (default the cell size).
    """
    full = WallCaster(env.wall_segments, env.robot_radius)
    return full, LocalCaster(full, env.cell_size if step is None else step)


# ---------------------------------------------------------------------------- contact data
@dataclass(frozen=True)
class ContactParams:
    """How a disk robot meets a straight wall (data only; docs/model.md §9 and Appendix B,
    "Contact calibration"). Fitted to a physics Create 2 by
    ``experiments/contact_calibration.py``; the rule that uses it is :mod:`envs.contact`.

    Attributes
    ----------
    beta_deg : float
        Incidence [deg] (angle between heading and wall) below which a contact does not
        close the bumper: the contact bearing α − 90° lies outside the bumper arc and the
        robot slides along the wall instead of bumping.
    slide_friction : float
        μ of the slide rule: while sliding, the speed along the wall is
        v · max(cos α − μ sin α, 0).
    turn_in : tuple of (incidence [deg], slide [m]) pairs
        A body that turns into the wall while it slides (MuJoCo's wheeled Create 2): from
        incidence α it slides L(α) along a straight wall while its incidence grows, and bumps
        when it reaches β. The pairs sample L (incidences increasing below β, slides
        decreasing and positive; L(β) = 0 is implied, linear in between). Incidences below
        the first pair's keep their heading while they slide; empty (the default): every
        slide keeps its heading. Since L depends on the incidence alone, a slide cut short
        (a wall's end, a clock budget) goes on from the incidence it reached.
    """

    beta_deg: float = 9.6
    slide_friction: float = 0.006
    turn_in: tuple = ()

    def __post_init__(self) -> None:
        b, mu = float(self.beta_deg), float(self.slide_friction)
        if not (0.0 <= b < 90.0 and 0.0 <= mu and math.cos(math.radians(b))
                > mu * math.sin(math.radians(b))):
            raise UserError(f"a contact rule needs 0 <= beta < 90 degrees and a friction "
                            f"0 <= mu < 1/tan(beta), got beta {b:g}, mu {mu:g}.")
        pairs = tuple((float(a), float(ell)) for a, ell in self.turn_in)
        object.__setattr__(self, "turn_in", pairs)
        a = np.array([p[0] for p in pairs] + [b])
        ell = np.array([p[1] for p in pairs] + [0.0])
        if pairs and not (a[0] >= 0 and np.all(np.diff(a) > 0) and np.all(np.diff(ell) < 0)):
            raise UserError(f"a turn-in table needs incidences rising from >= 0 to below beta "
                            f"({b:g}) and slide lengths falling to above 0, got {pairs}.")

    @cached_property
    def turn_table(self) -> tuple[np.ndarray, np.ndarray]:
        """(incidences [deg], slides [m]) of :attr:`turn_in` with (β, 0) appended; both
        empty when the rule has no turn-in.
        """
        if not self.turn_in:
            return np.zeros(0), np.zeros(0)
        return (np.array([p[0] for p in self.turn_in] + [float(self.beta_deg)]),
                np.array([p[1] for p in self.turn_in] + [0.0]))

    @property
    def text(self) -> str:
        """The rule as text, "β μ" then "α:L,α:L,…" for a turn-in table (:meth:`from_text`
        reads it back exactly).

        >>> rule = ContactParams(10.0, 0.0, turn_in=((2.0, 2.0),))
        >>> rule.text, ContactParams.from_text(rule.text) == rule
        ('10.0 0.0 2.0:2.0', True)
        """
        out = f"{float(self.beta_deg)!r} {float(self.slide_friction)!r}"
        if self.turn_in:
            out += " " + ",".join(f"{a!r}:{ell!r}" for a, ell in self.turn_in)
        return out

    @classmethod
    def from_text(cls, text: str) -> "ContactParams":
        """The rule of :attr:`text`."""
        parts = text.split()
        turn = () if len(parts) < 3 else tuple(
            tuple(float(v) for v in pair.split(":")) for pair in parts[2].split(","))
        return cls(float(parts[0]), float(parts[1]), turn_in=turn)

    def slide_left(self, incidence_deg: float) -> float:
        """[m] how far a body sliding at ``incidence_deg`` goes on before it bumps by turning
        in (:attr:`turn_in`): inf without turn-in or below its first incidence.

        >>> rule = ContactParams(10.0, 0.0, turn_in=((2.0, 2.0), (6.0, 0.5)))
        >>> rule.slide_left(1.0), rule.slide_left(4.0), rule.slide_left(8.0)
        (inf, 1.25, 0.25)
        """
        a, ell = self.turn_table if self.turn_in else ((math.inf,), ())   # none: the hot path
        return math.inf if incidence_deg < a[0] else float(np.interp(incidence_deg, a, ell))

    def incidence_after(self, left_m: float) -> float:
        """[deg] the incidence of a turning-in slide with ``left_m`` [m] still to go (the
        inverse of :meth:`slide_left`).

        >>> ContactParams(10.0, 0.0, turn_in=((2.0, 2.0), (6.0, 0.5))).incidence_after(1.25)
        4.0
        """
        a, ell = self.turn_table
        return float(np.interp(left_m, ell[::-1], a[::-1]))


PYBULLET_CONTACT = ContactParams(beta_deg=10.5, slide_friction=0.0)
"""The PyBullet Create 2's fitted contact rule (±79.5° bumper arc read by the contact normal,
frictionless walls, regularised contacts; ``python -m experiments.contact_calibration``, at
0.3 and 0.2 m/s alike): every trial up to 10.45° slid 3 m with its heading kept (within
0.03°) at the speed factor cos α, every one from 10.55° bumped; the fit's μ, 0.0004, is
stored as 0. β is the geometric 90° − 79.5° (docs/model.md Appendix B)."""

MUJOCO_CONTACT = ContactParams(
    beta_deg=10.44, slide_friction=0.14,
    turn_in=((2.0, 2.798), (3.0, 1.721), (5.0, 0.919), (7.0, 0.476), (8.0, 0.318),
             (9.0, 0.159), (9.5, 0.104), (9.75, 0.078), (9.9, 0.057), (10.0, 0.049),
             (10.1, 0.033), (10.25, 0.019)))
"""The MuJoCo Create 2's fitted contact rule (``python -m experiments.contact_calibration
--backend mujoco``, 144 trials at 0.3 m/s; the fit's ``turn_in`` and ``turn_in_beta_deg``
rounded): its wheels resist the wall's sideways push, so below the bumper arc it turns into
the wall while it slides and bumps when the incidence reaches 10.44° (every trial from 2° to
10.25°: start + turn = 10.43–10.45°), after the mean slides of the table (2.80 m from 2°,
0.92 m from 5°, 0.16 m from 9°). μ = 0.14 is the fit to its slides below 2°, which ran the
whole 3 m budget without a bump; at β it gives the speed factor 0.96 of every turn-in slide
(measured 0.93–0.98)."""

MUJOCO_CONTACTS = {
    0.3: MUJOCO_CONTACT,
    0.2: ContactParams(
        beta_deg=10.28, slide_friction=0.136,
        turn_in=((2.0, 2.255), (3.0, 1.550), (5.0, 0.734), (7.0, 0.382), (8.0, 0.237),
                 (9.0, 0.145), (9.5, 0.082), (9.75, 0.048), (9.9, 0.037), (10.0, 0.025),
                 (10.1, 0.0145))),
}
"""The MuJoCo body's rule by drive speed [m/s]: it turns in over shorter slides when it drives
slower (``--speed 0.2``: 2.25 m from 2°, 0.73 m from 5°, bump at 10.28°). 0.3 m/s is
``validate``'s speed, 0.2 m/s navigation's."""

__all__ += ["ContactParams", "PYBULLET_CONTACT", "MUJOCO_CONTACT", "MUJOCO_CONTACTS"]
