"""The feedback planner's search from one pose (docs/model.md §15, "Planning from a pose"):
§13's search rooted at a particle's pose, with the heading's offset from the Δ grid kept.

Two implementations of the same search, with the same states, the same order of
expansion and the same floating-point arithmetic, so they return the same plans:

- :func:`search`, the one the navigator uses. Per search it tabulates each heading's
  direction terms against every wall side and sorts the walls into strips across each
  heading; per expanded state it casts the flight in one pass over the walls of its strip
  and, in that pass, keeps the walls within ``r + 4·BUMP_RANGE`` of the pose: only those
  can stop a flight within ``BUMP_RANGE``, so the knife-edge guard's two casts (heading
  ± g) run over them alone. What a pose and heading lead to is computed once per search. A
  flight at the goal's heading is cut into chords (the numpy
  :func:`~planners.navigation.exact.chords`) only when it meets the goal cell shrunk by half
  the minimum depth (no arrival is possible otherwise).
- :func:`search_reference`, the straightforward one (every cast over every wall, chords
  whenever the flight's bounding box meets the goal cell): the tests and
  ``benchmarks/bench_feedback.py`` check :func:`search` against it.

With a contact rule (``FeedbackConfig.contact``, docs/model.md §9) both continue a flight
whose contact lies outside the bumper arc along its slide to the bump, as §13's planner does
(:func:`envs.contact.slide_on`): the flight costs and expects its clock length and lands at
the bump; goal arrivals stay on the straight part.

Both return ``(angles, flights, final_m, cost)`` tuples, cheapest first, which
:class:`planners.navigation.feedback.FeedbackNavigator` turns into candidates. :func:`search` with a
``guide`` (:func:`cost_to_go`) is the guided search of §15, a different rule (off by
default): it returns plans that need not be the cheapest.
"""

from __future__ import annotations

import heapq
import math
from itertools import compress

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra

from envs.contact import slide_on
from envs.motion import (
    APPROACH_MIN,
    BUMP_RANGE,
    GRAZE_TOL,
    cast_scalar,
    drive_distance,
    unit,
)

from ..exact import chords

__all__ = ["MAX_SETTLED_GUIDED", "NEAR_M", "BAND_PAD_M", "STRIP_M", "UNGUIDED",
           "ScalarWalls", "cost_to_go", "grazes", "search", "search_reference"]

MAX_SETTLED_GUIDED = 500
"""... and a guided search after this many (a guided search that finds a plan settles a
median of 17 states, 95 % of them fewer than 250: the rest are poses without a plan)."""
NEAR_M = 4 * BUMP_RANGE
"""[m] walls farther than r + this from a pose cannot stop a flight within BUMP_RANGE
(a side at distance s needs (s − r)/a with approach rate a <= 1; a corner at distance ρ
needs at least ρ − r of travel)."""
STRIP_M = 0.1
"""[m] width of the strips across a heading that :meth:`ScalarWalls.bands` sorts walls by."""
UNGUIDED = 1e4
"""Added to the distance bound of a state the guide cannot bring to the goal."""
BAND_PAD_M = 1e-5
"""[m] slack of the strips of :meth:`ScalarWalls.bands` beyond r (rounding, and NEAR_M)."""


