"""Navigation hot paths on `complex` at 8 orientations, beside a straightforward networkx
version measured in the same run.

    python -m benchmarks.bench_navigation [--env complex] [--angles 45,90,135] [--ref-sources 0]
                                          [--exact] [--exact-all-pairs] [--exact-only]
                                          [--exact-ref-starts 3]

Rows: roadmap build (step table + sparse layered graph), one plan query (cold: a fresh
single-source search), all pairs with the angle-use histogram. The networkx reference builds
an nx.DiGraph over (z, a) nodes and runs one multi-source Dijkstra (with paths) per source;
``--ref-sources K`` times K random sources and extrapolates to all N (0 = all sources).

``--exact`` adds the exact planner (docs/model.md §13): one cold query (mean and maximum of
20 random pairs; CPU and wall time) beside a plain heapq Dijkstra over the same states with
one scalar ray cast over every wall per expansion (same costs: the number of equal answers
is printed), and with ``--exact-all-pairs`` the full all-pairs run beside the same
reference's full search from ``--exact-ref-starts`` random starts (its CPU time
extrapolated to all N starts; its rows are compared with the all-pairs weights).
``--exact-only`` skips the step planner's rows. CPU time is shown because on a shared
machine wall time is mostly waiting.
"""

from __future__ import annotations

import argparse
import heapq
import math
import time

import networkx as nx
import numpy as np

import envs
from envs.motion import BUMP_RANGE, CONTACT_GAP
from planners.cells import CellSpace
from planners.navigation import Navigator
from planners.navigation.exact import ExactNavigator, chords


def best_of(fn, repeat: int):
    """Best wall time [s] of ``repeat`` calls of ``fn``, and the last result."""
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return min(times), out


def nx_build(cells: CellSpace, angles):
    """The reference roadmap as an ``nx.DiGraph`` over (z, angle index) nodes (same weights)."""
    G = nx.DiGraph()
    m = len(angles)
    steps = [int(round(a / cells.delta_deg)) for a in angles]
    fwd = cells.forward
    for z in range(cells.N):
        p, k = z % cells.P, z // cells.P
        for a in range(m):
            if fwd[z] >= 0:
                G.add_edge((z, a), (int(fwd[z]), a), weight=1.0)
            else:
                for b in range(m):
                    G.add_edge((z, a), (((k + steps[b]) % cells.K) * cells.P + p, b),
                               weight=1.0 if a == b else 100.0)
    return G


def nx_from_source(G, cells, angles, s):
    """Shortest cost and path from configuration ``s`` to every configuration in the networkx
    graph.
    """
    dist, paths = nx.multi_source_dijkstra(G, [(s, a) for a in range(len(angles))])
    best: dict[int, tuple[float, list]] = {}
    for (z, _b), d in dist.items():
        if z not in best or d < best[z][0]:
            best[z] = (d, paths[(z, _b)])
    hist = np.zeros(len(angles) + 1, dtype=np.int64)
    for z, (_d, path) in best.items():
        if z == s:
            continue
        used = {path[i + 1][1] for i in range(len(path) - 1)
                if path[i + 1][0] % cells.P == path[i][0] % cells.P}
        hist[len(used)] += 1
    return hist


def ref_exact_cost(nav: ExactNavigator, s: int, g: int) -> float:
    """The exact planner's cost from s to g by a plain heapq Dijkstra (one scalar ray cast
    per settled state, poses of the first settled arrival); inf when unreachable.
    """
    return float(ref_exact_costs(nav, s, g))


