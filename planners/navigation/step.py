"""Shortest bouncing plans: single queries and all pairs (docs/model.md §6; the paper's Alg. 1-2).

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
from dataclasses import dataclass
from functools import cached_property

import numpy as np
from scipy.sparse.csgraph import dijkstra

from envs import UserError

from ..cells import CellSpace
from ..plan import Plan
from ..resources import DEFAULT_MAX_MEMORY, check_memory, parse_memory, search_bytes
from .roadmap import Roadmap

__all__ = ["AllPairs", "Navigator", "Route"]


@dataclass(frozen=True)
class Route:
    """A shortest plan from one configuration to another.

    Attributes
    ----------
    start, goal : int      configuration indices z
    plan : Plan            the observation string
    cost : float           total weight (w1 per step and same-angle bump, w2 per angle change)
    path : tuple of int    configurations visited, start first and goal last
    """

    start: int
    goal: int
    plan: Plan
    cost: float
    path: tuple

    @property
    def angles_used(self) -> int:
        """Number of distinct bouncing angles in the plan."""
        return self.plan.angles_used

    def to_json(self) -> dict:
        """The route as a JSON-ready dict (plan as a label list and as text, cost, path)."""
        return {"start": self.start, "goal": self.goal, "plan": self.plan.to_list(),
                "plan_text": str(self.plan), "cost": _num(self.cost),
                "angles_used": self.angles_used, "path": list(self.path)}


def _num(x: float):
    return int(x) if float(x).is_integer() else float(x)


class Navigator:
    """Plans on the layered roadmap of an environment's cell space.

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

    def __init__(self, cells: CellSpace, angles: Iterable[float], w1: float = 1.0,
                 w2: float = 100.0, cache: int = 64, max_memory=DEFAULT_MAX_MEMORY) -> None:
        self.cells = cells
        self.roadmap = Roadmap(cells, tuple(angles), w1, w2)
        est = check_memory(cells, self.roadmap.angles, task="plan", searches=1,
                           max_memory=max_memory)
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

    def _check(self, z, what: str) -> int:
        try:
            zi = int(z)
        except (TypeError, ValueError, OverflowError):
            raise UserError(f"{what} {z!r} is not a configuration index.") from None
        if not 0 <= zi < self.cells.N:
            raise UserError(f"{what} {zi} is out of range: configurations are 0 to "
                            f"{self.cells.N - 1}.")
        return zi

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
        s, g = self._check(start, "start"), self._check(goal, "goal")
        if s == g:
            return Route(s, g, Plan(()), 0.0, (s,))
        dist, pred = self._search(s)
        return _route_from_tree(self.roadmap, s, g, dist, pred)

    def all_pairs(self, max_memory=DEFAULT_MAX_MEMORY) -> AllPairs:
        """Algorithm 2: every ordered pair, one Dijkstra per source (in one C call).

        Refuses (:class:`envs.UserError`) when the estimated peak memory exceeds
        ``max_memory`` bytes (or a size such as ``"2G"``; None: no limit).
        """
        check_memory(self.cells, self.angles, task="allpairs", max_memory=max_memory)
        return AllPairs(self.roadmap)


class AllPairs:
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

    @property
    def N(self) -> int:
        """Number of configurations N."""
        return self.roadmap.N

    def route(self, i: int, j: int) -> Route | None:
        """The plan for the pair (i, j), rebuilt from the stored predecessor trees."""
        i, j = int(i), int(j)
        if i == j:
            return Route(i, j, Plan(()), 0.0, (i,))
        return _route_from_tree(self.roadmap, i, j, self._dist[i], self._pred[i])

    def histogram(self) -> np.ndarray:
        """Counts of plans by number of angles used (0..m) over reachable pairs i != j."""
        used = self.angles_used[self.angles_used >= 0]
        return np.bincount(used, minlength=self.roadmap.m + 1)

    @cached_property
    def reachable_fraction(self) -> float:
        """Fraction of the ordered pairs (i ≠ j) with a plan."""
        N = self.N
        return float((self.weights[~np.eye(N, dtype=bool)] >= 0).mean()) if N > 1 else 1.0


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
    return Route(s, g, Plan(tuple(labels)), float(d[b]), path)


def _popcount(x: np.ndarray) -> np.ndarray:
    x = x.astype(np.uint64, copy=True)
    count = np.zeros(x.shape, dtype=np.int64)
    while x.any():
        count += (x & np.uint64(1)).astype(np.int64)
        x >>= np.uint64(1)
    return count
