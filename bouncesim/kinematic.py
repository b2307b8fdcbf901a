"""The kinematic twin: exact continuous geometry, simulated time (MODEL §8-9).

The robot is a disk of radius r whose centre moves inside the C-space (E eroded by r). A
straight drive is a ray cast against the walls *grown into capsules*: the disk centred at c
touches a wall segment AB exactly when dist(c, AB) = r, so the first contact along the ray
c + t u is the first entry of the ray into one of the capsules {p : dist(p, AB) <= r}. Each
capsule is the union of a rectangle (the segment's two offset sides) and two disks (its end
points), so the entry distance has a closed form (no polygonal approximation of the rounded
corners, unlike ``env.cspace``). :class:`WallCaster` does this vectorised over robots x walls.

Two bodies use it:

- :class:`KinematicRobot`, a :class:`bouncesim.robot.Robot` for the executors: ``wait(dt)``
  advances the pose under the current wheel command, ``drive_until_bump`` jumps straight to
  the contact (or the timeout), ``turn`` is exact plus a seeded noise sample.
- :class:`KinematicBatch`, thousands of independent robots stepped at once under the MODEL §9
  step semantics, for Monte-Carlo coverage.

Contact conventions (shared by both)
------------------------------------
- A drive stops ``CONTACT_GAP`` = 1e-9 m (along the ray) before the computed contact, so the
  disk does not penetrate a wall (at a glancing incidence the gap to the wall is smaller than
  1e-9 m; rounding is then of order 1e-16 m).
- Motion parallel to a wall the disk touches is not a contact (a robot in a cell next to a wall
  sits at exactly distance r from it): a side is hit only when the motion approaches its line
  (rate > 1e-12 per metre), a wall corner only when the ray passes closer than r − 1e-7 m
  (100 times the contact gap, so a robot stopped at a wall can slide past the corners in
  line with that wall; a grazing pass may overlap a corner by at most 1e-7 m).
- The bumper is the front half of the body. It reads closed when the wall blocks forward
  motion within ``BUMP_RANGE`` = 1e-6 m; the side is taken from the bearing β of the contact
  point relative to the heading: |β| <= 10° closes both switches, β > 10° the left one and
  β < −10° the right one. A contact behind the centre line (driving backwards into a wall) is
  not a bump: the robot stalls there, its clock runs on and the bumper stays open.
- Opt-in for the single robot only (``KinematicRobot(glance_deg=...)``): contacts more than
  ``glance_deg`` from the heading do not press the bumper; the body slides along the wall.
  The default and the batch keep the front-half bumper above.

Examples
--------
>>> import envs
>>> env = envs.load("lab")
>>> bot = KinematicRobot(env)
>>> bot.place(0.51, 0.51, 30.0)
>>> ev = bot.drive_until_bump(0.2, 60.0)
>>> ev.bumped, round(ev.elapsed, 4)          # centre reaches y = 1.02 - r = 0.85 after 0.68 m
(True, 3.4)
>>> tuple(round(v, 4) for v in bot.true_pose())
(1.0989, 0.85, 30.0)
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from functools import cached_property, lru_cache

import numpy as np

from envs import Environment, UserError
from planners.cells import CellSpace
from planners.plan import PolicyMix

from .noise import NoiseModel, NoNoise, noise_for_mix
from .robot import CREATE2, BumpEvent, Robot, RobotSpec

__all__ = ["WallCaster", "LocalCaster", "casters", "KinematicRobot", "KinematicBatch",
           "BatchCoverage", "unit", "CONTACT_GAP", "BUMP_RANGE", "STEP_TOL", "CENTRE_ZONE_DEG"]

CONTACT_GAP = 1e-9
"""[m] a drive stops this far (along the ray) short of the exact contact."""
BUMP_RANGE = 1e-6
"""[m] the bumper reads closed when forward motion is blocked within this distance."""
STEP_TOL = 1e-6
"""[m] a step whose drive reaches the wall within this of the full length h is a forward step
(the robot ends touching the wall and bumps at the start of the next step)."""
CENTRE_ZONE_DEG = 10.0
"""[deg] contacts within ±this of straight ahead close both bumper switches."""
_EXACT = NoNoise()
_MAX_EVENTS = 64         # contacts and slides handled within one forward drive
_SCALAR_MAX = 8          # batches up to this size cast robot by robot in plain Python
_APPROACH_MIN = 1e-12   # a side is approached only when u . n exceeds this
_GRAZE_TOL = 1e-7       # [m] a corner is hit only when the ray passes closer than r - this


def unit(heading_deg) -> np.ndarray:
    """Unit heading vector(s) (..., 2) of heading(s) [deg]; |components| < 1e-12 snap to 0
    so that axis-aligned headings are exact (cos 90° would otherwise be 6e-17)."""
    th = np.radians(np.asarray(heading_deg, dtype=float))
    u = np.stack([np.cos(th), np.sin(th)], axis=-1)
    u[np.abs(u) < 1e-12] = 0.0
    return u


def _cast_scalar(sides, verts, r, r2, graze, x, y, ux, uy, within=None):
    """The capsule ray cast for one disk over lists of sides (Ax, Ay, ex, ey, L) and corners
    (Vx, Vy): the contact distance, or with ``within`` the wall points touched within it."""
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
        # Row vectors for broadcasting against (n_rays, 1) columns.
        self._Ax, self._Ay = self.A[:, 0][None], self.A[:, 1][None]
        self._ex, self._ey = self.e[:, 0][None], self.e[:, 1][None]
        self._nx, self._ny = self.n[:, 0][None], self.n[:, 1][None]
        self._Lr = self.L[None]
        self._Vx, self._Vy = self.vertices[:, 0][None], self.vertices[:, 1][None]
        self._r2 = self.r * self.r
        self._graze = self.r * self.r - (self.r - _GRAZE_TOL) ** 2
        # Python floats for the scalar path (one robot): same formulas, same rounding
        self._side_list = [tuple(float(v) for v in row) for row in
                           np.column_stack([self.A, self.e, self.L])]
        self._vert_list = [(float(x), float(y)) for x, y in self.vertices]

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
        disc = self._r2 - rho2
        ok = (b < 0.0) & (disc > self._graze)
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
        return _cast_scalar(self._side_list, self._vert_list, self.r, self._r2, self._graze,
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
    fine : float, optional   fine-grid cell [m] (default r / 2)
    """

    def __init__(self, caster: WallCaster, max_dist: float, fine: float | None = None) -> None:
        self.caster = caster
        self.max_dist = float(max_dist)
        r = caster.r
        g = float(fine) if fine is not None else r / 2
        seg = caster.segments
        lo = np.minimum(seg[:, 0], seg[:, 1]).min(axis=0)
        hi = np.maximum(seg[:, 0], seg[:, 1]).max(axis=0)
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
        ``within`` <= ``max_dist``, the wall points touched within that distance."""
        i = min(max(int((x - self.x0) / self.g), 0), self.nx - 1)
        j = min(max(int((y - self.y0) / self.g), 0), self.ny - 1)
        sides, verts = self._scalar_lists
        f = j * self.nx + i
        c = self.caster
        return _cast_scalar(sides[f], verts[f], c.r, c._r2, c._graze, x, y, ux, uy, within)

    def fine_cell(self, pos: np.ndarray) -> np.ndarray:
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
        disc = self.caster._r2 - (vx * vx + vy * vy - b * b)
        ok = (b < 0.0) & (disc > self.caster._graze)
        with np.errstate(invalid="ignore"):
            tc = np.where(ok, -b - np.sqrt(np.maximum(disc, 0.0)), np.inf)
        return np.maximum(np.minimum(ts, tc.min(axis=1)), 0.0)


@lru_cache(maxsize=32)
def casters(env: Environment, step: float | None = None) -> tuple[WallCaster, LocalCaster]:
    """The (cached) full and local casters of an environment; local range ``step`` [m]
    (default the cell size)."""
    full = WallCaster(env.wall_segments, env.robot_radius)
    return full, LocalCaster(full, env.cell_size if step is None else step)


# ============================================================================ one robot
class KinematicRobot(Robot):
    """A disk robot with exact straight-line kinematics and simulated time.

    Parameters
    ----------
    env : Environment
    noise : NoiseModel, optional
        Rotation noise applied to every :meth:`turn` (default None: exact).
    rng : numpy.random.Generator or int, optional
        Source of the noise draws (an int is a seed). Required when the noise is not exact.
    turn_speed : float
        Wheel speed used for in-place turns [m/s]; a turn by φ takes
        ``spec.turn_time(φ, turn_speed)`` of simulated time.
    turn : {"clock", "encoders"}
        Accepted for parity with the PyBullet robot; in the twin both are exact (the wheels
        turn by exactly the commanded arc) and take the same time.
    glance_deg : float, optional
        Opt-in glancing-contact model. Default None: every contact on the front half stops
        the robot and closes the bumper (the MODEL §8 twin). With a value in (0°, 90°), a
        contact whose bearing from the heading exceeds it (a wall met at less than
        90° − glance_deg) does not press the bumper: the body slides along the wall (heading
        kept, speed v·sin β along the wall; around a corner it wraps on the corner's circle
        until it can go straight on). 80 matches the PyBullet robot's bumper arc. Two
        glancing contacts at once (a pocket) stall the robot without a bump.
    spec : RobotSpec, optional
        Body figures; default the Create 2 with the environment's radius.

    Notes
    -----
    The robot starts at the centre of position cell 0 facing east, clock 0. ``turn`` leaves
    the wheels stopped. Encoders count the wheel travel: straight motion actually made (a
    stalled robot's wheels do not count) and the *commanded* turn (noise is body slip, which
    encoders do not see).
    """

    def __init__(self, env: Environment, noise: NoiseModel | None = None, rng=None, *,
                 turn_speed: float = 0.1, turn: str = "clock",
                 spec: RobotSpec | None = None, glance_deg: float | None = None) -> None:
        self.env = env
        self.noise = noise if noise is not None else NoNoise()
        if rng is None and not self.noise.exact:
            raise ValueError("a KinematicRobot with rotation noise needs an rng (or a seed).")
        self.rng = rng if isinstance(rng, np.random.Generator) or rng is None else \
            np.random.default_rng(rng)
        self.spec = spec if spec is not None else replace(CREATE2, radius=env.robot_radius)
        if not 0 < turn_speed <= self.spec.max_wheel_speed:
            raise UserError(f"turn speed must lie in (0, {self.spec.max_wheel_speed:g}] m/s, "
                            f"got {turn_speed:g}.")
        self.turn_speed = float(turn_speed)
        if turn not in ("clock", "encoders"):
            raise UserError(f"turn must be 'clock' or 'encoders', got {turn!r}.")
        self.turn_mode = turn
        if glance_deg is not None and not 0 < float(glance_deg) < 90:
            raise UserError(f"glance_deg must lie in (0, 90) degrees, got {glance_deg}.")
        self.glance_deg = None if glance_deg is None else float(glance_deg)
        self.caster, self.local = casters(env)
        cells = CellSpace(env)
        x, y = cells.centres[0]
        self._x, self._y = float(x), float(y)
        self._set_heading(0.0)
        self._speed = 0.0
        self._t = 0.0
        self._wheel = [0.0, 0.0]           # left, right wheel travel [m]

    # ------------------------------------------------------------------ helpers
    def _set_heading(self, deg: float) -> None:
        self._heading = float(deg)
        # the batch's array path, so both bodies use bitwise the same unit vectors
        ux, uy = unit(np.array([self._heading]))[0]
        self._ux, self._uy = float(ux), float(uy)

    def _free_distance(self, sign: float, need: float = math.inf) -> float:
        """Distance [m] to contact along ±heading; exact when below ``need`` (else >= need)."""
        ux, uy = sign * self._ux, sign * self._uy
        t = self.local.cast_one(self._x, self._y, ux, uy)
        if t < self.local.max_dist or need < self.local.max_dist:
            return t
        return self.caster.cast_one(self._x, self._y, ux, uy)

    def _advance(self, d: float) -> None:
        """Move d [m] along the heading (negative: backwards) without a collision check."""
        self._x += d * self._ux
        self._y += d * self._uy
        self._wheel[0] += d
        self._wheel[1] += d

    def _move(self, dist: float) -> float:
        """Move ``dist`` [m] along the heading (negative: backwards), stopping at contact.
        Returns the distance actually travelled (signed)."""
        if dist == 0:
            return 0.0
        sign = 1.0 if dist > 0 else -1.0
        free = max(self._free_distance(sign, abs(dist) + CONTACT_GAP) - CONTACT_GAP, 0.0)
        d = sign * min(abs(dist), free)
        self._advance(d)
        return d

    # ------------------------------------------------------------------ Robot interface
    def drive(self, speed: float) -> None:
        speed = float(speed)
        if not math.isfinite(speed) or abs(speed) > self.spec.max_wheel_speed + 1e-12:
            raise UserError(f"speed {speed:g} m/s is beyond the robot's "
                            f"{self.spec.max_wheel_speed:g} m/s wheel limit.")
        self._speed = speed

    def stop(self) -> None:
        self._speed = 0.0

    def _contacts(self) -> list[tuple[float, float, float, tuple | None]]:
        """Front contacts within BUMP_RANGE ahead: (bearing β [deg], x, y, side or None)."""
        x, y, ux, uy = self._x, self._y, self._ux, self._uy
        out = []
        for px, py, side in self.local.cast_one(x, y, ux, uy, BUMP_RANGE):
            wx, wy = px - x, py - y
            beta = math.degrees(math.atan2(ux * wy - uy * wx, ux * wx + uy * wy))
            if abs(beta) < 90.0:       # behind the centre line: not the bumper
                out.append((beta, px, py, side))
        return out

    def bumper(self) -> tuple[bool, bool]:
        arc = 90.0 if self.glance_deg is None else self.glance_deg
        left = right = False
        for beta, _, _, _ in self._contacts():
            if abs(beta) <= arc:
                left |= beta >= -CENTRE_ZONE_DEG
                right |= beta <= CENTRE_ZONE_DEG
        return bool(left), bool(right)

    def clock(self) -> float:
        return self._t

    def wait(self, duration: float) -> None:
        duration = float(duration)
        if duration < 0 or not math.isfinite(duration):
            raise ValueError(f"cannot wait {duration} s.")
        if self._speed > 0:
            self._forward(self._speed, duration)
        else:
            self._move(self._speed * duration)
        self._t += duration

    def turn(self, angle_deg: float) -> None:
        angle = float(angle_deg)
        actual = self.noise.sample(self.rng, angle)
        self._set_heading((self._heading + actual) % 360.0)
        self._t += self.spec.turn_time(angle, self.turn_speed)
        arc = math.radians(angle) * self.spec.wheel_base / 2
        self._wheel[0] -= arc
        self._wheel[1] += arc
        self._speed = 0.0

    def encoders(self) -> tuple[int, int]:
        mpc = self.spec.metres_per_count
        return int(round(self._wheel[0] / mpc)), int(round(self._wheel[1] / mpc))

    def _forward(self, speed: float, duration: float) -> tuple[float | None, float]:
        """Drive forward at ``speed`` > 0 [m/s] for up to ``duration`` [s] (clock untouched).

        Returns (time of the bump that stopped the robot, or None; free distance left ahead
        [m] at the end). After a bump, or when wedged, the robot stays put.
        """
        t = 0.0
        for _ in range(_MAX_EVENTS):
            reach = speed * (duration - t)
            ahead = self._free_distance(1.0, reach + CONTACT_GAP + BUMP_RANGE)
            dist = max(ahead - CONTACT_GAP, 0.0)
            if dist > reach:
                self._advance(reach)
                return None, dist - reach
            self._advance(dist)
            t += dist / speed
            if self.glance_deg is None:
                return t, 0.0
            contacts = self._contacts()
            if not contacts or any(abs(b) <= self.glance_deg for b, *_ in contacts):
                return t, 0.0
            used = self._slide(contacts, speed, duration - t)
            if used is None:                     # wedged: pushes on without moving
                return None, 0.0
            t += used
            if t >= duration:
                return None, self._free_distance(1.0, BUMP_RANGE)
        return None, 0.0

    def _slide(self, contacts, speed: float, budget: float) -> float | None:
        """Slide along the one glancing contact for at most ``budget`` [s]; the time used,
        or None when the robot is wedged (two walls at once, or the slide is blocked)."""
        pts = {(round(px, 9), round(py, 9)): (b, px, py, side) for b, px, py, side in contacts}
        if len(pts) != 1:
            sides = [c for c in contacts if c[3] is not None]
            if len(sides) != 1 or len({(round(c[1], 9), round(c[2], 9)) for c in contacts}) > 1:
                return None
            contacts = sides
        beta, px, py, side = contacts[0]
        x, y, ux, uy = self._x, self._y, self._ux, self._uy
        nx, ny = x - px, y - py
        nn = math.hypot(nx, ny)
        nx, ny = nx / nn, ny / nn                       # wall -> centre
        un = ux * nx + uy * ny
        tx, ty = ux - un * nx, uy - un * ny              # the push along the wall
        ts = math.hypot(tx, ty)
        if ts < 1e-12:
            return None
        tx, ty = tx / ts, ty / ts
        if side is not None:                             # slide along a straight wall
            Ax, Ay, ex, ey, L = side
            lam = (x - Ax) * ex + (y - Ay) * ey
            along = tx * ex + ty * ey
            to_end = (L - lam if along > 0 else lam) / abs(along) + 1e-9
            block = self.caster.cast_one(x, y, tx, ty)
            d = min(to_end, max(block - CONTACT_GAP, 0.0), speed * ts * budget)
            if d <= 0:
                return None
            self._x += d * tx
            self._y += d * ty
            self._wheel[0] += d
            self._wheel[1] += d
            return d / (speed * ts)
        # wrap around a corner V = (px, py) on the circle of radius r until the contact is
        # abeam (bearing 90°): time (r / v) ln(tan(45°) / tan(β0 / 2))
        r = self.env.robot_radius
        b0 = math.radians(abs(beta))
        full = (r / speed) * -math.log(math.tan(b0 / 2))
        used = min(full, budget)
        b1 = 2 * math.atan(math.tan(b0 / 2) * math.exp(speed * used / r))
        turn = b1 - b0
        sgn = 1.0 if (nx * ty - ny * tx) > 0 else -1.0   # the normal turns toward the push
        c, s_ = math.cos(sgn * turn), math.sin(sgn * turn)
        mx, my = c * nx - s_ * ny, s_ * nx + c * ny
        qx, qy = px + r * mx, py + r * my
        # the arc is at most 90° - glance_deg long: check that its end is clear of the walls
        if not bool(self.env.points_free([[qx, qy]])[0]):
            return None
        self._x, self._y = qx, qy
        self._wheel[0] += r * turn
        self._wheel[1] += r * turn
        return used

    def drive_until_bump(self, speed: float, timeout: float) -> BumpEvent:
        """Exact equivalent of the polling default: jump to the contact or to the timeout.

        A bumper already closed returns at once; otherwise the robot drives to the first
        contact (bump, elapsed = distance / speed) or for the whole timeout (no bump, unless
        the wall is then within ``BUMP_RANGE``: the polling loop reads the bumper once more
        at the timeout). Driving backwards never bumps (the bumper is the front half).
        """
        t0 = self._t
        self.drive(speed)
        try:
            timeout = max(float(timeout), 0.0)
            reach = max(speed, 0.0) * timeout
            ahead = self._free_distance(1.0, reach + CONTACT_GAP + BUMP_RANGE)
            if ahead <= BUMP_RANGE:              # touching something ahead: pressed?
                left, right = self.bumper()
                if left or right:
                    return BumpEvent(True, left, right, 0.0)
            if speed > 0:
                t_bump, left_ahead = self._forward(speed, timeout)
                if t_bump is not None:
                    self._t += t_bump
                    left, right = self.bumper()
                    return BumpEvent(True, left, right, t_bump)
                self._t += timeout
                if left_ahead <= BUMP_RANGE:
                    left, right = self.bumper()
                    return BumpEvent(bool(left or right), left, right, timeout)
                return BumpEvent(False, False, False, timeout)
            self.wait(timeout)
            left, right = self.bumper()
            return BumpEvent(bool(left or right), left, right, self._t - t0)
        finally:
            self.stop()

    # ------------------------------------------------------------------ simulation only
    def place(self, x: float, y: float, heading_deg: float) -> None:
        x, y = float(x), float(y)
        if not bool(self.env.points_free([[x, y]])[0]):
            raise UserError(f"the robot does not fit at ({x:g}, {y:g}) in {self.env.name}.")
        self._x, self._y = x, y
        self._set_heading(float(heading_deg) % 360.0)
        self._speed = 0.0

    def true_pose(self) -> tuple[float, float, float]:
        return self._x, self._y, self._heading

    def __repr__(self) -> str:
        return (f"KinematicRobot({self.env.name!r}, pose=({self._x:.3f}, {self._y:.3f}, "
                f"{self._heading:.1f}°), t={self._t:.3f} s, noise={self.noise})")


# ============================================================================ many robots
@dataclass(frozen=True)
class BatchCoverage:
    """Step-sampled visit histogram of a batch run (MODEL §9).

    Attributes
    ----------
    counts : (P,) int array    steps counted in each free position cell
    dropped : int              steps counted in no free cell
    bumps : int                bump steps (move to contact + rotation)
    n_robots : int
    steps : int                steps per robot (after burn-in)
    """

    counts: np.ndarray
    dropped: int
    bumps: int
    n_robots: int
    steps: int

    @property
    def total(self) -> int:
        """All robot-steps, dropped ones included."""
        return int(self.counts.sum()) + self.dropped

    @property
    def coverage(self) -> np.ndarray:
        """(P,) fraction of the counted (non-dropped) steps in each position cell."""
        c = self.counts.astype(float)
        s = c.sum()
        return c / s if s > 0 else c

    def tv(self, q) -> float:
        """Total-variation distance ½ Σ |q − q̂| to a predicted coverage q (P,)."""
        q = np.asarray(q, dtype=float)
        return 0.5 * float(np.abs(q / q.sum() - self.coverage).sum())


class KinematicBatch:
    """Many independent kinematic robots stepped together (MODEL §9 step semantics).

    A step: if the wall ahead is at least h away, move h forward (counted in the cell where
    the step starts); otherwise move to contact, then rotate in place by the current bouncing
    angle plus noise (one step, counted in the cell of the contact position). A contact within
    ``STEP_TOL`` of h counts as a full forward step (the robot then bumps at the start of the
    next step), as :func:`bouncesim.execute.execute_mix` counts it on a Robot.

    Parameters
    ----------
    env : Environment
    n_robots : int
    rng : numpy.random.Generator or int
        Draws the starts, the epoch angles and the rotation noise.
    cells : CellSpace, optional
    step : float, optional   step length [m] (default the cell size h)
    starts : (n_robots,) int array, optional
        Start configurations z (default: drawn uniformly from the N configurations).

    Attributes
    ----------
    pos : (n, 2) array      robot centres [m]
    heading : (n,) array    headings [deg]; change it by assignment, not in place (the cached
                            unit vectors follow assignments and the batch's own turns)

    Notes
    -----
    Starts are uniform over the N free configurations: the centre of position cell p facing
    θ_k, (p, k) drawn uniformly (as MODEL §7 starts the chain).

    Examples
    --------
    >>> import envs
    >>> b = KinematicBatch(envs.load("lab"), 200, np.random.default_rng(0))
    >>> res = b.run(90.0, 50)
    >>> res.total, res.counts.shape
    (10000, (48,))
    """

    def __init__(self, env: Environment, n_robots: int, rng, *, cells: CellSpace | None = None,
                 step: float | None = None, starts=None) -> None:
        self.env = env
        self.cells = cells if cells is not None else CellSpace(env)
        self.rng = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
        self.n = int(n_robots)
        if self.n < 1:
            raise ValueError("a batch needs at least one robot.")
        self.h = float(step if step is not None else env.cell_size)
        self.caster, self.local = casters(env, None if step is None else self.h)
        if starts is None:
            z = self.rng.integers(0, self.cells.N, size=self.n)
        else:
            z = np.asarray(starts, dtype=np.int64).reshape(-1)
            if z.shape != (self.n,) or (z < 0).any() or (z >= self.cells.N).any():
                raise ValueError(f"starts must be {self.n} configurations in [0, {self.cells.N}).")
        p, k = self.cells.pk(z)
        self.pos = self.cells.centres[p].copy()
        self.heading = (k * self.cells.delta_deg).astype(float)
        self._u = self._u_of = None      # cached unit headings, refreshed on turns
        x0, y0 = env.origin
        self._x0, self._y0 = x0, y0
        self._grid = self.cells.index_grid
        self._rows, self._cols = self._grid.shape

    def cell_of(self, pos: np.ndarray) -> np.ndarray:
        """Position cell p of each point (n, 2), or -1 outside the free cells."""
        h = self.cells.h
        i = np.floor((pos[:, 0] - self._x0) / h).astype(np.int64)
        j = np.floor((pos[:, 1] - self._y0) / h).astype(np.int64)
        ok = (i >= 0) & (i < self._cols) & (j >= 0) & (j < self._rows)
        out = np.full(len(pos), -1, dtype=np.int64)
        out[ok] = self._grid[j[ok], i[ok]]
        return out

    def step(self, angles_deg, noise: NoiseModel | None = None
             ) -> tuple[np.ndarray, np.ndarray]:
        """Advance every robot by one step.

        Parameters
        ----------
        angles_deg : float or (n,) array   each robot's current bouncing angle [deg]
        noise : NoiseModel, optional   rotation noise (default exact)

        Returns
        -------
        cells : (n,) int     the cell each step is counted in (-1: no free cell)
        bumped : (n,) bool   which robots bumped (and turned)
        """
        if self._u is None or self._u_of is not self.heading:
            self._u, self._u_of = unit(self.heading), self.heading
        u = self._u
        if self.n <= _SCALAR_MAX:          # a handful of robots: the scalar path is faster
            free = np.array([self.local.cast_one(x, y, a, b)
                             for (x, y), (a, b) in zip(self.pos.tolist(), u.tolist())])
        else:
            free = self.local.cast(self.pos, u)
        free -= CONTACT_GAP
        move = np.clip(free, 0.0, self.h, out=free)
        bumped = move < self.h - STEP_TOL
        counted = self.cell_of(self.pos)
        self.pos += move[:, None] * u
        if bumped.any():
            idx = np.flatnonzero(bumped)
            counted[idx] = self.cell_of(self.pos[idx])
            ang = np.broadcast_to(np.asarray(angles_deg, dtype=float), (self.n,))[idx]
            noise = noise if noise is not None else _EXACT
            self.heading[idx] = (self.heading[idx] + noise.sample_many(self.rng, ang)) % 360.0
            u[idx] = unit(self.heading[idx])
        return counted, bumped

    def run(self, policy, steps: int, *, epoch: int | None = None,
            noise: NoiseModel | None = None, burn_in: int = 0) -> BatchCoverage:
        """Run ``steps`` steps per robot and return the step-sampled visit histogram.

        Parameters
        ----------
        policy : float or PolicyMix
            One bouncing angle [deg], or a mix time-shared in epochs (MODEL §8): every robot
            draws, independently, one angle with probabilities α per epoch.
        steps : int          counted steps per robot
        epoch : int          steps per epoch (required for a mix of two or more angles)
        noise : NoiseModel   rotation noise; default the mix's §7 model (eps, r), else exact
        burn_in : int        steps run first and not counted
        """
        if isinstance(policy, PolicyMix):
            angles = np.asarray(policy.angles, dtype=float)
            alpha = np.asarray(policy.alpha, dtype=float)
            alpha = alpha / alpha.sum()
            if noise is None:
                noise = noise_for_mix(policy, self.cells.delta_deg)
        else:
            angles, alpha = np.array([float(policy)]), np.ones(1)
        for a in angles:
            self.cells.angle_steps(a)                  # a multiple of 360°/K (MODEL §5)
        noise = noise if noise is not None else NoNoise()
        mixed = np.count_nonzero(alpha > 0) > 1
        if mixed and (epoch is None or int(epoch) < 1):
            raise UserError("a policy mix of two or more angles needs an epoch length >= 1.")
        epoch = int(epoch) if epoch else 1
        counts = np.zeros(self.cells.P + 1, dtype=np.int64)   # last bin: dropped
        bumps = 0
        current = np.full(self.n, angles[0])
        for s in range(int(burn_in) + int(steps)):
            if mixed and s % epoch == 0:
                current = angles[self.rng.choice(len(angles), size=self.n, p=alpha)]
            cells, bumped = self.step(current, noise)
            if s >= burn_in:
                counts += np.bincount(np.where(cells < 0, self.cells.P, cells),
                                      minlength=self.cells.P + 1)
                bumps += int(bumped.sum())
        return BatchCoverage(counts=counts[:-1], dropped=int(counts[-1]), bumps=bumps,
                             n_robots=self.n, steps=int(steps))