def ref_exact_costs(nav: ExactNavigator, s: int, goal: int | None = None):
    """A plain heapq Dijkstra over the exact planner's states from configuration ``s``: one
    scalar ray cast over every wall per settled state (``WallCaster.cast_one``), one bin
    lookup and one chord call per flight, poses of the first settled arrival.

    With ``goal``, the cheapest cost to it (inf when unreachable), stopping once no cheaper
    arrival is possible; without, the (N,) cheapest cost to every configuration (inf when
    unreachable, 0 at ``s``): one row of the all-pairs weights.
    """
    cs, bd, m, K, h = nav.cells, nav.boundary, nav.m, nav.cells.K, nav.cells.h
    steps = [cs.angle_steps(a) for a in nav.angles]
    best = np.full(cs.N, np.inf)
    p0, k0 = (int(v) for v in cs.pk(s))
    x0, y0 = (float(v) for v in cs.centres[p0])
    heap = [(0.0, -1, x0, y0, k0, -1)]
    settled: set = set()
    while heap:
        c, st, x, y, k, a = heapq.heappop(heap)
        if st in settled:
            continue
        if goal is not None and c >= best[goal]:
            break
        settled.add(st)
        ux, uy = (float(v) for v in cs.units[k])
        t = nav.caster.cast_one(x, y, ux, uy)
        D = 0.0 if t <= BUMP_RANGE else max(t - CONTACT_GAP, 0.0)
        if goal is None or k == cs.pk(goal)[1]:
            _, p, tt, depth = chords(cs, [[x, y]], [[ux, uy]], [D])
            for pi, ti, di in zip(p, tt, depth):
                z = k * cs.P + int(pi)
                if di >= nav.min_depth:
                    best[z] = min(best[z], c + nav.w1 * ti / h)
        lx, ly = x + D * ux, y + D * uy
        b = int(bd.bin_of([[lx, ly]])[0])
        for bi in range(m):
            k2 = (k + steps[bi]) % K
            w = (nav.w1 if m == 1 else min(nav.w1, nav.w2)) if a < 0 else \
                (nav.w1 if a == bi else nav.w2)
            heapq.heappush(heap, (c + nav.w1 * D / h + w, (b * K + k2) * m + bi, lx, ly, k2,
                                  bi))
    if goal is not None:
        return best[goal]
    best[s] = 0.0
    return best


def exact_rows(env, angles, all_pairs: bool, ref_starts: int = 3) -> None:
    """Time the exact planner against the heapq reference and print the rows."""
    cells = CellSpace(env.with_discretization())
    nav = ExactNavigator(cells, angles)
    c0 = time.process_time()
    _ = nav.boundary, nav._heading_caster
    t_build = time.process_time() - c0
    rng = np.random.default_rng(1)
    pairs = rng.integers(0, cells.N, size=(20, 2))
    ours, cpu = [], []
    t0 = time.perf_counter()
    for s, g in pairs:
        c0 = time.process_time()
        ours.append(nav.plan(s, g))
        cpu.append(time.process_time() - c0)
    cpu_q, wall_q = float(np.mean(cpu)), (time.perf_counter() - t0) / 20
    c0, t0 = time.process_time(), time.perf_counter()
    ref = [ref_exact_cost(nav, int(s), int(g)) for s, g in pairs[:5]]
    cpu_r, wall_r = (time.process_time() - c0) / 5, (time.perf_counter() - t0) / 5
    same = sum((r is None and not math.isfinite(c)) or
               (r is not None and (s == g or abs(r.cost - c) < 1e-6))
               for r, c, (s, g) in zip(ours, ref, pairs))
    print(f"exact planner: {nav.n_states} states (bins of h/4), boundary and culled casts "
          f"built in {_fmt(t_build)} CPU")
    print(f"{'operation':<28}{'cpu':>12}{'wall':>12}{'heapq ref cpu':>15}{'target':>10}")
    print(f"{'exact: one plan query':<28}{_fmt(cpu_q):>12}{_fmt(wall_q):>12}"
          f"{_fmt(cpu_r):>15}{'0.2 s':>10}")
    print(f"slowest of the 20 queries: {_fmt(max(cpu))} CPU; equal costs with the heapq "
          f"reference: {same} of 5 (reference wall {_fmt(wall_r)} per query)")
    if all_pairs:
        c0, t0 = time.process_time(), time.perf_counter()
        ap = nav.all_pairs()
        cpu_a, wall_a = time.process_time() - c0, time.perf_counter() - t0
        starts = rng.choice(cells.N, size=min(ref_starts, cells.N), replace=False)
        c0 = time.process_time()
        rows = [ref_exact_costs(nav, int(s)) for s in starts]
        cpu_ref = (time.process_time() - c0) * cells.N / max(len(starts), 1)
        equal = sum(np.allclose(np.where(ap.weights[s] < 0, np.inf, ap.weights[s]), row,
                                rtol=0, atol=1e-6) for s, row in zip(starts, rows))
        print(f"{'exact: all pairs':<28}{_fmt(cpu_a):>12}{_fmt(wall_a):>12}"
              f"{_fmt(cpu_ref):>15}{'60 s':>10}")
        print(f"exact all pairs: heapq reference extrapolated from {len(starts)} full searches; "
              f"rows equal to it: {equal} of {len(starts)}")
        print(f"exact reachable pairs: {ap.reachable_fraction:.1%}; histogram (angles used "
              f"0..m): {ap.histogram().tolist()}")