class ScalarWalls:
    """A wall caster's sides (Ax, Ay, ex, ey, L) and corners (Vx, Vy) as Python floats,
    with its radius terms, for casts one pose at a time (the formulas of
    :meth:`envs.motion.WallCaster.cast_one`, so the same numbers to the bit).
    """

    def __init__(self, caster) -> None:
        self.sides = [tuple(float(v) for v in row)
                      for row in np.column_stack([caster.A, caster.e, caster.L]).tolist()]
        self.verts = [(float(x), float(y)) for x, y in np.asarray(caster.vertices).tolist()]
        self.r = float(caster.r)
        self.r2 = self.r * self.r
        self.graze = self.r * self.r - (self.r - GRAZE_TOL) ** 2
        self._ends = np.stack([caster.A, caster.A + caster.e * caster.L[:, None]])  # (2, S, 2)
        self._v = np.asarray(caster.vertices, dtype=float).reshape(-1, 2)

    def directions(self, units) -> list:
        """Per unit heading (ux, uy): every side with its terms u×e and u·e."""
        return [[(ax, ay, ex, ey, L, uy * ex - ux * ey, ux * ex + uy * ey)
                 for ax, ay, ex, ey, L in self.sides] for ux, uy in units]

    def bands(self, units, dsides, width: float, extra: float = 0.0):
        """A lookup ``(k, x, y) -> (sides, corners)``: the walls a disk at (x, y) flying along
        ``units[k]`` can touch, a superset found by strips of ``width`` [m] across each
        heading (a wall belongs to a strip when its offset across the heading comes within
        r + BAND_PAD_M + ``extra`` of it); with ``dsides[k]``'s direction terms. Every wall
        within r + NEAR_M of (x, y) is among them, and with ``extra`` every wall that passes
        within r + ``extra`` of the flight's line.
        """
        U = np.asarray(units, dtype=float).reshape(-1, 2)
        pad = self.r + BAND_PAD_M + extra

        def across(q):             # offset across each heading: u × q, shape (K, n)
            return U[:, :1] * q[None, :, 1] - U[:, 1:] * q[None, :, 0]

        a, b = across(self._ends[0]), across(self._ends[1])
        sv = across(self._v)
        lo = np.concatenate([np.minimum(a, b), sv], axis=1) - pad     # (K, S + V)
        hi = np.concatenate([np.maximum(a, b), sv], axis=1) + pad
        j0 = math.floor(float(lo.min()) / width)
        n = math.floor(float(hi.max()) / width) - j0 + 1
        edge = (j0 + np.arange(n + 1)) * width
        on = ((lo[:, None, :] <= edge[None, 1:, None]) &
              (hi[:, None, :] >= edge[None, :-1, None]))                # (K, n, S + V)
        ns, verts = len(self.sides), self.verts
        every = [(ds, verts) for ds in dsides]
        table: dict = {}

        def lookup(k: int, x: float, y: float):
            ux, uy = units[k]
            j = math.floor((ux * y - uy * x) / width) - j0
            got = table.get((k, j))
            if got is None:
                if not 0 <= j < n:
                    return every[k]
                row = on[k, j].tolist()
                got = table[k, j] = (list(compress(dsides[k], row[:ns])),
                                     list(compress(verts, row[ns:])))
            return got

        return lookup

    def cast_near(self, x: float, y: float, ux: float, uy: float, dsides, verts, near: bool):
        """(contact distance [m], near sides, near corners, cos b): the cast along (ux, uy)
        over the sides ``dsides`` (with their :meth:`directions` terms for this heading) and
        the corners ``verts``; with ``near``, those within r + NEAR_M of (x, y) (else empty);
        cos b of the contact's bearing b on the first feature met (1 when none): a contact
        with cos b >= sin β lies inside the bumper arc of a contact rule (§9).
        """
        r, lim = self.r, self.r + NEAR_M
        best, ns, nv, cos_b = math.inf, [], [], 1.0
        for ax, ay, ex, ey, L, un, ue in dsides:
            rx = x - ax
            ry = y - ay
            s0 = ry * ex - rx * ey
            if near and abs(s0) <= lim:
                ns.append((ax, ay, ex, ey, L))
            a = -un if s0 >= 0 else un
            if not a > APPROACH_MIN:
                continue
            t = (abs(s0) - r) / a
            if t < 0.0:
                t = 0.0
            if t < best and 0.0 <= rx * ex + ry * ey + t * ue <= L:
                best, cos_b = t, a
        r2, graze, lim2 = self.r2, self.graze, lim * lim
        for vx0, vy0 in verts:
            vx = x - vx0
            vy = y - vy0
            q = vx * vx + vy * vy
            if near and q <= lim2:
                nv.append((vx0, vy0))
            b = vx * ux + vy * uy
            if not b < 0.0:
                continue
            disc = r2 - (q - b * b)
            if not disc > graze:
                continue
            root = math.sqrt(disc)
            t = -b - root
            if t < 0.0:
                t = 0.0
            if t < best:
                best, cos_b = t, root / r
        return best, ns, nv, cos_b


