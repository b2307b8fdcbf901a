"""Walls for a physics engine: an environment's polygons cut into convex pieces.

Physics engines collide convex shapes, so the PyBullet world
(:mod:`bouncesim.robots.pybullet.robot`) and the MuJoCo world
(:mod:`bouncesim.robots.mujoco.world`) are built from these pieces (world frame of
docs/model.md §1, metres):

- the outer boundary becomes one thin convex slab per boundary edge, lying outside the free
  space (:func:`wall_pieces`), extended past convex corners and mitred at reflex ones;
- every obstacle becomes convex pieces (:func:`convex_pieces`): convex polygons as they are,
  non-convex ones triangulated by ear clipping (:func:`ear_clip`) and greedily merged into
  convex parts.

Examples
--------
>>> from shapely.geometry import Polygon
>>> L = Polygon([(0, 0), (2, 0), (2, 1), (1, 1), (1, 2), (0, 2)])
>>> parts = convex_pieces(L)
>>> round(sum(p.area for p in parts), 9), all(_is_convex(p) for p in parts)
(3.0, True)
>>> [round(p.area, 3) for p in wall_pieces(Polygon([(0, 0), (1, 0), (1, 1), (0, 1)]), 0.1)]
[0.12, 0.12, 0.12, 0.12]
"""

from __future__ import annotations

import math

import numpy as np
import shapely
from shapely.geometry import Polygon
from shapely.geometry.polygon import orient

__all__ = ["WALL_THICKNESS", "convex_pieces", "ear_clip", "wall_pieces"]

WALL_THICKNESS = 0.1
"""Thickness [m] of the boundary slabs."""


def _is_convex(poly: Polygon) -> bool:
    """Whether a polygon is convex (its hull adds no area, up to rounding)."""
    return poly.convex_hull.area - poly.area <= 1e-9 * max(poly.area, 1.0)