def main(argv=None) -> None:
    """Run the navigation benchmark against networkx and print the table."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--env", default="complex")
    ap.add_argument("--orientations", type=int, default=8)
    ap.add_argument("--angles", default="45,90,135")
    ap.add_argument("--ref-sources", type=int, default=0,
                    help="time the networkx all-pairs on this many sources and extrapolate "
                    "(0: all)")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--exact", action="store_true",
                    help="also time the exact planner (docs/model.md §13)")
    ap.add_argument("--exact-all-pairs", action="store_true",
                    help="with --exact: also the exact all pairs (about 20 CPU s on complex)")
    ap.add_argument("--exact-ref-starts", type=int, default=3,
                    help="with --exact-all-pairs: full heapq reference searches to time and "
                    "compare (extrapolated to all starts)")
    ap.add_argument("--exact-only", action="store_true",
                    help="with --exact: skip the step planner's rows")
    args = ap.parse_args(argv)
    angles = [float(a) for a in args.angles.split(",")]
    env = envs.load(args.env, orientations=args.orientations)
    if args.exact and args.exact_only:
        exact_rows(env, angles, args.exact_all_pairs, args.exact_ref_starts)
        return

    def build():
        cells = CellSpace(env.with_discretization())   # fresh caches every time
        nav = Navigator(cells, angles)
        _ = nav.roadmap.graph
        return nav
    t_build, nav = best_of(build, args.repeat)
    cells = nav.cells
    rng = np.random.default_rng(0)
    pairs = rng.integers(0, cells.N, size=(50, 2))

    def one_query():
        for s, g in pairs:
            nav._cache.clear()
            nav.plan(s, g)
    t_q, _ = best_of(one_query, args.repeat)
    t_q /= len(pairs)
    t_all, hist = best_of(lambda: nav.all_pairs().histogram(),
                          max(1, args.repeat - 1))

    t0 = time.perf_counter()
    G = nx_build(cells, angles)
    t_nx_build = time.perf_counter() - t0
    t0 = time.perf_counter()
    for s, g in pairs[:10]:
        dist = nx.multi_source_dijkstra_path_length(G, [(s, a) for a in range(len(angles))])
        min((v for (z, _b), v in dist.items() if z == g), default=None)
    t_nx_q = (time.perf_counter() - t0) / 10
    sources = (np.arange(cells.N) if args.ref_sources <= 0 else
               rng.choice(cells.N, size=min(args.ref_sources, cells.N), replace=False))
    t0 = time.perf_counter()
    nx_hist = np.zeros(len(angles) + 1, dtype=np.int64)
    for s in sources:
        nx_hist += nx_from_source(G, cells, angles, int(s))
    t_nx_all = (time.perf_counter() - t0) * cells.N / len(sources)
    extrap = "" if len(sources) == cells.N else f" (extrapolated from {len(sources)} sources)"

    print(f"{args.env}: P = {cells.P}, K = {cells.K}, N = {cells.N}, "
          f"Φ = {args.angles}, roadmap nodes = {nav.roadmap.n_nodes}, "
          f"edges = {nav.roadmap.graph.nnz}")
    print(f"{'operation':<28}{'bouncesim':>12}{'networkx':>12}{'speed-up':>10}{'target':>10}")
    for name, ours, ref, target in (
            ("roadmap build", t_build, t_nx_build, "0.5 s"),
            ("one plan query", t_q, t_nx_q, "20 ms"),
            ("all pairs + histogram", t_all, t_nx_all, "3 s")):
        print(f"{name:<28}{_fmt(ours):>12}{_fmt(ref):>12}{ref / ours:>9.0f}x{target:>10}")
    print(f"histogram (angles used 0..m): {hist.tolist()}{extrap}")
    if len(sources) == cells.N:
        print(f"networkx histogram:           {nx_hist.tolist()} "
              f"(equal totals: {nx_hist.sum() == hist.sum()}; ties may split differently)")
    if args.exact:
        exact_rows(env, angles, args.exact_all_pairs, args.exact_ref_starts)


def _fmt(t: float) -> str:
    return f"{t * 1e3:.1f} ms" if t < 1 else f"{t:.2f} s"


if __name__ == "__main__":
    main()
