"""The exact planner's all pairs and its culled casts (docs/model.md §13).

Independent evidence: a plain heapq Dijkstra per start (the benchmark's reference: one
scalar cast over every wall per state, one bin lookup and chord call per flight, no shared
flight table), and the motion layer's full scalar cast.
"""

from __future__ import annotations

import numpy as np
import pytest

import envs
from benchmarks.bench_navigation import ref_exact_costs
from envs.generated import random_polygon_room
from planners.cells import CellSpace
from planners.navigation.exact import ExactAllPairs, ExactNavigator
from planners.navigation.exact._cast import HeadingCaster

from .conftest import random_room

ANGLES = (45, 90, 135)


def test_all_pairs_rows_equal_a_plain_dijkstra_per_start():
    """On a random polygon room with a hole (non-rectilinear: no exact ties), searched in
    three batches of starts that share one flight table, a row of the all-pairs weights
    from each batch is the plain per-start Dijkstra's cheapest cost to every configuration;
    the angles used agree with the single query's plan.
    """
    rng = np.random.default_rng(0)
    env = random_polygon_room(rng)
    cs = CellSpace(env)
    nav = ExactNavigator(cs, ANGLES)
    batch = -(-cs.N // 3)
    ap = ExactAllPairs(nav, batch=batch)
    reached = 0
    for part in range(3):
        s = int(rng.integers(part * batch, min(cs.N, (part + 1) * batch)))
        ref = ref_exact_costs(nav, s)
        ours = np.where(ap.weights[s] < 0, np.inf, ap.weights[s])
        assert np.array_equal(np.isinf(ours), np.isinf(ref)), s
        fin = np.isfinite(ref)
        assert ours[fin] == pytest.approx(ref[fin], abs=1e-9)
        reached += int(fin.sum())
        for g in rng.choice(np.flatnonzero(fin), size=3):
            r = nav.plan(s, int(g))
            assert r.cost == pytest.approx(ours[g], abs=1e-9)
            if g != s:
                assert ap.angles_used[s, g] == r.angles_used
    assert reached > cs.N                        # the rows are not mostly empty


def test_all_pairs_on_a_rectilinear_room_equal_single_queries():
    """On a random rectilinear room (exact ties everywhere) the all-pairs weights equal the
    single queries' costs for every pair from three starts.
    """
    env = random_room(np.random.default_rng(5))
    cs = CellSpace(env)
    nav = ExactNavigator(cs, ANGLES)
    ap = nav.all_pairs()
    for s in (0, cs.N // 2, cs.N - 1):
        for g in range(cs.N):
            r = nav.plan(s, g)
            assert ap.weights[s, g] == pytest.approx(-1.0 if r is None else r.cost,
                                                     abs=1e-9), (s, g)


@pytest.mark.parametrize("name", ["complex", "poly"])
def test_culled_casts_equal_the_full_cast(name):
    """Along every heading, from random points inside and around the walls, the culled cast
    is the full scalar cast over every wall, bitwise.
    """
    rng = np.random.default_rng(2)
    env = (envs.load("complex", orientations=8) if name == "complex"
           else random_polygon_room(rng))
    cs = CellSpace(env.with_discretization())
    nav = ExactNavigator(cs, ANGLES)
    hc = HeadingCaster(nav.caster, cs.units, cs.h / 2)
    seg = nav.caster.segments.reshape(-1, 2)
    pts = rng.uniform(seg.min(0) - 0.3, seg.max(0) + 0.3, size=(3000, 2))
    ks = rng.integers(0, cs.K, size=len(pts))
    for (x, y), k in zip(pts.tolist(), ks.tolist()):
        ux, uy = (float(v) for v in cs.units[k])
        assert hc.cast_one(x, y, k, ux, uy) == nav.caster.cast_one(x, y, ux, uy), (x, y, k)