def grazes(px: float, py: float, ux: float, uy: float, D: float, verts, r: float,
           clearance: float, spread_rad: float) -> bool:
    """Whether the flight of a disk of radius ``r`` from (px, py) along (ux, uy) for ``D``
    [m] passes a wall corner of ``verts`` closer than its clearance without touching it: a
    corner beside the flight at distance s along it needs r + ``clearance`` +
    s·tan(``spread_rad``) [m] across it (a heading off by the declared spread would touch
    it). Corners the disk touches (its bump) and those behind or beyond it do not count.
    """
    slope = math.tan(spread_rad)
    for vx, vy in verts:
        wx, wy = vx - px, vy - py
        s = wx * ux + wy * uy
        if not 0.0 < s < D:
            continue
        gap = abs(wx * uy - wy * ux) - r
        if GRAZE_TOL < gap < clearance + s * slope:
            return True
    return False


def _meets(px, py, ux, uy, D, x0, y0, x1, y1) -> bool:
    """Whether the segment from (px, py) along (ux, uy) for D [m] meets the box (slab test,
    1e-9 m of slack).
    """
    lo, hi = 0.0, D
    for p, u, a, b in ((px, ux, x0, x1), (py, uy, y0, y1)):
        if u == 0.0:
            if p < a - 1e-9 or p > b + 1e-9:
                return False
            continue
        t0, t1 = (a - p) / u, (b - p) / u
        if t0 > t1:
            t0, t1 = t1, t0
        lo, hi = max(lo, t0), min(hi, t1)
    return lo <= hi + 1e-9


def _setup(fnav, heading_deg: float):
    cs, cfg = fnav.cells, fnav.cfg
    K, dlt = cs.K, cs.delta_deg
    k0 = int(round(heading_deg / dlt))
    eps = float(heading_deg) - k0 * dlt
    guard = cfg.edge_guard * cfg.turn_spread_deg
    units, plus, minus = ([tuple(float(v) for v in u) for u in unit(np.arange(K) * dlt + eps + g)]
                          for g in (0.0, guard, -guard))
    return k0 % K, units, plus, minus, guard


def _unwind(arrivals, best: float, slack: float) -> list:
    out: dict = {}
    for cost, _, node, final in sorted(arrivals):
        if cost > best + slack:
            break
        angles, flights = [], []
        while node is not None:
            node, ang, fl = node
            angles.append(ang)
            flights.append(fl)
        key = tuple(reversed(angles))
        if key not in out:
            out[key] = (key, tuple(reversed(flights)), float(final), cost)
    return list(out.values())


