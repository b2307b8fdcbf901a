"""The C-space boundary cut into contact bins (docs/model.md §5): shared by the event
coverage model (:mod:`planners.coverage.event`) and the exact navigation planner
(:mod:`planners.navigation.exact`), which both name a contact point by its bin.

Each ring of ``env.cspace`` (the free space eroded by the robot's radius; exterior and holes)
is cut into equal bins by arc length; a point goes to the bin of its nearest ring point. With
``corners=True`` (the event model) every concave corner of the walls, a sharp left turn of a
ring, is a bin of its own: a point within ``GRAZE_TOL`` of the corner goes to it, and its
point is the corner itself (``CONTACT_GAP`` off both walls), where a robot that flew along one
wall into the corner stops.

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

With corner bins, its four corners are bins 32-35; the corner (0.1, 0.1) is one of them:

>>> bc = Boundary(env, 0.1, corners=True)
>>> bc.n_bins, bc.n_corners, int(bc.bin_of([[0.1 + 1e-9, 0.1 + 1e-9]])[0]) >= 32
(36, 4, True)
"""

from __future__ import annotations

import math

import numba
import numpy as np
import shapely
from scipy.spatial import cKDTree
from shapely.geometry.polygon import orient

from envs import UserError
from envs.motion import CONTACT_GAP, GRAZE_TOL

__all__ = ["Boundary", "bins_estimate"]

_SNAP = 2e-3             # [m] a landing point must lie this close to the C-space ring
_NUDGE = CONTACT_GAP    # [m] flight starts sit this far off the ring, on the free side
_CORNER_TURN = 0.03     # sin of the smallest left turn of a ring that is a corner (1.72°);
#                         cusps (turns of ~180°, the ends of zero-width spikes) are not corners
_SHORT = 1e-9           # [m] ring segments shorter than this belong to the vertex they sit at


class Boundary:
    """The C-space boundary (``env.cspace`` rings) cut into contact bins by arc length.

    Parameters
    ----------
    env : Environment
    bin_length : float   target bin length [m]
    corners : bool       a bin of its own for every concave corner (docs/model.md §5)

    Attributes
    ----------
    n_bins : int                       ring bins, then the corner bins
    n_ring_bins, n_corners : int
    ring_of_bin : (n_bins,) int        ring of every bin
    ring_length, ring_bin_length : (R,) [m]
    ring_first_bin, ring_bins : (R,) int
    corner_of_bin : (n_bins,) int      corner of a corner bin (bin n_ring_bins + c), else -1
    corner_vertex, corner_point : (n_corners, 2) [m]
        the ring's vertex, and the point at ``CONTACT_GAP`` from both walls (flight starts)
    corner_seg : (n_corners, 2) int    the ring segments that meet there (in, out)

    Notes
    -----
    ``env.cspace`` is E eroded by the radius with rounded corners approximated by 32
    segments per quarter circle, so the rings deviate from the exact contact set by at most
    r (1 − cos(π/128)) ≈ 5e-5 m at r = 0.17 m; they are used only to *name* contact points
    (binning) and to place flight start points. Projection: every point goes to its nearest
    ring segment among the candidates of a fine grid cell (candidates = segments within
    ``fine``·√½ + 2 mm of the cell centre).
    """

    def __init__(self, env, bin_length: float, corners: bool = False) -> None:
        rings, part = _rings(env)
        if not rings:
            raise UserError(f"{env.name} has no free C-space for the robot.")
        self.A, self.B, self.seg_ring, self.seg_s0, lengths = _segments(rings)
        self.seg_len = np.hypot(*(self.B - self.A).T)
        e = (self.B - self.A) / self.seg_len[:, None]
        self.seg_inward = np.column_stack([-e[:, 1], e[:, 0]])
        self.ring_length = np.array(lengths)
        self.ring_bins = np.maximum(1, np.ceil(self.ring_length / bin_length - 1e-9)
                                    ).astype(np.int64)
        self.ring_bin_length = self.ring_length / self.ring_bins
        self.ring_first_bin = np.concatenate([[0], np.cumsum(self.ring_bins)[:-1]])
        self.n_ring_bins = int(self.ring_bins.sum())
        seg_in, seg_out = (_ring_corners(env, self.A, self.B, self.seg_ring, self.seg_len)
                           if corners else (np.zeros(0, np.int64),) * 2)
        self.n_corners = int(seg_in.size)
        self.n_bins = self.n_ring_bins + self.n_corners
        self.corner_seg = np.column_stack([seg_in, seg_out])
        self.corner_vertex = self.B[seg_in].reshape(-1, 2)
        n1, n2 = self.seg_inward[seg_in], self.seg_inward[seg_out]
        # the point CONTACT_GAP off both walls: (p − V)·n1 = (p − V)·n2 = gap
        self.corner_point = self.corner_vertex + _NUDGE * (n1 + n2) \
            / (1.0 + (n1 * n2).sum(axis=1))[:, None]
        self.corner_of_bin = np.concatenate([np.full(self.n_ring_bins, -1),
                                             np.arange(self.n_corners)])
        self.ring_of_bin = np.concatenate([np.repeat(np.arange(len(rings)), self.ring_bins),
                                           self.seg_ring[seg_in]])
        self._corner_tree = cKDTree(self.corner_vertex) if self.n_corners else None
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
        """Contact bin of each point (n, 2): its corner's when it lies within ``GRAZE_TOL`` of
        a corner (with corner bins), else the ring bin of its nearest ring point.
        """
        ring, s = self.locate(pts)
        local = np.minimum((s / self.ring_bin_length[ring]).astype(np.int64),
                           self.ring_bins[ring] - 1)
        out = self.ring_first_bin[ring] + local
        if self._corner_tree is not None:
            d, c = self._corner_tree.query(np.asarray(pts, dtype=float).reshape(-1, 2),
                                           distance_upper_bound=GRAZE_TOL)
            near = np.isfinite(d)
            out[near] = self.n_ring_bins + c[near]
        return out

    def points(self, bins, frac, return_segment: bool = False):
        """Ring points (n, 2) at fraction ``frac`` ∈ [0, 1] along each bin, moved 1e-9 m
        into the free side (where the twin's robot stops: ``CONTACT_GAP`` short of the
        contact), so that a contact on a cell border is counted in the free cell; a corner
        bin's point is its ``corner_point`` whatever ``frac``. With ``return_segment`` also
        the ring segment of each point (a corner's: the segment that ends there).
        """
        bins = np.asarray(bins, dtype=np.int64).reshape(-1)
        ring = self.ring_of_bin[bins]
        s = (bins - self.ring_first_bin[ring]
             + np.broadcast_to(np.asarray(frac, dtype=float), bins.shape)) \
            * self.ring_bin_length[ring]
        # segment of each arc length within its ring
        out = np.empty((bins.size, 2))
        seg = np.empty(bins.size, dtype=np.int64)
        corner = self.corner_of_bin[bins]
        at = corner >= 0
        out[at] = self.corner_point[corner[at]]
        seg[at] = self.corner_seg[corner[at], 0]
        for r_i in np.unique(ring[~at]):
            m = (ring == r_i) & ~at
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


