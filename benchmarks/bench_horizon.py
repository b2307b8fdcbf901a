"""steps_to_limit of three angles and their mix: one pass against a pass per policy.

    python -m benchmarks.bench_horizon                     # the two-room office, K = 72, cap 2000
    python -m benchmarks.bench_horizon --maps office,lab --orientations 360 --cap 500

For every map (event model; angles 30°, 75°, 315°, ε = 5°, r = 0.8, the mix α = (0.2, 0.3,
0.5) whose runs each keep one angle; docs/model.md §17): the wall time of the four
``steps_to_limit`` calls the CLI made before (one pass per angle, then one for the mix, which
runs every angle again) against one :func:`~planners.coverage.steps_to_limit_each` pass (the
mix read off the angles' runs, finished runs dropped), whether all four answers are
identical, and the per-step cost of the recursion's sparse products: the flights H with one
vector against H with a block of the three angles' vectors (per vector), and a turn (CPU
time). Measured: the block costs as much per vector as one product, so the passes keep one
vector per run.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from envs.generated import load_map
from planners.cells import CellSpace
from planners.coverage import (
    Horizon,
    TurnNoise,
    clear_cache,
    model_for,
    steps_to_limit,
    steps_to_limit_each,
)

ANGLES = (30.0, 75.0, 315.0)
ALPHA = np.array([0.2, 0.3, 0.5])
NOISE = TurnNoise(5.0, 0.8)


def product_ms(hz: Horizon, reps: int = 20) -> tuple[float, float, float]:
    """CPU [ms] of H·x, of H·X per vector (X: 3 vectors) and of one turn Wᵀ·x."""
    rec = hz._prepare(NOISE)
    H = rec.ts.H
    W = hz._turns([ANGLES[0]], NOISE, rec.offset)[0]
    rng = np.random.default_rng(0)
    X = rng.random((H.shape[1], 3), dtype=np.float32)
    x = np.ascontiguousarray(X[:, 0])
    y = rng.random(W.shape[1], dtype=np.float32)

    def ms(f):                            # CPU time: steadier than wall time on a busy machine
        f()
        t0 = time.process_time()
        for _ in range(reps):
            f()
        return (time.process_time() - t0) / reps * 1e3

    return ms(lambda: H @ x), ms(lambda: H @ X) / 3, ms(lambda: W @ y)


def main(argv=None) -> int:
    """Run the benchmark and print its table (exit status)."""
    ap = argparse.ArgumentParser(prog="python -m benchmarks.bench_horizon",
                                 description=__doc__.split("\n\n")[0])
    ap.add_argument("--maps", default="office")
    ap.add_argument("--orientations", type=int, default=72)
    ap.add_argument("--cap", type=int, default=2000, help="steps_to_limit cap [steps]")
    args = ap.parse_args(argv)
    print(f"K = {args.orientations}, angles 30/75/315 and their mix, eps 5°, r 0.8; "
          f"cap {args.cap} steps")
    print("| map | states | per policy [s] | one pass [s] | speed-up | identical | steps_to_limit "
          "| H·x [ms] | H·X per vector [ms] | turn [ms] |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for name in args.maps.split(","):
        clear_cache()
        cs = CellSpace(load_map(name, args.orientations))
        model = model_for(cs, "event")
        lims = [model.analyse(a, NOISE).q for a in ANGLES]
        mix_lim = np.column_stack(lims) @ ALPHA
        hz = Horizon(model)
        hz._prepare(NOISE)                     # both sides start from the built recursion
        t0 = time.perf_counter()
        old = [steps_to_limit(hz, [a], q, noise=NOISE, cap=args.cap)
               for a, q in zip(ANGLES, lims)]
        old.append(steps_to_limit(hz, ANGLES, mix_lim, noise=NOISE, alpha=ALPHA, cap=args.cap))
        t_old = time.perf_counter() - t0
        t0 = time.perf_counter()
        each, mix = steps_to_limit_each(hz, ANGLES, lims, noise=NOISE, alpha=ALPHA,
                                        mix_limit=mix_lim, cap=args.cap)
        t_new = time.perf_counter() - t0
        key = ("steps", "tv", "last")
        same = all(r[k] == s[k] for r, s in zip(old, [*each, mix]) for k in key)
        stl = " / ".join("—" if r["steps"] is None else str(r["steps"]) for r in old)
        hx, hX, wx = product_ms(hz)
        print(f"| {name} | {model.n_states} | {t_old:.1f} | {t_new:.1f} | "
              f"{t_old / t_new:.2f} | {same} | {stl} | {hx:.2f} | {hX:.2f} | {wx:.2f} |",
              flush=True)
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