def search(fnav, x: float, y: float, heading_deg: float, slack: float,
           bumped: bool = False, guide=None) -> list[tuple]:
    """Plans from the pose (x [m], y [m], heading [deg]) to ``fnav``'s goal: every goal
    arrival within ``slack`` of the cheapest, distinct angle sequences only, cheapest first,
    as (angles, flights, final_m, cost). ``bumped``: the first flight is 0. Same result as
    :func:`search_reference`; what a pose and heading lead to (the flight, the guard, the
    landing bin, the goal chords) is computed once per search.

    ``guide`` (nested lists [bin][k][angle] of :func:`cost_to_go`): the states are taken in
    the order of their cost plus the guide's cost to go (plus ``UNGUIDED`` where it is
    infinite) instead of §13's distance bound: few states are settled, and the first
    arrivals found end the search (not necessarily the cheapest plan).
    """
    cs, nav = fnav.cells, fnav.nav
    K, m, h = cs.K, nav.m, cs.h
    k0, units, plus, minus, guard = _setup(fnav, heading_deg)
    walls = fnav.walls
    dirs = walls.directions(units)
    near_walls = walls.bands(units, dirs, STRIP_M)
    cast_near = walls.cast_near
    clear_m, clear_rad = fnav.cfg.clearance_m, math.radians(fnav.cfg.turn_spread_deg)
    x0, y0, x1, y1 = cs.env.bounds            # no flight is longer than the diagonal
    reach = clear_m + math.hypot(x1 - x0, y1 - y0) * math.tan(clear_rad)
    beside = walls.bands(units, dirs, STRIP_M, reach) if clear_m > 0 or clear_rad > 0 \
        else None
    r, r2, graze = walls.r, walls.r2, walls.graze

    def cast_some(px, py, ux, uy, sides, verts):      # the motion layer's scalar cast
        return cast_scalar(sides, verts, r, r2, graze, px, py, ux, uy)
    w1, w2 = nav.w1, nav.w2
    first_bump = w1 if m == 1 else min(w1, w2)
    steps = nav.steps.tolist()
    gx0, gy0, gx1, gy1 = fnav.box
    half = nav.min_depth / 2
    sx0, sy0, sx1, sy1 = gx0 + half, gy0 + half, gx1 - half, gy1 - half
    gk, gp = fnav.gk, int(cs.pk(fnav.goal)[0])
    bin_of, angles, min_depth = nav.bin_of_point, nav.angles, nav.min_depth
    hyp, k_h = math.hypot, w1 / h
    contact, caster = fnav.cfg.contact, nav.caster
    # a first contact with cos b above this closes the bumper: no slide (the margin keeps
    # the test conservative, so the slides are those of the reference search)
    sin_beta = -1.0 if contact is None else math.sin(math.radians(contact.beta_deg)) + 1e-6
    memo: dict = {}

    def expand(px: float, py: float, k: int, first: bool):
        """(D, blocked, lx, ly, landing bin, bound there, goal arrivals' t) of a flight."""
        ux, uy = units[k]
        if first and bumped:
            t, ns, nv, cos_b = 0.0, (), (), 1.0
        else:
            t, ns, nv, cos_b = cast_near(px, py, ux, uy, *near_walls(k, px, py),
                                         bool(guard) and not first)
        if math.isinf(t):
            return None
        D = 0.0 if t <= BUMP_RANGE else drive_distance(t)
        if guard and not first and D > 1e-3 and (ns or nv) and (
                cast_some(px, py, *plus[k], ns, nv) <= BUMP_RANGE or
                cast_some(px, py, *minus[k], ns, nv) <= BUMP_RANGE):
            return D, True, 0.0, 0.0, 0, 0.0, ()      # along a wall it touches: a knife edge
        if beside is not None and not first and \
                grazes(px, py, ux, uy, D, beside(k, px, py)[1], r, clear_m, clear_rad):
            return D, True, 0.0, 0.0, 0, 0.0, ()      # passes a corner with too little room
        lx, ly = px + D * ux, py + D * uy
        goal_t = ()
        if k == gk and min(px, lx) <= gx1 and max(px, lx) >= gx0 and \
                min(py, ly) <= gy1 and max(py, ly) >= gy0 and \
                _meets(px, py, ux, uy, D, sx0, sy0, sx1, sy1):
            _, p, tt, depth = chords(cs, [[px, py]], [[ux, uy]], [D])
            goal_t = tuple(ti for pi, ti, di in zip(p.tolist(), tt.tolist(), depth.tolist())
                           if pi == gp and di >= min_depth)
        if cos_b < sin_beta and not (first and bumped):     # a glancing contact slides on
            lx, ly, extra = slide_on(caster, contact, lx, ly, ux, uy)
            D += extra
        hb = k_h * hyp(max(gx0 - lx, lx - gx1, 0.0), max(gy0 - ly, ly - gy1, 0.0))
        return D, False, lx, ly, bin_of(lx, ly), hb, goal_t

    heap = [(0.0, 0, None, 0.0, float(x), float(y), k0, -1, None)]
    settled, order, best, arrivals = set(), 1, math.inf, []
    cap = fnav.cfg.max_settled if guide is None else MAX_SETTLED_GUIDED
    while heap and len(settled) < cap:
        key, _, st, c, px, py, k, a, node = heapq.heappop(heap)
        if st in settled:
            continue
        if key > best + slack:
            break
        settled.add(st)
        mk = (px, py, k)
        out = memo.get(mk) if st is not None else None
        if out is None:
            out = expand(px, py, k, st is None)
            if out is None:
                return []
            if st is not None:
                memo[mk] = out
        D, blocked, lx, ly, lb, hb, goal_t = out
        if blocked:
            continue
        for ti in goal_t:
            arrivals.append((c + w1 * ti / h, len(arrivals), node, ti))
            best = min(best, c + w1 * ti / h)
        cD = c + w1 * D / h
        gl = None if guide is None else guide[lb]
        for b in range(m):
            k2 = (k + steps[b]) % K
            tgt = (lb, k2, b)
            if tgt in settled:
                continue
            c2 = cD + (first_bump if a < 0 else (w1 if a == b else w2))
            hk = hb if gl is None else gl[k2][b]
            if hk == math.inf:
                hk = hb + UNGUIDED
            heapq.heappush(heap, (c2 + hk, order, tgt, c2, lx, ly, k2, b, (node, angles[b], D)))
            order += 1
    return _unwind(arrivals, best, slack)


