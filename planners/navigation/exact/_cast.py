"""Scalar ray casts along the Δ-grid headings with the walls culled per heading and origin
(the exact planner's single queries, docs/model.md §13).

The exact planner's flights leave every pose along one of the K headings θ_k. A disk of
radius r that starts within ρ of a point c and moves along u can only touch wall points q
with |(q − c)·n| ≤ r + ρ and (q − c)·u ≥ −(r + ρ) (n ⟂ u): a half-strip ahead of c. For
every heading and every cell of a fine grid (cell g, ρ = g/√2 plus a 1e-6 m margin) the
sides and corners that meet that half-strip are listed once; a cast then runs the motion
layer's scalar cast (:class:`envs.motion.WallCaster`'s ``cast_one``) over those only. Every
feature left out would give no contact, so the distance is the full cast's, bitwise (the
minimum of the same numbers).
"""

from __future__ import annotations

import math

import numpy as np

from envs.motion import WallCaster, cast_scalar

__all__ = ["HeadingCaster"]

_MARGIN = 1e-6           # [m] added to the half-strip's half-width


class HeadingCaster:
    """:meth:`envs.motion.WallCaster.cast_one` for unit headings ``units[k]``, with the walls
    culled per heading and fine grid cell.

    Parameters
    ----------
    caster : WallCaster
    units : (K, 2) float   unit heading vectors
    fine : float           fine grid cell [m] (at least 1/64 of the walls' extent, so a
                           large map does not make the tables explode; exactness does not
                           depend on it)
    """

    def __init__(self, caster: WallCaster, units, fine: float) -> None:
        self.caster = caster
        units = np.asarray(units, dtype=float).reshape(-1, 2)
        seg = caster.segments
        lo = np.minimum(seg[:, 0], seg[:, 1]).min(axis=0)
        hi = np.maximum(seg[:, 0], seg[:, 1]).max(axis=0)
        g = max(float(fine), float((hi - lo).max()) / 64)
        self.g, self.x0, self.y0 = g, float(lo[0]), float(lo[1])
        self.nx = max(1, int(math.ceil((hi[0] - lo[0]) / g)))
        self.ny = max(1, int(math.ceil((hi[1] - lo[1]) / g)))
        jj, ii = np.mgrid[0:self.ny, 0:self.nx]
        cen = np.column_stack([self.x0 + (ii.ravel() + 0.5) * g,
                               self.y0 + (jj.ravel() + 0.5) * g])
        R = caster.r + g * math.sqrt(0.5) + _MARGIN
        A = caster.A
        d = caster.e * caster.L[:, None]                      # B − A
        V = caster.vertices
        sides, verts = caster.side_list, caster.vert_list
        self.sides: list = [[] for _ in units]
        self.verts: list = [[] for _ in units]
        chunk = max(1, 1_000_000 // (len(A) + len(V)))    # cells per block of the tests
        for lo_c in range(0, len(cen), chunk):
            c = cen[lo_c:lo_c + chunk]
            for ku, u in enumerate(units):
                ok, okv = _near(A - c[:, None], d, V - c[:, None], u, R)
                self.sides[ku].extend([sides[i] for i in np.flatnonzero(row)] for row in ok)
                self.verts[ku].extend([verts[i] for i in np.flatnonzero(row)] for row in okv)

    def cast_one(self, x: float, y: float, k: int, ux: float, uy: float) -> float:
        """Contact distance [m] from (x, y) along heading ``k`` (unit vector (ux, uy) =
        ``units[k]``): :meth:`WallCaster.cast_one`, bitwise.
        """
        i = int((x - self.x0) // self.g)
        j = int((y - self.y0) // self.g)
        c = self.caster
        if 0 <= i < self.nx and 0 <= j < self.ny:
            f = j * self.nx + i
            return cast_scalar(self.sides[k][f], self.verts[k][f], c.r, c.r2, c.graze,
                                x, y, ux, uy)
        return c.cast_one(x, y, ux, uy)


def _near(A, d, V, u, R: float):
    """Which sides A + λd (λ ∈ [0, 1]) and corners V, given relative to the cell centres
    ((F, m, 2) and (F, v, 2)), meet the half-strip |q·n| <= R, q·u >= −R (n ⟂ u):
    (F, m) and (F, v) booleans.
    """
    n = np.array([-u[1], u[0]])
    an, au = A @ n, A @ u                                  # (F, m)
    dn, du = d @ n, d @ u
    lo = np.zeros_like(an)
    hi = np.ones_like(an)
    ok = np.ones(an.shape, dtype=bool)
    # the segment clipped to p + λ q >= 0 for the three sides of the half-strip (Liang–Barsky)
    for p, q in ((R - an, -dn), (R + an, dn), (R + au, du)):
        q = np.broadcast_to(q, p.shape)
        with np.errstate(divide="ignore", invalid="ignore"):
            lam = -p / q
        lo = np.where(q > 0, np.maximum(lo, lam), lo)
        hi = np.where(q < 0, np.minimum(hi, lam), hi)
        ok &= (q != 0) | (p >= 0)
    ok &= lo <= hi
    vn, vu = V @ n, V @ u
    return ok, (np.abs(vn) <= R) & (vu >= -R)
