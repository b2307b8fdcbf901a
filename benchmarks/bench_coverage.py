"""Benchmark of Algorithm 3 (coverage): the sparse pipeline against a networkx reference.

The pipeline = for each bouncing angle the transition matrix, the persistent groups, the
limiting distribution and the coverage, then the policy mix α. The reference follows the
paper literally: a networkx graph per angle, its strongly connected components and its
transitive closure to decide which components are persistent, dense numpy solves for the
stationary distributions and the absorption probabilities, and SLSQP for α. Both run in the
same process on the same problems and their answers are compared.

Usage::

    python -m benchmarks.bench_coverage            # K ladder + the N = 65880 headline
    python -m benchmarks.bench_coverage --big      # complex at 0.05 m cells, K = 360 (~2.4M)
    python -m benchmarks.bench_coverage --big --no-matrix   # ... without the full-matrix run
    python -m benchmarks.bench_coverage --budget 120   # time budget for the reference [s]

Run ``--big`` on its own: its peak resident memory is read from the process as a whole.
"""

from __future__ import annotations

import argparse
import resource
import time

import numpy as np

import envs
from planners.cells import CellSpace
from planners.coverage import StepModel, StepSettings, TurnNoise, design_mix, solve_mix

ANGLES = (30.0, 75.0, 315.0)
R = 0.8


# ---------------------------------------------------------------------------- reference
def reference_algorithm3(cs: CellSpace, angles, eps_deg: float, r: float):
    """Algorithm 3 as the paper describes it (networkx + dense numpy). Returns (alpha, Q).

    Q is the (P, m) matrix of coverage vectors.
    """
    import networkx as nx
    from scipy.optimize import minimize

    N, P, K = cs.N, cs.P, cs.K
    delta = 360.0 / K
    fwd = cs.forward.tolist()
    qs = []
    for phi in angles:
        s, e = round(phi / delta), round(eps_deg / delta)
        turns = {}
        for d in range(-e, e + 1):
            pr = (r if d == 0 else (1 - r) / (2 * e)) if e else 1.0
            if pr > 0:
                turns[(s + d) % K] = turns.get((s + d) % K, 0.0) + pr
        G = nx.DiGraph()
        G.add_nodes_from(range(N))
        Pm = np.zeros((N, N))
        for z in range(N):
            if fwd[z] >= 0:
                G.add_edge(z, fwd[z])
                Pm[z, fwd[z]] = 1.0
            else:
                for t, pr in turns.items():
                    z2 = int(cs.turn(z, t))
                    G.add_edge(z, z2)
                    Pm[z, z2] += pr
        sccs = [set(c) for c in nx.strongly_connected_components(G)]
        closure = nx.transitive_closure(G, reflexive=False)
        groups = [sorted(c) for c in sccs
                  if all(set(closure.successors(u)) <= c for u in c)]
        rec = np.zeros(N, dtype=bool)
        pis = []
        for g in groups:
            Pg = Pm[np.ix_(g, g)]
            A = np.vstack([Pg.T - np.eye(len(g)), np.ones((1, len(g)))])
            rhs = np.zeros(len(g) + 1)
            rhs[-1] = 1.0
            pis.append(np.linalg.lstsq(A, rhs, rcond=None)[0])
            rec[g] = True
        T = np.flatnonzero(~rec)
        pi = np.zeros(N)
        if T.size:                   # all groups' absorption columns in one dense solve
            Rm = np.column_stack([Pm[np.ix_(T, g)].sum(axis=1) for g in groups])
            X = np.linalg.solve(np.eye(T.size) - Pm[np.ix_(T, T)], Rm)
        else:
            X = np.zeros((0, len(groups)))
        for j, (g, pg) in enumerate(zip(groups, pis)):
            pi[g] = (len(g) + X[:, j].sum()) / N * pg
        qs.append(pi.reshape(K, P).sum(axis=0))
    Q = np.column_stack(qs)
    b = np.full(P, 1.0 / P)
    m = len(angles)
    res = minimize(lambda al: float(np.sum((Q @ al - b) ** 2)), np.full(m, 1.0 / m),
                   method="SLSQP", bounds=[(0, 1)] * m,
                   constraints=[{"type": "eq", "fun": lambda al: al.sum() - 1}],
                   options={"ftol": 1e-14, "maxiter": 500})
    return res.x, Q


# ---------------------------------------------------------------------------- runs
def _pipeline(cs, eps, method="runs"):
    t0 = time.perf_counter()
    res = design_mix(StepModel(cs, StepSettings(method)), ANGLES, TurnNoise(eps, R))
    return res, time.perf_counter() - t0


def _rss_gb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024 ** 2   # KB -> GB


SIZES = (("lab", 24), ("fig1", 24), ("complex", 24), ("complex", 48), ("complex", 72),
         ("complex", 360))