def search_reference(fnav, x: float, y: float, heading_deg: float, slack: float,
                     bumped: bool = False) -> list[tuple]:
    """:func:`search` written plainly: every cast (the flight, and the guard's two) over all
    walls with :meth:`~envs.motion.WallCaster.cast_one`, chords whenever the flight's
    bounding box meets the goal cell.
    """
    cs, nav = fnav.cells, fnav.nav
    K, m, h = cs.K, nav.m, cs.h
    k0, units, plus, minus, guard = _setup(fnav, heading_deg)
    w1, w2 = nav.w1, nav.w2
    first_bump = w1 if m == 1 else min(w1, w2)
    steps = nav.steps.tolist()
    gx0, gy0, gx1, gy1 = fnav.box
    gk, gp = fnav.gk, int(cs.pk(fnav.goal)[0])
    cast, bin_of = nav.caster.cast_one, nav.bin_of_point

    def bound(px: float, py: float) -> float:
        return w1 / h * math.hypot(max(gx0 - px, px - gx1, 0.0), max(gy0 - py, py - gy1, 0.0))

    # heap: (key, order, state, cost, x, y, k, angle index, node),
    # node = (parent node, angle, flight)
    heap = [(0.0, 0, None, 0.0, float(x), float(y), k0, -1, None)]
    settled, order, best, arrivals = set(), 1, math.inf, []
    while heap and len(settled) < fnav.cfg.max_settled:
        key, _, st, c, px, py, k, a, node = heapq.heappop(heap)
        if st in settled:
            continue
        if key > best + slack:
            break
        settled.add(st)
        ux, uy = units[k]
        t = 0.0 if (bumped and st is None) else cast(px, py, ux, uy)
        if math.isinf(t):
            return []
        D = 0.0 if t <= BUMP_RANGE else drive_distance(t)
        if guard and st is not None and D > 1e-3 and (
                cast(px, py, *plus[k]) <= BUMP_RANGE or
                cast(px, py, *minus[k]) <= BUMP_RANGE):
            continue                       # along a wall it touches: a knife edge
        if st is not None and grazes(px, py, ux, uy, D, fnav.walls.verts, fnav.walls.r,
                                     fnav.cfg.clearance_m,
                                     math.radians(fnav.cfg.turn_spread_deg)):
            continue                       # passes a corner with too little room
        if k == gk and min(px, px + D * ux) <= gx1 and max(px, px + D * ux) >= gx0 and \
                min(py, py + D * uy) <= gy1 and max(py, py + D * uy) >= gy0:
            _, p, tt, depth = chords(cs, [[px, py]], [[ux, uy]], [D])
            for pi, ti, di in zip(p.tolist(), tt.tolist(), depth.tolist()):
                if pi == gp and di >= nav.min_depth:
                    arrivals.append((c + w1 * ti / h, len(arrivals), node, ti))
                    best = min(best, c + w1 * ti / h)
        lx, ly = px + D * ux, py + D * uy
        if nav.contact is not None and not (bumped and st is None):
            lx, ly, extra = slide_on(nav.caster, nav.contact, lx, ly, ux, uy)
            D += extra
        lb = bin_of(lx, ly)
        hb = bound(lx, ly)
        for b in range(m):
            k2 = (k + steps[b]) % K
            tgt = (lb, k2, b)
            if tgt in settled:
                continue
            c2 = c + w1 * D / h + (first_bump if a < 0 else (w1 if a == b else w2))
            heapq.heappush(heap, (c2 + hb, order, tgt, c2, lx, ly, k2, b,
                                  (node, nav.angles[b], D)))
            order += 1
    return _unwind(arrivals, best, slack)


