"""The C-space boundary cut into contact bins (docs/model.md §5): shared by the event
coverage model (:mod:`planners.coverage.event`) and the exact navigation planner
(:mod:`planners.navigation.exact`), which both name a contact point by its bin.

Each ring of ``env.cspace`` (the free space eroded by the robot's radius; exterior and holes)
is cut into equal bins by arc length; a point goes to the bin of its nearest ring point.

Examples
--------
A 1 m × 1 m room with r = 0.1: the C-space is the square [0.1, 0.9]², a ring of 3.2 m, cut
into 0.1 m bins; the point (0.5, 0.1) lies 0.4 m along the ring from its first vertex:

>>> from envs import Environment
>>> env = Environment.from_dict({"boundary": [[0, 0], [1, 0], [1, 1], [0, 1]],
...     "robot_radius": 0.1, "discretization": {"cell_size": 0.25, "orientations": 4}})
>>> bd = Boundary(env, 0.1)
>>> bd.n_bins, float(bd.ring_length[0].round(9))
(32, 3.2)
>>> int(bd.bin_of([[0.5, 0.1]])[0]) == int(bd.bin_of([[0.55, 0.1]])[0])
True
"""

from __future__ import annotations

import math

import numba
import numpy as np
import shapely
from shapely.geometry.polygon import orient

from envs import UserError
from envs.motion import CONTACT_GAP

__all__ = ["Boundary", "bins_estimate"]

_SNAP = 2e-3             # [m] a landing point must lie this close to the C-space ring
_NUDGE = CONTACT_GAP    # [m] flight starts sit this far off the ring, on the free side