def ladder(budget: float) -> list[dict]:
    """Time the pipeline at every size of :data:`SIZES` within ``budget`` [s] per reference run;
    rows of the table.
    """
    rows = []
    ref_done = True
    for name, K in SIZES:
        eps = 5.0 if K % 72 == 0 else 360.0 / K
        env = envs.load(name, orientations=K)
        cs = CellSpace(env)
        t0 = time.perf_counter()
        _ = cs.forward
        t_fwd = time.perf_counter() - t0
        times = {}
        for method in ("runs", "matrix"):
            best = np.inf
            for _ in range(3):
                res, dt = _pipeline(cs, eps, method)
                best = min(best, dt)
            times[method] = best
        row = {"env": name, "K": K, "N": cs.N, "eps": eps, "forward_s": t_fwd,
               "runs_s": times["runs"], "matrix_s": times["matrix"], "alpha": res.alpha}
        if ref_done:
            t0 = time.perf_counter()
            alpha_ref, Q = reference_algorithm3(cs, ANGLES, eps, R)
            t_ref = time.perf_counter() - t0
            row["reference_s"] = t_ref
            row["max_q_diff"] = float(np.abs(Q - res.A).max())
            row["max_alpha_diff"] = float(np.abs(alpha_ref - res.alpha).max())
            if t_ref > budget / 8:          # the next size would take (much) longer
                ref_done = False
        rows.append(row)
        print(_fmt_row(row), flush=True)
    return rows


def _fmt_row(row) -> str:
    ref = row.get("reference_s")
    s = (f"| {row['env']} | {row['K']:>4} | {row['N']:>6} | {row['eps']:g} | "
         f"{row['forward_s']:.3f} | {row['runs_s']:.3f} | {row['matrix_s']:.3f} | ")
    if ref is None:
        return s + "not run | - | - |"
    return s + (f"{ref:.1f} | {ref / row['runs_s']:.0f}x | "
                f"q {row['max_q_diff']:.1e}, alpha {row['max_alpha_diff']:.1e} |")


def big(with_matrix: bool = True) -> None:
    """Time the 0.05 m complex case (about 2.4 M configurations at K = 360) and print its peak
    memory.
    """
    t0 = time.perf_counter()
    env = envs.load("complex", cell_size=0.05, orientations=360)
    cs = CellSpace(env)
    _ = cs.P
    t_cells = time.perf_counter() - t0
    t0 = time.perf_counter()
    _ = cs.forward
    t_fwd = time.perf_counter() - t0
    print(f"complex at 0.05 m cells, K=360: P={cs.P}, N={cs.N}")
    print(f"cells {t_cells:.2f} s, step table (CellSpace.forward, shapely) {t_fwd:.2f} s")
    print("| angle | groups | largest | transient | runs method [s] |")
    print("|---|---|---|---|---|")
    per = []
    t_all = time.perf_counter()
    for a in ANGLES:
        t0 = time.perf_counter()
        ac = StepModel(cs).analyse(a, TurnNoise(5.0, R))
        dt = time.perf_counter() - t0
        per.append(ac)
        print(f"| {a:g} | {ac.analysis.n_groups} | {int(ac.group_sizes.max())} | "
              f"{100 * ac.transient_fraction:.1f}% | {dt:.2f} |", flush=True)
    t0 = time.perf_counter()
    mix = solve_mix(np.column_stack([ac.q for ac in per]), np.full(cs.P, 1.0 / cs.P))
    t_mix = time.perf_counter() - t0
    t_chain = time.perf_counter() - t_all
    print(f"alpha = {np.round(mix.alpha, 6).tolist()}, residual {mix.residual:.4g}, "
          f"TV {mix.tv:.4g} (mix {t_mix * 1e3:.1f} ms)")
    print(f"chains + groups + limiting + alpha: {t_chain:.2f} s; with cells and step table: "
          f"{t_chain + t_fwd + t_cells:.2f} s; peak RSS {_rss_gb():.2f} GB")
    if with_matrix:
        print("full-matrix method (planners.coverage.markov.analyse_chain on the N x N chain):")
        for a, ac in zip(ANGLES, per):
            t0 = time.perf_counter()
            am = StepModel(cs, StepSettings("matrix")).analyse(a, TurnNoise(5.0, R))
            dt = time.perf_counter() - t0
            print(f"  {a:g}°: {dt:.2f} s, max |q_matrix - q_runs| = "
                  f"{np.abs(am.q - ac.q).max():.1e}", flush=True)
        print(f"peak RSS including the full-matrix runs {_rss_gb():.2f} GB")


def main(argv=None) -> int:
    """Run the coverage benchmark and print its table (exit status)."""
    ap = argparse.ArgumentParser(prog="python -m benchmarks.bench_coverage",
                                 description=__doc__.splitlines()[0])
    ap.add_argument("--big", action="store_true",
                    help="only the ~2.4M-configuration case (complex, 0.05 m, K=360)")
    ap.add_argument("--no-matrix", action="store_true",
                    help="with --big: skip the full-matrix comparison")
    ap.add_argument("--budget", type=float, default=240.0,
                    help="stop growing the reference once one run exceeds budget/8 [s]")
    args = ap.parse_args(argv)
    if args.big:
        big(with_matrix=not args.no_matrix)
        return 0
    print(f"angles {ANGLES}, r={R}; eps = 5° where K allows it, else one step 360°/K; "
          "times are best of 3 for the sparse pipeline (step table excluded: built once "
          "and cached), one run for the reference.")
    print("| env | K | N | eps | step table [s] | sparse, runs [s] | sparse, matrix [s] | "
          "networkx reference [s] | speed-up (runs) | max difference |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    ladder(args.budget)
    print(f"peak RSS {_rss_gb():.2f} GB")
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
