"""steps_to_limit of three angles and their mix: one pass against a pass per policy; and the
CLI's whole ``--horizon`` pipeline before and after kept runs and split steps.

    python -m benchmarks.bench_horizon                     # the two-room office, K = 72, cap 2000
    python -m benchmarks.bench_horizon --maps office,lab --orientations 360 --cap 500
    python -m benchmarks.bench_horizon --pipeline --maps lab,fig1,office,complex --orientations 360

For every map (event model; angles 30°, 75°, 315°, ε = 5°, r = 0.8, the mix α = (0.2, 0.3,
0.5) whose runs each keep one angle; docs/model.md §17): the wall time of the four
``steps_to_limit`` calls the CLI made before (one pass per angle, then one for the mix, which
runs every angle again) against one :func:`~planners.coverage.steps_to_limit_each` pass (the
mix read off the angles' runs, finished runs dropped), whether all four answers are
identical, and the per-step cost of the recursion's sparse products: the flights H with one
vector against H with a block of the three angles' vectors (per vector), and a step's two
products over every state against over the states mass can land in (CPU time). Measured:
the block costs as much per vector as one product, so the passes keep one vector per run.

``--pipeline`` times what ``bouncesim coverage MAP --model event --horizon 2000`` computes
(angles 30°, 75°, 315°, ε = 5°, r = 0.8, uniform target): the model's build, the three
angles' limits, then the horizon part (α fitted to the angles' q_T, docs/model.md §17, and
the ``steps_to_limit`` report of the angles and the mix) two ways in the same run: *before*,
as the CLI did it (one :class:`~planners.coverage.Horizon` for the fit and a fresh one for
the report, every step on one thread), and *now* (the model's shared Horizon, whose kept runs
the report resumes, every step split over the cores, :func:`planners.timeshare.default_threads`),
with the CLI's defaults (cap 10⁷ steps, 60 s per policy). Wall and CPU seconds, the load
average, and whether α and the steps_to_limit found both ways agree.
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np
import scipy.sparse as sp

import planners.timeshare as timeshare
from envs.generated import load_map
from planners.cells import CellSpace
from planners.coverage import (
    Horizon,
    TurnNoise,
    analyses,
    clear_cache,
    horizon_of,
    model_for,
    steps_to_limit,
    steps_to_limit_each,
)
from planners.coverage.horizon import fit_horizon_mix

ANGLES = (30.0, 75.0, 315.0)
ALPHA = np.array([0.2, 0.3, 0.5])
NOISE = TurnNoise(5.0, 0.8)
LIMIT_SECONDS = 60.0       # the CLI's --limit-seconds default (per policy)


def product_ms(hz: Horizon, reps: int = 20) -> tuple[float, float, float, float]:
    """CPU [ms] of H·x, of H·X per vector (X: 3 vectors), and of one step's two products
    (flights, then the turn) over every state against over the states mass can land in
    (:attr:`planners.timeshare.TimeShared.live`), which the recursion uses.
    """
    rec = hz._prepare(NOISE)
    ts = rec.ts
    H = ts.H
    W = hz.model.turn_matrix(ANGLES[0], NOISE)
    if rec.offset:
        W = sp.block_diag((W, sp.csr_matrix((hz.model.cs.N,) * 2)), format="csr")
    W_all = sp.csr_matrix(W.T).astype(np.float32)
    W_live = ts.turn(W)
    rng = np.random.default_rng(0)
    X = rng.random((H.shape[1], 3), dtype=np.float32)
    x = np.ascontiguousarray(X[:, 0])

    def ms(f):                            # CPU time: steadier than wall time on a busy machine
        f()
        t0 = time.process_time()
        for _ in range(reps):
            f()
        return (time.process_time() - t0) / reps * 1e3

    return (ms(lambda: H @ x), ms(lambda: H @ X) / 3, ms(lambda: W_all @ (H @ x)),
            ms(lambda: W_live @ (ts.H_live @ x)))


def _clock() -> tuple[float, float]:
    return time.perf_counter(), time.process_time()


def _since(t: tuple[float, float]) -> tuple[float, float]:
    return time.perf_counter() - t[0], time.process_time() - t[1]


def pipeline_row(name: str, K: int, T: int) -> str:
    """One ``--pipeline`` row (see the module docstring)."""
    clear_cache()
    t = _clock()
    model = model_for(CellSpace(load_map(name, K)), "event")
    build = _since(t)
    t = _clock()
    per = tuple(analyses(model, ANGLES, NOISE))
    limits = _since(t)
    lims = [a.q for a in per]
    target = np.full(model.cs.P, 1.0 / model.cs.P)
    out = {}
    for way in ("before", "now"):
        threads = timeshare.default_threads
        if way == "before":
            timeshare.default_threads = lambda: 1
        try:
            t = _clock()
            hz = Horizon(model) if way == "before" else horizon_of(model)
            fit = fit_horizon_mix(hz, ANGLES, NOISE, target, T, None, per)
            t_fit = _since(t)
            t = _clock()
            hz = Horizon(model) if way == "before" else hz
            each, mix = steps_to_limit_each(hz, ANGLES, lims, noise=NOISE, alpha=fit.alpha,
                                            mix_limit=np.column_stack(lims) @ fit.alpha,
                                            max_seconds=LIMIT_SECONDS)
            out[way] = (t_fit, _since(t), fit.alpha, [r["steps"] for r in [*each, mix]])
        finally:
            timeshare.default_threads = threads
    k = timeshare.default_threads()          # what "now" used (it follows the load)
    fb, rb, ab, sb = out["before"]
    fn, rn, an, sn = out["now"]
    # a policy the time budget stopped on one side has no steps there: compare the others
    same = bool(np.array_equal(ab, an)
                and all(b == n for b, n in zip(sb, sn) if b is not None and n is not None))
    load = os.getloadavg()[0]
    stl = " / ".join("—" if s is None else str(s) for s in sn)
    return (f"| {name} | {model.n_states} | {build[0]:.1f} | {limits[0]:.1f} / {limits[1]:.1f} "
            f"| {fb[0]:.1f} / {fb[1]:.1f} | {fn[0]:.1f} / {fn[1]:.1f} "
            f"| {build[0] + limits[0] + fn[0]:.1f} | {rb[0]:.1f} | {rn[0]:.1f} | {same} "
            f"| {stl} | {k} | {load:.1f} |")


def main(argv=None) -> int:
    """Run the benchmark and print its table (exit status)."""
    ap = argparse.ArgumentParser(prog="python -m benchmarks.bench_horizon",
                                 description=__doc__.split("\n\n")[0])
    ap.add_argument("--maps", default="office")
    ap.add_argument("--orientations", type=int, default=72)
    ap.add_argument("--cap", type=int, default=2000, help="steps_to_limit cap [steps]")
    ap.add_argument("--pipeline", action="store_true",
                    help="time the CLI's --horizon pipeline before and now (see above)")
    ap.add_argument("--horizon", type=int, default=2000, help="--pipeline's T [steps]")
    args = ap.parse_args(argv)
    if args.pipeline:
        print(f"K = {args.orientations}, angles 30/75/315, eps 5°, r 0.8, T = {args.horizon}; "
              "wall / CPU seconds")
        print("| map | states | build | limits | q_T before | q_T now | build + limits + q_T "
              "now, wall | steps_to_limit before | steps_to_limit now | identical "
              "| steps_to_limit (30° / 75° / 315° / mix) | threads now | load |")
        print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
        for name in args.maps.split(","):
            print(pipeline_row(name, args.orientations, args.horizon), flush=True)
        return 0
    print(f"K = {args.orientations}, angles 30/75/315 and their mix, eps 5°, r 0.8; "
          f"cap {args.cap} steps")
    print("| map | states | per policy [s] | one pass [s] | speed-up | identical | steps_to_limit "
          "| H·x [ms] | H·X per vector [ms] | step, all states [ms] | step, live states [ms] |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for name in args.maps.split(","):
        clear_cache()
        cs = CellSpace(load_map(name, args.orientations))
        model = model_for(cs, "event")
        lims = [model.analyse(a, NOISE).q for a in ANGLES]
        mix_lim = np.column_stack(lims) @ ALPHA
        hz = Horizon(model)
        hz._prepare(NOISE)                     # every side starts from the built recursion

        def fresh(model=model, hz=hz) -> Horizon:   # no kept runs: each pass from step 0
            h = Horizon(model)
            h._prepared = hz._prepared
            return h

        t0 = time.perf_counter()
        old = [steps_to_limit(fresh(), [a], q, noise=NOISE, cap=args.cap)
               for a, q in zip(ANGLES, lims)]
        old.append(steps_to_limit(fresh(), ANGLES, mix_lim, noise=NOISE, alpha=ALPHA,
                                  cap=args.cap))
        t_old = time.perf_counter() - t0
        t0 = time.perf_counter()
        each, mix = steps_to_limit_each(fresh(), ANGLES, lims, noise=NOISE, alpha=ALPHA,
                                        mix_limit=mix_lim, cap=args.cap)
        t_new = time.perf_counter() - t0
        key = ("steps", "tv", "last")
        same = all(r[k] == s[k] for r, s in zip(old, [*each, mix]) for k in key)
        stl = " / ".join("—" if r["steps"] is None else str(r["steps"]) for r in old)
        hx, hX, step_all, step_live = product_ms(hz)
        print(f"| {name} | {model.n_states} | {t_old:.1f} | {t_new:.1f} | "
              f"{t_old / t_new:.2f} | {same} | {stl} | {hx:.2f} | {hX:.2f} | {step_all:.2f} "
              f"| {step_live:.2f} |",
              flush=True)
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