def ear_clip(poly: Polygon) -> list[Polygon]:
    """Triangulate a simple polygon without holes by ear clipping.

    The fallback for shapely < 2.1 (which lacks ``constrained_delaunay_triangles``).
    Collinear vertices are dropped; the triangles partition the polygon.

    >>> tris = ear_clip(Polygon([(0, 0), (2, 0), (2, 1), (1, 1), (1, 2), (0, 2)]))
    >>> len(tris), round(sum(t.area for t in tris), 9)
    (4, 3.0)
    """
    if len(poly.interiors):
        raise ValueError("ear_clip handles polygons without holes only.")
    pts = np.asarray(orient(poly, 1.0).exterior.coords)[:-1]
    idx = list(range(len(pts)))
    scale = max(float(np.ptp(pts, axis=0).max()), 1e-12)
    eps = 1e-12 * scale * scale

    def cross(i: int, j: int, k: int) -> float:
        a, b, c = pts[i], pts[j], pts[k]
        return float((b[0] - a[0]) * (c[1] - b[1]) - (b[1] - a[1]) * (c[0] - b[0]))

    def inside(q: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> bool:
        d1 = (b[0] - a[0]) * (q[1] - a[1]) - (b[1] - a[1]) * (q[0] - a[0])
        d2 = (c[0] - b[0]) * (q[1] - b[1]) - (c[1] - b[1]) * (q[0] - b[0])
        d3 = (a[0] - c[0]) * (q[1] - c[1]) - (a[1] - c[1]) * (q[0] - c[0])
        return d1 >= -eps and d2 >= -eps and d3 >= -eps

    tris: list[Polygon] = []
    while len(idx) > 3:
        n = len(idx)
        for k in range(n):
            i0, i1, i2 = idx[k - 1], idx[k], idx[(k + 1) % n]
            if cross(i0, i1, i2) <= eps:
                continue
            a, b, c = pts[i0], pts[i1], pts[i2]
            if any(inside(pts[m], a, b, c) for m in idx
                   if m not in (i0, i1, i2) and not (np.allclose(pts[m], a)
                                                    or np.allclose(pts[m], b)
                                                    or np.allclose(pts[m], c))):
                continue
            tris.append(Polygon([a, b, c]))
            idx.pop(k)
            break
        else:  # no ear: drop a collinear vertex, which does not change the shape
            for k in range(n):
                if abs(cross(idx[k - 1], idx[k], idx[(k + 1) % n])) <= eps:
                    idx.pop(k)
                    break
            else:
                raise ValueError("ear_clip found no ear (is the polygon simple?).")
    if abs(cross(*idx)) > eps:
        tris.append(Polygon(pts[idx]))
    return tris


def _triangulate(poly: Polygon) -> list[Polygon]:
    if hasattr(shapely, "constrained_delaunay_triangles"):
        tris = shapely.get_parts(shapely.constrained_delaunay_triangles(poly))
        return [t for t in tris if t.area > 0]
    return ear_clip(poly)


def convex_pieces(poly: Polygon) -> list[Polygon]:
    """Split a polygon into convex pieces whose union is the polygon.

    A convex polygon is returned as it is; a non-convex one is triangulated (shapely's
    constrained Delaunay triangulation, or :func:`ear_clip`) and neighbouring pieces are
    merged greedily while their union stays convex.

    Parameters
    ----------
    poly : Polygon
        A simple polygon [m] (holes are triangulated around when shapely ≥ 2.1).

    Returns
    -------
    list of Polygon
    """
    if _is_convex(poly):
        return [poly]
    return _merge_convex(_triangulate(poly), 1e-9 * max(math.sqrt(poly.area), 1.0))


def _merge_convex(pieces: list[Polygon], tol: float = 1e-9) -> list[Polygon]:
    """Greedily merge pieces that share an edge while their union stays convex."""
    pieces = list(pieces)
    merged = True
    while merged:
        merged = False
        for i in range(len(pieces)):
            for j in range(i + 1, len(pieces)):
                a, b = pieces[i], pieces[j]
                if a.boundary.intersection(b.boundary).length <= tol:
                    continue
                u = shapely.union(a, b)
                if isinstance(u, Polygon) and not len(u.interiors) and _is_convex(u):
                    pieces[i] = u.simplify(0.0)
                    pieces.pop(j)
                    merged = True
                    break
            if merged:
                break
    return pieces


def wall_pieces(boundary: Polygon, thickness: float = WALL_THICKNESS) -> list[Polygon]:
    """Convex wall slabs along every edge of the outer boundary, on its outer side.

    Each slab's inner side is its edge and it is ``thickness`` deep. At a convex corner both
    slabs run on by ``thickness`` past the corner (that extension lies outside the room), so
    the corner is sealed; at a reflex corner (non-convex rooms) both end on the corner's
    bisector (a mitre), since a square end would cut into the room across the other edge.
    Works for either winding.

    Parameters
    ----------
    boundary : Polygon   the outer wall polygon W [m]
    thickness : float    wall thickness [m]

    Returns
    -------
    list of Polygon, one convex quadrilateral per edge [m]
    """
    pts = np.asarray(orient(boundary, 1.0).exterior.coords)[:-1]   # CCW: inside on the left
    n = len(pts)
    t = float(thickness)
    units, normals = [], []
    for i in range(n):
        e = pts[(i + 1) % n] - pts[i]
        u = e / np.hypot(*e)
        units.append(u)
        normals.append(np.array([u[1], -u[0]]))                 # right of the edge = outside

    def convex_at(k: int) -> bool:
        u0, u1 = units[k - 1], units[k]
        return float(u0[0] * u1[1] - u0[1] * u1[0]) > 0

    def mitre(k: int) -> np.ndarray:
        """Outward offset of vertex k [m] where the two offset edges meet."""
        n1, n2 = normals[k - 1], normals[k]
        return pts[k] + t * (n1 + n2) / (1.0 + float(n1 @ n2))

    pieces = []
    for i in range(n):
        j = (i + 1) % n
        a, b, u, nn = pts[i], pts[j], units[i], normals[i]
        if convex_at(i):
            a0 = a - t * u
            ring = [a0, a0 + t * nn]
        else:
            ring = [a, mitre(i)]
        if convex_at(j):
            b0 = b + t * u
            ring = [ring[0], b0, b0 + t * nn, ring[1]]
        else:
            ring = [ring[0], b, mitre(j), ring[1]]
        pieces.append(Polygon(ring))
    return pieces
