"""Scalar ray casts along the Δ-grid headings with the walls culled per heading and origin
(the exact planner's single queries, docs/model.md §15).

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

from envs.motion import WallCaster, _cast_scalar

__all__ = ["HeadingCaster"]

_MARGIN = 1e-6           # [m] added to the half-strip's half-width


class HeadingCaster:
    """:meth:`envs.motion.WallCaster.cast_one` for unit headings ``units[k]``, with the walls
    culled per heading and fine grid cell.

    Parameters
    ----------
    caster : WallCaster
    units : (K, 2) float   unit heading vectors
    fine : float           fine grid cell [m]
    """

    def __init__(self, caster: WallCaster, units, fine: float) -> None:
        self.caster = caster
        units = np.asarray(units, dtype=float).reshape(-1, 2)
        seg = caster.segments
        lo = np.minimum(seg[:, 0], seg[:, 1]).min(axis=0)
        hi = np.maximum(seg[:, 0], seg[:, 1]).max(axis=0)
        g = float(fine)
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
        sides, verts = caster._side_list, caster._vert_list
        self.sides: list = []
        self.verts: list = []
        for u in units:
            n = np.array([-u[1], u[0]])
            an = (A[None] - cen[:, None]) @ n                  # (F, m)
            au = (A[None] - cen[:, None]) @ u
            dn, du = d @ n, d @ u
            lo_l = np.zeros_like(an)
            hi_l = np.ones_like(an)
            ok = np.ones(an.shape, dtype=bool)
            # the segment A + λ(B − A), λ ∈ [0, 1], clipped to p + λ q >= 0 (Liang–Barsky)
            for p, q in ((R - an, -dn), (R + an, dn), (R + au, du)):
                q = np.broadcast_to(q, p.shape)
                with np.errstate(divide="ignore", invalid="ignore"):
                    lam = -p / q
                lo_l = np.where(q > 0, np.maximum(lo_l, lam), lo_l)
                hi_l = np.where(q < 0, np.minimum(hi_l, lam), hi_l)
                ok &= (q != 0) | (p >= 0)
            ok &= lo_l <= hi_l
            vn = (V[None] - cen[:, None]) @ n
            vu = (V[None] - cen[:, None]) @ u
            okv = (np.abs(vn) <= R) & (vu >= -R)
            self.sides.append([[sides[i] for i in np.flatnonzero(row)] for row in ok])
            self.verts.append([[verts[i] for i in np.flatnonzero(row)] for row in okv])

    def cast_one(self, x: float, y: float, k: int, ux: float, uy: float) -> float:
        """Contact distance [m] from (x, y) along heading ``k`` (unit vector (ux, uy) =
        ``units[k]``): :meth:`WallCaster.cast_one`, bitwise.
        """
        i = int((x - self.x0) // self.g)
        j = int((y - self.y0) // self.g)
        c = self.caster
        if 0 <= i < self.nx and 0 <= j < self.ny:
            f = j * self.nx + i
            return _cast_scalar(self.sides[k][f], self.verts[k][f], c.r, c._r2, c._graze,
                                x, y, ux, uy)
        return c.cast_one(x, y, ux, uy)
