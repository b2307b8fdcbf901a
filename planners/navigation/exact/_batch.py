"""The exact planner's search from many starts at once (docs/model.md §13, all pairs).

Every tree of :meth:`planners.navigation.exact.ExactNavigator.search` keeps, per state, the
exact pose of its best arrival; the flight from that pose depends on the pose and the heading only,
not on the start. On ``complex`` the 1464 starts settle 6.0 M states but only 0.34 M
distinct (pose, heading) pairs, so the flights are cast once, in a table shared by every
tree (and by every batch of starts): :class:`FlightTable`.

- A **flight node** is a pose (x, y) [m] with a heading k. The root node of a start
  configuration is its cell centre with its heading; the child node (n, b) of node n is the
  landing pose of n's flight with the heading after turning by angle b. Nodes are keyed by
  the bits of x, y and k, so every tree whose best arrival at a state lands on the same
  pose (from the same flight, or in a corner) shares its node and its flight.
- Per node the table holds what the search needs of its flight, computed once with one
  vectorised cast for all new nodes of a band: the clock length, its cost w1·clock/h, the
  landing's contact bin (as the m child states) and the goal arrivals along the flight (the
  chords of :func:`planners.navigation.exact._chords.chords` at least ``min_depth`` deep: goal
  configuration k·P + p, its cost w1·t/h and t).
- The search itself is the Dial's-bucket search described in §13, with the same order,
  costs (the same floating-point operations) and ties, so its trees and all-pairs results
  are those of one search per start.
"""

from __future__ import annotations

import heapq
from dataclasses import dataclass

import numpy as np

from envs.contact import contact_flights

from ._chords import chords

__all__ = ["FlightTable", "SearchArrays", "search_many"]

_IMPROVE = 1e-9          # a new arrival replaces a state's pose when cheaper by this


class _Grow:
    """A growable numpy array (amortised doubling) along its first axis."""

    def __init__(self, shape_tail=(), dtype=float, fill=0) -> None:
        self.a = np.full((1024, *shape_tail), fill, dtype=dtype)
        self.n, self.fill = 0, fill

    def extend(self, values) -> None:
        values = np.asarray(values)
        need = self.n + len(values)
        if need > len(self.a):
            big = np.full((max(need, 2 * len(self.a)), *self.a.shape[1:]), self.fill,
                          dtype=self.a.dtype)
            big[:self.n] = self.a[:self.n]
            self.a = big
        self.a[self.n:need] = values
        self.n = need

    def reserve(self, count: int) -> None:
        """Append ``count`` rows of the fill value."""
        self.extend(np.full((count, *self.a.shape[1:]), self.fill, dtype=self.a.dtype))