class Boundary:
    """The C-space boundary (``env.cspace`` rings) cut into contact bins by arc length.

    Parameters
    ----------
    env : Environment
    bin_length : float   target bin length [m]

    Attributes
    ----------
    n_bins : int
    ring_of_bin : (n_bins,) int        ring of every bin
    ring_length, ring_bin_length : (R,) [m]
    ring_first_bin, ring_bins : (R,) int

    Notes
    -----
    ``env.cspace`` is E eroded by the radius with rounded corners approximated by 32
    segments per quarter circle, so the rings deviate from the exact contact set by at most
    r (1 − cos(π/128)) ≈ 5e-5 m at r = 0.17 m; they are used only to *name* contact points
    (binning) and to place flight start points. Projection: every point goes to its nearest
    ring segment among the candidates of a fine grid cell (candidates = segments within
    ``fine``·√½ + 2 mm of the cell centre).
    """

    def __init__(self, env, bin_length: float) -> None:
        rings = []
        part = []
        for poly in shapely.get_parts(env.cspace):
            if poly.is_empty:
                continue
            poly = orient(poly, sign=1.0)        # free side on the left of every ring
            rings.append(np.asarray(poly.exterior.coords))
            rings.extend(np.asarray(i.coords) for i in poly.interiors)
            part.extend([len(set(part))] * (1 + len(poly.interiors)))
        if not rings:
            raise UserError(f"{env.name} has no free C-space for the robot.")
        A, B, rid, s0 = [], [], [], []
        lengths = []
        for r_i, c in enumerate(rings):
            d = np.hypot(*(c[1:] - c[:-1]).T)
            keep = d > 0
            a, b, d = c[:-1][keep], c[1:][keep], d[keep]
            A.append(a)
            B.append(b)
            rid.append(np.full(len(a), r_i))
            s0.append(np.concatenate([[0.0], np.cumsum(d)[:-1]]))
            lengths.append(float(d.sum()))
        self.A = np.concatenate(A)
        self.B = np.concatenate(B)
        self.seg_ring = np.concatenate(rid)
        self.seg_s0 = np.concatenate(s0)
        self.seg_len = np.hypot(*(self.B - self.A).T)
        e = (self.B - self.A) / self.seg_len[:, None]
        self.seg_inward = np.column_stack([-e[:, 1], e[:, 0]])
        self.ring_length = np.array(lengths)
        self.ring_bins = np.maximum(1, np.ceil(self.ring_length / bin_length - 1e-9)
                                    ).astype(np.int64)
        self.ring_bin_length = self.ring_length / self.ring_bins
        self.ring_first_bin = np.concatenate([[0], np.cumsum(self.ring_bins)[:-1]])
        self.n_bins = int(self.ring_bins.sum())
        self.ring_of_bin = np.repeat(np.arange(len(rings)), self.ring_bins)
        self.part_of_bin = np.asarray(part)[self.ring_of_bin]   # connected part of C-space
        self._ring_seg_first = np.concatenate(
            [[0], np.cumsum(np.bincount(self.seg_ring, minlength=len(rings)))[:-1]])
        self._build_grid(max(min(0.05, env.cell_size / 4), 1e-3))
        self._ab = None

    def _build_grid(self, g: float) -> None:
        lo = np.minimum(self.A, self.B).min(axis=0) - g
        hi = np.maximum(self.A, self.B).max(axis=0) + g
        self.g, self.x0, self.y0 = g, float(lo[0]), float(lo[1])
        self.nx = int(math.ceil((hi[0] - lo[0]) / g))
        self.ny = int(math.ceil((hi[1] - lo[1]) / g))
        jj, ii = np.mgrid[0:self.ny, 0:self.nx]
        cen = np.column_stack([self.x0 + (ii.ravel() + 0.5) * g,
                               self.y0 + (jj.ravel() + 0.5) * g])
        reach = g * math.sqrt(0.5) + _SNAP
        # every segment within reach of a cell's centre (shapely's tree), by cell then segment
        tree = shapely.STRtree(shapely.linestrings(np.stack([self.A, self.B], axis=1)))
        rows, cols = tree.query(shapely.points(cen), predicate="dwithin", distance=reach)
        order = np.lexsort((cols, rows))
        rows, cols = rows[order], cols[order]
        counts = np.bincount(rows, minlength=len(cen))
        k = max(1, int(counts.max()))
        table = np.full((len(cen), k), -1, dtype=np.int64)
        slot = np.arange(rows.size) - np.concatenate([[0], np.cumsum(counts)])[rows]
        table[rows, slot] = cols
        self.candidates = table

    def locate(self, pts) -> tuple[np.ndarray, np.ndarray]:
        """(ring, arc length [m]) of the nearest ring point of each point (n, 2): compiled
        (:func:`_locate_kernel`, the same numbers as :meth:`locate_reference`).
        """
        pts = np.ascontiguousarray(np.asarray(pts, dtype=float).reshape(-1, 2))
        if self._ab is None:
            self._ab = (np.ascontiguousarray(self.A), np.ascontiguousarray(self.B))
        seg, lam = _locate_kernel(pts, self.x0, self.y0, self.g, self.nx, self.ny,
                                  self.candidates, self._ab[0], self._ab[1], self.seg_len,
                                  _SNAP)
        return self.seg_ring[seg], self.seg_s0[seg] + lam * self.seg_len[seg]

    def locate_reference(self, pts) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`locate` in numpy (the reference the kernel is checked against)."""
        pts = np.asarray(pts, dtype=float).reshape(-1, 2)
        i = np.clip(((pts[:, 0] - self.x0) / self.g).astype(np.int64), 0, self.nx - 1)
        j = np.clip(((pts[:, 1] - self.y0) / self.g).astype(np.int64), 0, self.ny - 1)
        cand = self.candidates[j * self.nx + i]                       # (n, k)
        valid = cand >= 0
        c = np.where(valid, cand, 0)
        d = _point_seg_dist(pts[:, None, :], self.A[c], self.B[c])
        d = np.where(valid, d, np.inf)
        best = np.argmin(d, axis=1)
        seg = c[np.arange(len(pts)), best]
        far = d[np.arange(len(pts)), best] > _SNAP
        if far.any():                                            # off the grid's reach
            dd = _point_seg_dist(pts[far][:, None, :], self.A[None], self.B[None])
            seg[far] = np.argmin(dd, axis=1)
        a, b = self.A[seg], self.B[seg]
        e = b - a
        lam = np.clip(((pts - a) * e).sum(1) / (self.seg_len[seg] ** 2), 0.0, 1.0)
        return self.seg_ring[seg], self.seg_s0[seg] + lam * self.seg_len[seg]

    def bin_of(self, pts) -> np.ndarray:
        """Contact bin of each point (n, 2)."""
        ring, s = self.locate(pts)
        local = np.minimum((s / self.ring_bin_length[ring]).astype(np.int64),
                           self.ring_bins[ring] - 1)
        return self.ring_first_bin[ring] + local

    def points(self, bins, frac, return_segment: bool = False):
        """Ring points (n, 2) at fraction ``frac`` ∈ [0, 1] along each bin, moved 1e-9 m
        into the free side (where the twin's robot stops: ``CONTACT_GAP`` short of the
        contact), so that a contact on a cell border is counted in the free cell. With
        ``return_segment`` also the ring segment of each point.
        """
        bins = np.asarray(bins, dtype=np.int64)
        ring = self.ring_of_bin[bins]
        s = (bins - self.ring_first_bin[ring] + np.asarray(frac, dtype=float)) \
            * self.ring_bin_length[ring]
        # segment of each arc length within its ring
        out = np.empty((bins.size, 2))
        seg = np.empty(bins.size, dtype=np.int64)
        for r_i in np.unique(ring):
            m = ring == r_i
            first = self._ring_seg_first[r_i]
            s0 = self.seg_s0[self.seg_ring == r_i]
            k = np.clip(np.searchsorted(s0, s[m], side="right") - 1, 0, s0.size - 1) + first
            lam = np.clip((s[m] - self.seg_s0[k]) / self.seg_len[k], 0.0, 1.0)
            out[m] = self.A[k] + lam[:, None] * (self.B[k] - self.A[k]) \
                + _NUDGE * self.seg_inward[k]
            seg[m] = k
        return (out, seg) if return_segment else out


def _point_seg_dist(p, a, b) -> np.ndarray:
    """Distance between points p and segments ab (broadcast over leading axes)."""
    e = b - a
    ee = (e * e).sum(-1)
    t = np.clip(((p - a) * e).sum(-1) / np.where(ee > 0, ee, 1.0), 0.0, 1.0)
    d = p - (a + t[..., None] * e)
    return np.hypot(d[..., 0], d[..., 1])


@numba.njit(cache=True)
def _seg_dist(px, py, ax, ay, bx, by):
    """:func:`_point_seg_dist` of one point and one segment (the same operations)."""
    ex, ey = bx - ax, by - ay
    ee = ex * ex + ey * ey
    t = ((px - ax) * ex + (py - ay) * ey) / (ee if ee > 0 else 1.0)
    t = min(max(t, 0.0), 1.0)
    return math.hypot(px - (ax + t * ex), py - (ay + t * ey))


@numba.njit(cache=True)
def _locate_kernel(pts, x0, y0, g, nx, ny, candidates, A, B, seg_len, snap):
    """Per point: its nearest segment among its fine cell's candidates (all segments when
    that one is farther than ``snap``; ties: the first) and the fraction along it.
    """
    n, k = pts.shape[0], candidates.shape[1]
    seg = np.empty(n, dtype=np.int64)
    lam = np.empty(n)
    for p in range(n):
        px, py = pts[p, 0], pts[p, 1]
        i = min(max(int((px - x0) / g), 0), nx - 1)
        j = min(max(int((py - y0) / g), 0), ny - 1)
        best, bd = 0, np.inf
        first = True
        for c in range(k):
            s = candidates[j * nx + i, c]
            d = _seg_dist(px, py, A[s, 0], A[s, 1], B[s, 0], B[s, 1]) if s >= 0 else np.inf
            if first or d < bd:
                best, bd, first = (s if s >= 0 else 0), d, False
        if bd > snap:                                    # off the grid's reach
            bd = np.inf
            for s in range(A.shape[0]):
                d = _seg_dist(px, py, A[s, 0], A[s, 1], B[s, 0], B[s, 1])
                if d < bd:
                    best, bd = s, d
        ex, ey = B[best, 0] - A[best, 0], B[best, 1] - A[best, 1]
        t = ((px - A[best, 0]) * ex + (py - A[best, 1]) * ey) / (seg_len[best] ** 2)
        seg[p] = best
        lam[p] = min(max(t, 0.0), 1.0)
    return seg, lam


def bins_estimate(env, bin_length: float) -> int:
    """About how many contact bins :class:`Boundary` cuts ``env``'s C-space into at
    ``bin_length`` [m], from the rings' length alone (nothing built): length / bin length plus
    one per ring, an upper bound for memory estimates.
    """
    ring = env.cspace.boundary
    rings = max(1, len(getattr(ring, "geoms", [ring])))
    return int(math.ceil(ring.length / bin_length)) + rings
