"""steps_to_limit of three angles and their mix: one pass against a pass per policy; and the
CLI's whole ``--horizon`` pipeline: one thread, split steps, and runs beside the analyses.

    python -m benchmarks.bench_horizon                     # the two-room office, K = 72, cap 2000
    python -m benchmarks.bench_horizon --maps office,lab --orientations 360 --cap 500
    python -m benchmarks.bench_horizon --pipeline --maps lab,complex,fig1,office \
        --orientations 360 --threads 2

For every map (event model; angles 30°, 75°, 315°, ε = 5°, r = 0.8, the mix α = (0.2, 0.3,
0.5) whose runs each keep one angle; docs/model.md §20): the wall time of the four
``steps_to_limit`` calls the CLI made before (one pass per angle, then one for the mix, which
runs every angle again) against one :func:`~planners.coverage.steps_to_limit_each` pass (the
mix read off the angles' runs, finished runs dropped), whether all four answers are
identical, and the per-step cost of the recursion's sparse products: the flights H with one
vector against H with a block of the three angles' vectors (per vector), and a step's two
products over every state against over the states mass can land in, and the flights' product
read from the D·n departures against from the compact rings the recursion keeps (CPU time).
Measured: the block costs as much per vector as one product, so the passes keep one vector
per run.

``--pipeline`` times what ``bouncesim coverage MAP --model event --horizon 2000`` computes
(angles 30°, 75°, 315°, ε = 5°, r = 0.8, uniform target): the model's build, then the three
angles' limits and α fitted to their q_T (docs/model.md §20) three ways in the same run:
*one thread* for everything; the limits on threads and *then* the runs, each step split into
row blocks over the cores (the CLI before runs went beside the analyses); and *now*,
:func:`~planners.coverage.design_mix` with the horizon, whose runs go on the analyses'
threads from the start. Then the ``steps_to_limit`` report of the angles and the mix, which
resumes the kept runs, with the CLI's defaults (cap 10⁷ steps, 60 s per policy). Wall and
CPU seconds, the load average, and whether α and the q_T columns agree bitwise all three
ways. ``--threads N`` fixes the thread count of the ways that use threads (default: the idle
cores by the load average, :func:`planners.coverage.timeshare.default_threads`);
``--now-only`` times only the CLI's way, without the report (for the speed goal: build +
limits + q_T).
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np
import scipy.sparse as sp

import planners.coverage.api as api
import planners.coverage.timeshare as timeshare
from envs.generated import load_map
from planners.cells import CellSpace
from planners.coverage import (
    Horizon,
    TurnNoise,
    analyses,
    clear_cache,
    design_mix,
    horizon_of,
    model_for,
    steps_to_limit,
    steps_to_limit_each,
)
from planners.coverage.horizon import fit_horizon_mix
from planners.coverage.targets import check_target

ANGLES = (30.0, 75.0, 315.0)
ALPHA = np.array([0.2, 0.3, 0.5])
NOISE = TurnNoise(5.0, 0.8)
LIMIT_SECONDS = 60.0       # the CLI's --limit-seconds default (per policy)


def product_ms(hz: Horizon, reps: int = 20) -> tuple[float, ...]:
    """CPU [ms] of H·x, of H·X per vector (X: 3 vectors), of one step's two products
    (flights, then the turn) over every state against over the states mass can land in
    (:attr:`planners.coverage.timeshare.TimeShared.live`), and of the flights' product on the live
    states read from the D·n departures (the straightforward way) against the compact rings
    the recursion uses (:attr:`~planners.coverage.timeshare.TimeShared.Hc`, with the step's copies
    into the product's vector and its gathers of v into the rings); then one whole step of
    the recursion as it was (those flights, the turn to v on all n states, Σ v in float64)
    against now (the flights from the ring of the sources' v, the turn straight to the
    sources' v by Wᵀ's stacked rows, Σ x in float64), and
    :meth:`~planners.coverage.timeshare.TimeShared.advance` per step over 100 steps (one thread).
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

    H_live = sp.csr_matrix(H[ts.live])
    v = x[:ts.chain.n]
    w = np.empty(ts.Hc.shape[1], dtype=np.float32)
    rings = {j: np.empty((j + 1, S.size), dtype=np.float32) for j, _, _, S in ts._lags}

    def compact():                        # what one step of the recursion does for x_t
        for j, a, b, _ in ts._lags:
            w[a:b] = rings[j][0]
        y = ts.Hc @ w
        for j, _, _, S in ts._lags:
            np.take(v, S, out=rings[j][0])
        return y

    dep = np.zeros(ts.chain.n)

    def step_before():                    # x_t, then v_t on all states, Σ v_t
        v[:] = W_live @ compact()
        dep[:] += v

    WS = ts._stacked(W_live)
    U = rng.random((ts.D, ts.Hc.shape[1]), dtype=np.float32)
    xs = np.zeros(ts.live.size)

    def step_now():                       # x_t from the sources' ring, v_t on the sources
        for j, a, b, _ in ts._lags:
            w[a:b] = U[(-1 - j) % ts.D, a:b]
        y = ts.Hc @ w
        xs[:] += y
        U[0] = WS @ y

    hist = np.zeros((ts.D, ts.chain.n), dtype=np.float32)
    hist[0, rec.offset:] = 1.0 / (ts.chain.n - rec.offset)
    c0 = time.process_time()
    ts.advance(W_live, hist, 100, threads=1)
    adv = (time.process_time() - c0) / 100 * 1e3
    return (ms(lambda: H @ x), ms(lambda: H @ X) / 3, ms(lambda: W_all @ (H @ x)),
            ms(lambda: W_live @ (H_live @ x)), ms(lambda: H_live @ x), ms(compact),
            ms(step_before), ms(step_now), adv)


def _clock() -> tuple[float, float]:
    return time.perf_counter(), time.process_time()


def _since(t: tuple[float, float]) -> tuple[float, float]:
    return time.perf_counter() - t[0], time.process_time() - t[1]


def _limits_and_horizon(model, way: str, T: int, target):
    """The angles' limits and α fitted to their q_T, one of three ways (see ``--pipeline``);
    returns (MixDesign or its fit, the Horizon that holds the runs).
    """
    if way == "now":                          # the CLI's call
        hz = horizon_of(model)
        return design_mix(model, ANGLES, NOISE, target=target, horizon=T), hz
    hz = Horizon(model)
    per = tuple(analyses(model, ANGLES, NOISE))
    b = check_target(target, model.cs, "positions")          # as design_mix normalises it
    return fit_horizon_mix(hz, ANGLES, NOISE, b, T, None, per), hz


WAYS = ("one thread", "split steps", "now")


def pipeline_row(name: str, K: int, T: int, threads: int | None = None,
                 now_only: bool = False) -> str:
    """One ``--pipeline`` row (see the module docstring); ``threads`` fixes the thread count
    of the ways that split (default: :func:`planners.coverage.timeshare.default_threads`);
    ``now_only``: only the CLI's way, and no steps_to_limit report ("—" in those columns).
    """
    clear_cache()
    t = _clock()
    model = model_for(CellSpace(load_map(name, K)), "event")
    build = _since(t)
    target = np.full(model.cs.P, 1.0 / model.cs.P)
    out = {}
    for way in ("now",) if now_only else WAYS:
        saved = timeshare.default_threads, api.default_threads
        if way == "one thread" or threads:
            timeshare.default_threads = api.default_threads = (
                lambda n=1 if way == "one thread" else threads: n)
        try:
            t = _clock()
            fit, hz = _limits_and_horizon(model, way, T, target)
            out[way] = (_since(t), fit)
        finally:
            timeshare.default_threads, api.default_threads = saved
    k = threads or timeshare.default_threads()    # what "now" used (it follows the load)
    fit = out["now"][1]
    lims = [a.q for a in fit.per_angle]
    load = os.getloadavg()[0]
    if now_only:
        stl_s, stl = "—", "—"
    else:
        t = _clock()
        each, mix = steps_to_limit_each(hz, ANGLES, lims, noise=NOISE, alpha=fit.alpha,
                                        mix_limit=np.column_stack(lims) @ fit.alpha,
                                        max_seconds=LIMIT_SECONDS)
        stl_s = f"{_since(t)[0]:.1f}"
        stl = " / ".join("—" if r["steps"] is None else str(r["steps"]) for r in [*each, mix])
    same = all(np.array_equal(o[1].alpha, fit.alpha) and np.array_equal(o[1].columns, fit.columns)
               for o in out.values()) if len(out) > 1 else "—"
    w = {way: v[0] for way, v in out.items()}
    return (f"| {name} | {model.n_states} | {build[0]:.1f} | "
            + " | ".join(f"{w[x][0]:.1f} / {w[x][1]:.1f}" if x in w else "—" for x in WAYS)
            + f" | **{build[0] + w['now'][0]:.1f}** | {same} | {stl_s} | {stl} | {k} "
            f"| {load:.1f} |")


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
    ap.add_argument("--now-only", action="store_true",
                    help="--pipeline: time only the CLI's way, without the steps_to_limit report")
    ap.add_argument("--threads", type=int, default=None,
                    help="--pipeline's thread count (default: the idle cores by the load)")
    args = ap.parse_args(argv)
    if args.pipeline:
        print(f"K = {args.orientations}, angles 30/75/315, eps 5°, r 0.8, T = {args.horizon}; "
              "wall / CPU seconds")
        print("| map | states | build | limits + q_T, one thread | limits, then q_T split "
              "| limits and q_T side by side (now) | build + limits + q_T now, wall "
              "| identical | steps_to_limit now | steps_to_limit (30° / 75° / 315° / mix) "
              "| threads now | load |")
        print("|---|---|---|---|---|---|---|---|---|---|---|---|")
        for name in args.maps.split(","):
            print(pipeline_row(name, args.orientations, args.horizon, args.threads,
                               args.now_only), flush=True)
        return 0
    print(f"K = {args.orientations}, angles 30/75/315 and their mix, eps 5°, r 0.8; "
          f"cap {args.cap} steps")
    print("| map | states | per policy [s] | one pass [s] | speed-up | identical | steps_to_limit "
          "| H·x [ms] | H·X per vector [ms] | step, all states [ms] | step, live states [ms] "
          "| flights from D·n [ms] | flights, compact [ms] | step before [ms] | step now [ms] "
          "| advance per step [ms] |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
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
        hx, hX, step_all, step_live, fl_window, fl_compact, before, now, adv = product_ms(hz)
        print(f"| {name} | {model.n_states} | {t_old:.1f} | {t_new:.1f} | "
              f"{t_old / t_new:.2f} | {same} | {stl} | {hx:.2f} | {hX:.2f} | {step_all:.2f} "
              f"| {step_live:.2f} | {fl_window:.2f} | {fl_compact:.2f} | {before:.2f} "
              f"| {now:.2f} | {adv:.2f} |", flush=True)
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