def cost_to_go(fnav, fracs=(0.25, 0.75)) -> np.ndarray:
    """(bins, K, m) §13's cost from each contact state (bin, heading k, last angle) to the
    goal on the grid headings (ε = 0), every state flown from points of its bin (at
    ``fracs`` of its length; the cheaper counts); inf where the goal is not reached.

    Solved backwards on the state graph of these flights (scipy's Dijkstra): the search's
    guide (:func:`search` with ``guide``).
    """
    cs, nav = fnav.cells, fnav.nav
    bd, K, m, h = nav.boundary, cs.K, nav.m, cs.h
    nb, w1, w2 = bd.n_bins, nav.w1, nav.w2
    steps = nav.steps
    gk, gp = fnav.gk, int(cs.pk(fnav.goal)[0])
    S = nb * K * m
    best = np.full((nb, K, m), np.inf)
    for frac in fracs:
        P = bd.points(np.arange(nb), np.full(nb, frac))
        rows, cols, wts = [], [], []
        for k in range(K):
            u = np.broadcast_to(cs.units[k], P.shape)
            t = nav.caster.cast(P, u)
            t = np.where(np.isfinite(t), t, 0.0)
            D = np.where(t <= BUMP_RANGE, 0.0, drive_distance(t))
            lb = bd.bin_of(P + D[:, None] * u)
            for a in range(m):                  # state (bin, k, a) -> (lb, k + step, b)
                src = (np.arange(nb) * K + k) * m + a
                for b in range(m):
                    k2 = (k + int(steps[b])) % K
                    rows.append(src)
                    cols.append((lb * K + k2) * m + b)
                    wts.append(w1 * D / h + (w1 if a == b else w2))
            if k == gk:
                fi, p, tt, depth = chords(cs, P, u, D)
                ok = (p == gp) & (depth >= nav.min_depth)
                arr = np.full(nb, np.inf)
                np.minimum.at(arr, fi[ok], w1 * tt[ok] / h)
                for a in range(m):
                    hit = np.isfinite(arr)
                    rows.append((np.flatnonzero(hit) * K + k) * m + a)
                    cols.append(np.full(hit.sum(), S))
                    wts.append(arr[hit] + 1e-9)         # > 0: sparse graphs drop zeros
        g = coo_matrix((np.concatenate(wts), (np.concatenate(rows), np.concatenate(cols))),
                       shape=(S + 1, S + 1)).tocsr()
        dist = dijkstra(g.T, directed=True, indices=S)
        best = np.minimum(best, dist[:S].reshape(nb, K, m))
    return best