def bins_estimate(env, bin_length: float, corners: bool = False) -> int:
    """About how many contact bins :class:`Boundary` cuts ``env``'s C-space into at
    ``bin_length`` [m], from the rings' length alone (nothing built): length / bin length plus
    one per ring, an upper bound for memory estimates; with ``corners`` also the corner bins
    (found on the rings, as :class:`Boundary` finds them).
    """
    ring = env.cspace.boundary
    rings = max(1, len(getattr(ring, "geoms", [ring])))
    extra = 0
    if corners:
        A, B, seg_ring, _, _ = _segments(_rings(env)[0])
        extra = _ring_corners(env, A, B, seg_ring, np.hypot(*(B - A).T))[0].size
    return int(math.ceil(ring.length / bin_length)) + rings + extra


def _rings(env) -> tuple[list, list]:
    """The rings of ``env.cspace`` (coordinate arrays, free side on the left; shapely's order:
    each polygon's exterior, then its interiors) and the connected part of each.
    """
    rings, part = [], []
    for poly in shapely.get_parts(env.cspace):
        if poly.is_empty:
            continue
        poly = orient(poly, sign=1.0)        # free side on the left of every ring
        rings.append(np.asarray(poly.exterior.coords))
        rings.extend(np.asarray(i.coords) for i in poly.interiors)
        part.extend([len(set(part))] * (1 + len(poly.interiors)))
    return rings, part


def _segments(rings) -> tuple:
    """(first ends A, second ends B, ring, start length, ring lengths) of the rings' segments
    of non-zero length, numbered ring by ring.
    """
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
    return np.concatenate(A), np.concatenate(B), np.concatenate(rid), np.concatenate(s0), lengths


def _ring_corners(env, A, B, seg_ring, seg_len) -> tuple[np.ndarray, np.ndarray]:
    """The concave corners of the rings: (segment in, segment out) of every vertex at which
    its ring turns left (towards its free side) by more than asin(``_CORNER_TURN``) and less
    than 180° − that, and at least one of the two segments is straight (a wall side moved by
    r, not a chord of a rounded corner: its midpoint lies r from the walls, a chord's up to
    r (1 − cos(π/128)) closer); segments shorter than ``_SHORT`` are skipped (part of the
    vertex). Rounded corners turn right, so their chords meet no corner of their own; a cusp
    (a turn of ~180°) is not one, nor is the meeting point of two rounded corners (a robot
    reaches it only when aimed at it exactly, e.g. the ends of a door one robot wide).
    """
    e = (B - A) / np.where(seg_len > 0, seg_len, 1.0)[:, None]
    mid = shapely.points(0.5 * (A + B))
    straight = shapely.distance(mid, env.free_space.boundary) >= env.robot_radius - GRAZE_TOL
    ins, outs = [], []
    lo = math.asin(_CORNER_TURN)
    for r_i in np.unique(seg_ring):
        idx = np.flatnonzero((seg_ring == r_i) & (seg_len >= _SHORT))
        if idx.size < 2:
            continue
        nxt = np.roll(idx, -1)
        cross = e[idx, 0] * e[nxt, 1] - e[idx, 1] * e[nxt, 0]
        dot = (e[idx] * e[nxt]).sum(axis=1)
        turn = np.arctan2(cross, dot)
        keep = (turn > lo) & (turn < math.pi - lo) & (straight[idx] | straight[nxt])
        ins.append(idx[keep])
        outs.append(nxt[keep])
    if not ins:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    return np.concatenate(ins).astype(np.int64), np.concatenate(outs).astype(np.int64)
