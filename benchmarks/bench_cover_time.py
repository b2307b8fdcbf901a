"""Coverage-time metrics (docs/model.md §20a): the compiled sampler on one core against all
cores, in the same run.

    python -m benchmarks.bench_cover_time                       # 198 cells, K = 360
    python -m benchmarks.bench_cover_time --map experiments/maps/two_room.json   # 87 cells

For the map (default: the 198-cell two-room map of ``experiments.cover_time``,
:func:`envs.generated.big_two_room`; event
model, ε = 5°, r = 0.8, angles 30°, 75°, 315°, one robot and a team of four, a horizon of
20 000 steps, 1000 sampled runs per record: what ``bouncesim coverage MAP --metrics
--robots 4`` samples for the angles): the wall time of
:func:`~planners.coverage.cover_time.coverage_metrics` with numba's threads set to 1 and to
every core (after a warm-up call that compiles), and whether the records agree bitwise (run
i draws from its own seed whichever thread samples it, so they must).
"""

from __future__ import annotations

import argparse
import time

import numba
import numpy as np

from envs import Environment
from envs.generated import big_two_room
from planners.cells import CellSpace
from planners.coverage import TurnNoise, model_for
from planners.coverage.cover_time import coverage_metrics

ANGLES = (30.0, 75.0, 315.0)


def main(argv=None) -> int:
    """Time the sampler on one thread and on all; print the table (exit status)."""
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--map", default=None, help="a map file (default: the 198-cell two rooms)")
    p.add_argument("--runs", type=int, default=1000)
    p.add_argument("--horizon", type=int, default=20_000)
    args = p.parse_args(argv)
    env = big_two_room(360) if args.map is None else Environment.from_file(args.map)
    cs = CellSpace(env)
    model = model_for(cs, "event")
    noise = TurnNoise(5.0, 0.8)
    kw = {"robots": [1, 4], "horizon": args.horizon, "runs": args.runs, "exact": False}
    coverage_metrics(model, ANGLES[0], noise, **{**kw, "runs": 2, "horizon": 10}, rng=0)
    cores = numba.config.NUMBA_NUM_THREADS
    rows, out = [], {}
    for threads in (1, cores):
        numba.set_num_threads(threads)
        t0 = time.perf_counter()
        out[threads] = coverage_metrics(model, ANGLES, noise, rng=1, **kw)
        rows.append((threads, time.perf_counter() - t0))
    numba.set_num_threads(cores)
    same = all(np.array_equal(a.covered_mean, b.covered_mean) and a.T == b.T
               and a.idleness_worst == b.idleness_worst
               for a, b in zip(out[1], out[cores], strict=True))
    print(f"{env.name}: {cs.P} cells, K = {cs.K}, {len(ANGLES)} angles x teams of 1 and 4, "
          f"{args.runs} runs of {args.horizon} steps per record")
    print("| numba threads | wall [s] |\n|---|---|")
    for threads, wall in rows:
        print(f"| {threads} | {wall:.1f} |")
    print(f"records identical: {same}")
    return 0 if same else 1


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