class FlightTable:
    """Flight nodes (pose × heading) and their flights, shared by the trees of a search.

    Parameters
    ----------
    nav : ExactNavigator   the planner (cells, angles, weights, caster, contact rule)
    """

    def __init__(self, nav) -> None:
        self.nav = nav
        cs = nav.cells
        self.root = np.full(cs.N, -1, dtype=np.int64)     # node of each start configuration
        self.index: dict = {}                             # (x bits, y bits, k) -> node
        self.pos = _Grow((2,))                            # pose [m] of each node
        self.k = _Grow(dtype=np.int64)                    # heading index
        self.land = _Grow((2,))                           # landing pose [m] of its flight
        self.clock = _Grow()                              # clock length [m] of its flight
        self.fc = _Grow()                                 # its cost w1·clock/h
        self.child_state = _Grow((nav.m,), dtype=np.int64)   # local state after turn b
        self.child = _Grow((nav.m,), dtype=np.int64, fill=-1)  # child node after turn b
        self.off = _Grow(dtype=np.int64)                  # first goal arrival of the node
        self.cnt = _Grow(dtype=np.int64)                  # number of its goal arrivals
        self.goal = _Grow(dtype=np.int64)                 # goal configuration k·P + p
        self.goal_cost = _Grow()                          # w1·t/h
        self.goal_t = _Grow()                             # t [m] along the flight

    @property
    def n(self) -> int:
        """Number of flight nodes."""
        return self.k.n

    def roots(self, z: np.ndarray) -> np.ndarray:
        """Nodes of start configurations ``z`` (created on first use)."""
        new = np.unique(z[self.root[z] < 0])
        if new.size:
            p, k = self.nav.cells.pk(new)
            self.root[new] = self._find(self.nav.cells.centres[p], k)
        return self.root[z]

    def children(self, parent: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Nodes after node ``parent``'s flight and turn ``b`` (created on first use)."""
        out = self.child.a[parent, b]
        miss = out < 0
        if miss.any():
            key, inv = np.unique(parent[miss] * self.nav.m + b[miss], return_inverse=True)
            pn, bn = np.divmod(key, self.nav.m)
            k = (self.k.a[pn] + self.nav.steps[bn]) % self.nav.cells.K
            ids = self._find(self.land.a[pn], k)
            self.child.a[pn, bn] = ids
            out[miss] = ids[inv.reshape(-1)]
        return out

    def _find(self, pos: np.ndarray, k: np.ndarray) -> np.ndarray:
        """Nodes of poses ``pos`` [m] with headings ``k``: the existing node of the same
        bits, else a new one (flights from different trees' arrivals meet at the same pose
        bitwise where they land from the same flight, and in corners).
        """
        pos = np.ascontiguousarray(pos, dtype=float).reshape(-1, 2)
        k = np.asarray(k, dtype=np.int64)
        bits = pos.view(np.int64)
        keys = list(zip(bits[:, 0].tolist(), bits[:, 1].tolist(), k.tolist()))
        index = self.index
        ids = np.fromiter((index.get(key, -1) for key in keys), dtype=np.int64,
                          count=len(keys))
        miss = np.flatnonzero(ids < 0)
        if miss.size:
            first: dict = {}
            for i in miss.tolist():
                first.setdefault(keys[i], i)
            rows = np.fromiter(first.values(), dtype=np.int64, count=len(first))
            index.update(zip(first, self._add(pos[rows], k[rows]).tolist()))
            ids[miss] = [index[keys[i]] for i in miss.tolist()]
        return ids

    def _add(self, pos: np.ndarray, k: np.ndarray) -> np.ndarray:
        """New nodes at poses ``pos`` with headings ``k``: cast and tabulate their flights."""
        nav, cs = self.nav, self.nav.cells
        w1, h, m, K, P = nav.w1, cs.h, nav.m, cs.K, cs.P
        pos = np.asarray(pos, dtype=float).reshape(-1, 2)
        k = np.asarray(k, dtype=np.int64)
        ids = np.arange(self.n, self.n + len(k))
        D, u = nav.flights(pos, k)
        land, clock = pos + D[:, None] * u, D
        if nav.contact is not None:                       # glancing contacts slide on
            fl = contact_flights(nav.caster, pos, u, D, nav.contact)
            land, clock = fl.end, fl.clock
        fi, p, t, depth = chords(cs, pos, u, D)
        ok = depth >= nav.min_depth
        fi, p, t = fi[ok], p[ok], t[ok]
        cnt = np.bincount(fi, minlength=len(k))
        self.off.extend(self.goal.n + np.cumsum(cnt) - cnt)
        self.cnt.extend(cnt)
        self.goal.extend(k[fi] * P + p)
        self.goal_cost.extend(w1 * t / h)
        self.goal_t.extend(t)
        lb = nav.boundary.bin_of(land)
        k2 = (k[:, None] + nav.steps[None]) % K
        self.child_state.extend((lb[:, None] * K + k2) * m + np.arange(m)[None])
        self.child.reserve(len(k))
        self.pos.extend(pos)
        self.k.extend(k)
        self.land.extend(land)
        self.clock.extend(clock)
        self.fc.extend(w1 * clock / h)
        return ids


@dataclass(frozen=True, eq=False)
class SearchArrays:
    """The trees of a search from B starts (one index space of B·(S + 1) states: source i
    owns states i·(S + 1) … i·(S + 1) + S, the last one its start).

    Attributes
    ----------
    cost : (B·(S + 1),) float   cost of every state (inf: not reached)
    pred : (B·(S + 1),) int     predecessor state (−1: none); None without ``tree``
    pos : (B·(S + 1), 2) float  exact pose [m] of each settled state; None without ``tree``
    flight : (B·(S + 1),) float clock length [m] of each settled state's flight; None
                                without ``tree``
    used : (B·(S + 1),) int     bit mask of the angles used on the way to each state
    gcost : (B, N) float        cost of the best arrival at every goal configuration
    gstate : (B, N) int         the state whose flight makes that arrival (−1: none)
    gt : (B, N) float           [m] along that flight: the final drive
    """

    cost: np.ndarray
    pred: np.ndarray | None
    pos: np.ndarray | None
    flight: np.ndarray | None
    used: np.ndarray
    gcost: np.ndarray
    gstate: np.ndarray
    gt: np.ndarray


def search_many(nav, starts: np.ndarray, table: FlightTable | None = None,
                tree: bool = True) -> SearchArrays:
    """The search from several starts at once (independent trees, one index space: source i
    owns states i·(S + 1) … i·(S + 1) + S, the last one its start). One cost band of all
    trees is settled per round (every state cheaper than the smallest unsettled cost plus the
    smallest edge weight is final); the flights come from ``table`` (a new one if None).

    Returns the :class:`SearchArrays`; with ``tree`` False, ``pred``, ``pos`` and ``flight``
    are None (all pairs needs the goal arrivals and angle masks only).
    """
    K, m, N = nav.cells.K, nav.m, nav.cells.N
    table = FlightTable(nav) if table is None else table
    starts = np.asarray(starts, dtype=np.int64)
    S = nav.n_states
    SS = S + 1
    B = len(starts)
    w1, w2 = nav.w1, nav.w2
    wmin = min(w1, w2)
    first_bump = w1 if m == 1 else min(w1, w2)
    cost = np.full(B * SS, np.inf)
    node = np.full(B * SS, -1, dtype=np.int32)     # settled: its node; else the parent's
    used = np.zeros(B * SS, dtype=np.int32 if tree or m > 8 else np.uint8)
    done = np.zeros(B * SS, dtype=bool)
    pred = np.full(B * SS, -1, dtype=np.int64) if tree else None
    astate = np.append(np.tile(np.arange(m), nav.boundary.n_bins * K), -1)
    roots = np.arange(B) * SS + S
    cost[roots] = 0.0
    gcost = np.full(B * N, np.inf)
    gstate = np.full(B * N, -1, dtype=np.int64)
    gt = np.full(B * N, np.nan)
    bm = np.arange(m)
    # Dial's bucket queue on the cost, buckets of the smallest edge weight: the lowest
    # non-empty bucket is final as a whole (every edge adds at least wmin)
    buckets: dict = {0: [roots]}
    heap = [0]
    while heap:
        j = heapq.heappop(heap)
        band = np.unique(np.concatenate(buckets.pop(j)))
        band = band[~done[band] & (np.floor(cost[band] / wmin) == j)]
        if band.size == 0:
            continue
        done[band] = True
        src_i, local = np.divmod(band, SS)
        root = local == S
        nodes = np.empty(band.size, dtype=np.int64)
        if root.any():
            nodes[root] = table.roots(starts[src_i[root]])
        if not root.all():
            nr = ~root
            nodes[nr] = table.children(node[band[nr]].astype(np.int64), local[nr] % m)
        node[band] = nodes
        c = cost[band]
        # goal arrivals along the flights (the band's rows in order, each node's in order)
        cnt = table.cnt.a[nodes]
        E = int(cnt.sum())
        if E:
            row = np.repeat(np.arange(band.size), cnt)
            ent = np.arange(E) + np.repeat(table.off.a[nodes] - (np.cumsum(cnt) - cnt), cnt)
            gz = src_i[row] * N + table.goal.a[ent]
            total = c[row] + table.goal_cost.a[ent]
            win = total < gcost[gz] - _IMPROVE           # only these can replace a goal's
            gz, total, row, ent = gz[win], total[win], row[win], ent[win]
            if gz.size:
                order = np.lexsort((total, gz))
                gz, total, row, ent = gz[order], total[order], row[order], ent[order]
                first = np.ones(gz.size, dtype=bool)
                first[1:] = gz[1:] != gz[:-1]
                gz, total, row, ent = gz[first], total[first], row[first], ent[first]
                gcost[gz], gstate[gz], gt[gz] = total, band[row], table.goal_t.a[ent]
        # landings and turns
        row = np.repeat(np.arange(band.size), m)
        b = np.tile(bm, band.size)
        tgt = src_i[row] * SS + table.child_state.a[nodes].reshape(-1)
        a = astate[local[row]]
        w = np.where(a < 0, first_bump, np.where(a == b, w1, w2))
        new = (c + table.fc.a[nodes])[row] + w
        better = ~done[tgt] & (new < cost[tgt] - _IMPROVE)  # only these can improve a state
        tgt, new, row, b = tgt[better], new[better], row[better], b[better]
        if tgt.size == 0:
            continue
        order = np.lexsort((new, tgt))
        tgt, new, row, b = tgt[order], new[order], row[order], b[order]
        firsts = np.ones(tgt.size, dtype=bool)
        firsts[1:] = tgt[1:] != tgt[:-1]
        tgt, new, row, b = tgt[firsts], new[firsts], row[firsts], b[firsts]
        cost[tgt] = new
        node[tgt] = nodes[row]
        used[tgt] = used[band[row]] | (1 << b)
        if tree:
            pred[tgt] = band[row]
        bj = np.floor(new / wmin).astype(np.int64)
        order = np.argsort(bj, kind="stable")
        bj, tg = bj[order], tgt[order]
        cut = np.flatnonzero(np.diff(bj)) + 1
        for jj, part in zip(bj[np.r_[0, cut]].tolist(), np.split(tg, cut)):
            if jj not in buckets:
                buckets[jj] = []
                heapq.heappush(heap, jj)
            buckets[jj].append(part)
    pos = flight = None
    if tree:
        pos = np.full((B * SS, 2), np.nan)
        flight = np.full(B * SS, np.nan)
        ok = done
        pos[ok] = table.pos.a[node[ok]]
        flight[ok] = table.clock.a[node[ok]]
    return SearchArrays(cost, pred, pos, flight, used, gcost.reshape(B, N),
                        gstate.reshape(B, N), gt.reshape(B, N))
