"""Shortest bouncing plans: single queries and all pairs (docs/model.md §12; the paper's Alg. 1-2).

Examples
--------
>>> import envs
>>> from planners.cells import CellSpace
>>> nav = Navigator(CellSpace(envs.load("lab")), [90, 135])
>>> route = nav.plan(8, 0)            # bottom-right facing east -> bottom-left facing east
>>> str(route.plan), route.cost
('90° 90° 00000000 90° 90°', 12.0)
>>> nav.plan(5, 5).cost               # start == goal: empty plan, cost 0
0.0
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Iterable

import numpy as np
from scipy.sparse.csgraph import dijkstra

from ..cells import CellSpace
from ..measures import step_flights
from ..plan import Plan
from ..resources import (
    BOOL,
    DEFAULT_MAX_MEMORY,
    F64,
    HEAP_NATIVE,
    I32,
    I64,
    MemoryEstimate,
    check_memory,
    parse_memory,
    pipeline,
)
from .base import PairTable, Route, check_config
from .roadmap import Roadmap

__all__ = ["AllPairs", "Navigator", "SEARCH_CACHE", "all_pairs_bytes", "roadmap_bytes",
           "search_bytes"]

SEARCH_CACHE = 64
"""Single-source searches a :class:`Navigator` keeps for repeated starts (default)."""


class Navigator:
    """The paper's step-model planner (``"step"``): plans on the layered roadmap of an
    environment's cell space (docs/model.md §12).

    Parameters
    ----------
    cells : CellSpace
    angles : sequence of float   bouncing angles Φ [deg]
    w1, w2 : float               edge weights (defaults: the paper's 1 and 100)
    cache : int                  number of single-source searches kept for repeated starts
    max_memory : int, str or None
        Refuse (:class:`envs.UserError`, before building anything) when the step table,
        roadmap and one search would need more than this many bytes (or a size such as
        ``"2G"``; None: no limit), and cache no more searches than fit; see
        :mod:`planners.resources`.
    """

    name = "step"
    needs = frozenset()
    closed_loop = False

    def __init__(self, cells: CellSpace, angles: Iterable[float], w1: float = 1.0,
                 w2: float = 100.0, cache: int = SEARCH_CACHE,
                 max_memory=DEFAULT_MAX_MEMORY) -> None:
        self.cells = cells
        self.roadmap = Roadmap(cells, tuple(angles), w1, w2)
        est = check_memory(cells, self.memory_estimate(cells, self.roadmap.angles, searches=1),
                           what="planning", max_memory=max_memory)
        if max_memory is not None:    # keep only as many cached searches as the limit allows
            per = search_bytes(cells.N, self.roadmap.m).traced
            spare = parse_memory(max_memory) - est.total
            cache = min(cache, 1 + int(max(spare, 0) // max(per, 1)))
        self._cache: OrderedDict[int, tuple[np.ndarray, np.ndarray]] = OrderedDict()
        self._cache_size = cache

    @property
    def angles(self) -> tuple:
        """The bouncing angles Φ [deg] of the roadmap's layers."""
        return self.roadmap.angles

    def _search(self, start: int) -> tuple[np.ndarray, np.ndarray]:
        hit = self._cache.get(start)
        if hit is not None:
            self._cache.move_to_end(start)
            return hit
        dist, pred = dijkstra(self.roadmap.graph, directed=True,
                              indices=int(self.roadmap.start_node(start)),
                              return_predecessors=True)
        self._cache[start] = (dist, pred)
        if len(self._cache) > self._cache_size:
            self._cache.popitem(last=False)
        return dist, pred

    def plan(self, start: int, goal: int) -> Route | None:
        """The minimum-weight plan from configuration ``start`` to ``goal``, or None."""
        s, g = check_config(self.cells, start, "start"), check_config(self.cells, goal, "goal")
        if s == g:
            return _route(self.cells, s, g, (), 0.0, (s,))
        dist, pred = self._search(s)
        return _route_from_tree(self.roadmap, s, g, dist, pred)

    def policy(self, start: int, goal: int) -> Plan | None:
        """The plan :func:`bouncesim.runs.execute.execute` runs (None: no plan)."""
        route = self.plan(start, goal)
        return None if route is None else route.plan

    def all_pairs(self, max_memory=DEFAULT_MAX_MEMORY) -> AllPairs:
        """Algorithm 2: every ordered pair, one Dijkstra per source (in one C call).

        Refuses (:class:`envs.UserError`) when the estimated peak memory exceeds
        ``max_memory`` bytes (or a size such as ``"2G"``; None: no limit).
        """
        check_memory(self.cells, self.memory_estimate(self.cells, self.angles, "allpairs"),
                     what="all pairs", max_memory=max_memory)
        return AllPairs(self.roadmap)

    @classmethod
    def memory_estimate(cls, cells: CellSpace, angles, task: str = "plan",
                        searches: int = 1) -> MemoryEstimate:
        """Peak memory of planning (``task="plan"``: the step table, the roadmap and up to
        ``searches`` cached single-source searches) or of all pairs (``"allpairs"``), from
        the sizes alone (:func:`planners.resources.pipeline` of :func:`roadmap_bytes`, then
        :func:`search_bytes` or :func:`all_pairs_bytes`).
        """
        N, m = cells.N, max(1, len(tuple(angles)))
        road = roadmap_bytes(N, m, vars(cells).get("forward"))
        if task == "plan":
            return pipeline(cells, road, search_bytes(N, m, searches))
        if task != "allpairs":
            raise ValueError(f"task must be 'plan' or 'allpairs', got {task!r}.")
        return pipeline(cells, road, all_pairs_bytes(N, m))


class AllPairs(PairTable):
    """All-pairs shortest plans (Algorithm 2) from one multi-source Dijkstra call.

    Attributes
    ----------
    weights : (N, N) float array   L[i, j], the minimum weight, -1 where unreachable, 0 on i == j
    angles_used : (N, N) int8      distinct angles in the plan, -1 where unreachable or i == j
    n_labels : (N, N) int32        plan length (steps + bumps), -1 where unreachable
    """

    def __init__(self, roadmap: Roadmap) -> None:
        self.roadmap = roadmap
        N, m = roadmap.N, roadmap.m
        starts = roadmap.start_node(np.arange(N))
        dist, pred = dijkstra(roadmap.graph, directed=True, indices=starts,
                              return_predecessors=True)
        # the best end layer for every (source, goal)
        layer_d = dist[:, : m * N].reshape(N, m, N)
        best = np.argmin(layer_d, axis=1)                       # (N, N) layer index
        L = np.take_along_axis(layer_d, best[:, None, :], axis=1)[:, 0, :]
        reach = np.isfinite(L)
        self._dist = dist
        self._pred = pred.astype(np.int32, copy=False)
        self._best = best.astype(np.int16)
        goal_nodes = best.astype(np.int64) * N + np.arange(N)[None, :]
        mask, depth = self._tree_masks()
        rows = np.arange(N)[:, None]
        used_bits = mask[rows, goal_nodes]
        used = _popcount(used_bits).astype(np.int8)
        nlab = depth[rows, goal_nodes].astype(np.int32)
        eye = np.eye(N, dtype=bool)
        W = np.where(reach, L, -1.0)
        W[eye] = 0.0
        used[~reach | eye] = -1
        nlab[~reach] = -1
        nlab[eye] = 0
        self.m = m
        self.weights = W
        self.angles_used = used
        self.n_labels = nlab

    def _tree_masks(self) -> tuple[np.ndarray, np.ndarray]:
        """Per (source, layer node): bit mask of the angles used on the tree path from the
        source, and the path's edge count.

        Pointer jumping over the predecessor trees of all sources at once: log2(depth)
        rounds of vectorised gathers instead of a Python walk per pair. Start nodes have no
        in-edges, so the only one in a tree is its root; columns stop at the layer nodes and
        one extra "sink" column stands for the root and for unreached nodes.
        """
        rm = self.roadmap
        N, P, m = rm.N, rm.cells.P, rm.m
        M = m * N                                                 # layer nodes
        sink = M
        pred = self._pred[:, :M]
        parent = np.where((pred < 0) | (pred >= M), sink, pred)  # root or unreached -> sink
        has_parent = pred >= 0
        node_p = np.arange(M) % N % P
        bump = has_parent & ((pred % N % P) == node_p[None, :])
        bit_t = np.uint8 if m <= 8 else np.uint64
        bits = np.left_shift(1, np.arange(M) // N).astype(bit_t)
        width = M + 1
        off = (np.arange(N, dtype=np.int64) * width)[:, None]
        anc = np.empty((N, width), dtype=np.int64)
        anc[:, :M] = parent + off
        anc[:, M] = sink + off[:, 0]
        mask = np.zeros((N, width), dtype=bit_t)
        mask[:, :M] = np.where(bump, bits[None, :], 0)
        depth = np.zeros((N, width), dtype=np.int32)
        depth[:, :M] = has_parent
        mask, depth, anc = mask.ravel(), depth.ravel(), anc.ravel()
        sinks = (np.arange(N, dtype=np.int64) * width + sink)
        live = np.nonzero(~np.isin(anc, sinks))[0]
        while live.size:
            a = anc[live]
            mask[live] |= mask[a]
            depth[live] += depth[a]
            anc[live] = anc[a]
            live = live[(anc[live] % width) != sink]
        return mask.reshape(N, width), depth.reshape(N, width)

    def route(self, i: int, j: int) -> Route | None:
        """The plan for the pair (i, j), rebuilt from the stored predecessor trees."""
        i, j = int(i), int(j)
        if i == j:
            return _route(self.roadmap.cells, i, j, (), 0.0, (i,))
        return _route_from_tree(self.roadmap, i, j, self._dist[i], self._pred[i])


def _route_from_tree(rm: Roadmap, s: int, g: int, dist: np.ndarray, pred: np.ndarray
                     ) -> Route | None:
    N, m = rm.N, rm.m
    goal_nodes = np.arange(m) * N + g
    d = dist[goal_nodes]
    b = int(np.argmin(d))
    if not np.isfinite(d[b]):
        return None
    node = int(goal_nodes[b])
    root = int(rm.start_node(s))
    nodes = [node]
    while node != root:
        node = int(pred[node])
        if node < 0:  # pragma: no cover - a tree without its root would be a bug
            raise RuntimeError("broken predecessor tree")
        nodes.append(node)
    nodes.reverse()
    labels = rm.labels_of_path(nodes)
    path = tuple(int(z) for z in rm.config_of(nodes))
    return _route(rm.cells, s, g, tuple(labels), float(d[b]), path)


def _route(cells: CellSpace, s: int, g: int, labels: tuple, cost: float, path: tuple) -> Route:
    """The step planner's :class:`Route`: the plan with the step model's run lengths as its
    flights (rounded to 1e-9 m) and the cell-centre pose of every configuration on its path.
    """
    plan = Plan(labels)
    flights, final = step_flights(cells, plan, int(cells.pk(s)[1]))
    plan = Plan.with_flights(plan, [round(f, 9) for f in flights], round(final, 9), "step")
    poses = tuple(cells.pose(z) for z in path)
    return Route(s, g, plan, cost, poses, "step", path)


def _popcount(x: np.ndarray) -> np.ndarray:
    x = x.astype(np.uint64, copy=True)
    count = np.zeros(x.shape, dtype=np.int64)
    while x.any():
        count += (x & np.uint64(1)).astype(np.int64)
        x >>= np.uint64(1)
    return count


# ---------------------------------------------------------------- memory (bytes)
def roadmap_bytes(N: int, m: int, forward=None) -> MemoryEstimate:
    """``Roadmap.graph``: E edges in row/col/weight parts, concatenated, COO, CSR."""
    E = _edges(N, m, forward)
    per = (3 * I64              # the rows, cols, vals parts
           + 3 * I64            # concatenated
           + 2 * I32 + F64     # scipy's COO (int32 indices)
           + I32 + F64)        # the CSR matrix
    nodes = (m + 1) * N
    return MemoryEstimate("the roadmap", E * per, 0.0,
                          E * (I32 + F64) + (nodes + 1) * I32)


def search_bytes(N: int, m: int, searches: int = 1) -> MemoryEstimate:
    """Single-source Dijkstra runs kept by ``Navigator`` (distances float64, predecessors
    int32 per node; the heap is native).
    """
    nodes = (m + 1) * N
    return MemoryEstimate("the searches", searches * nodes * (F64 + I32),
                          nodes * HEAP_NATIVE)


def all_pairs_bytes(N: int, m: int) -> MemoryEstimate:
    """``AllPairs``: the multi-source Dijkstra's (N, (m + 1) N) distances and predecessors,
    then the pointer jumping's per-(source, layer node) arrays.
    """
    nodes = (m + 1) * N
    M = m * N
    traced = (N * nodes * (F64 + I32)                   # dist, pred
              + N * M * (I64 + 3 * BOOL                 # parent, has_parent, bump, pred < 0
                         + I64 + BOOL + I32            # anc, mask, depth
                         + I64 + BOOL                   # live, isin
                         + 2 * I32))                     # pred % N % P
    return MemoryEstimate("all pairs", traced, nodes * HEAP_NATIVE)


def _edges(N: int, m: int, forward=None) -> float:
    if forward is None:                   # before the step table: every z steps or bumps
        return float(N) * max(2 * m, m * m + m)
    B = int((forward < 0).sum())
    return 2.0 * m * (N - B) + (m * m + m) * B
