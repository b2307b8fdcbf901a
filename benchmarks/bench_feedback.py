"""Feedback navigation's decision time per bump (docs/model.md §22), beside one cold exact
query (the open-loop planner, §15) measured in the same run.

    python -m benchmarks.bench_feedback [--env lab] [--sigma 2] [--pairs 10] [--seed 0]

Runs ``--pairs`` seeded feedback runs in the kinematic twin with Gaussian turn noise σ and
prints the decision time per bump (filter update, planning from the belief, scoring, the
final drive) in CPU time of this process and in wall time: median, 95th percentile and
maximum, against the 50 ms target, and one cold ``ExactNavigator.plan`` query from each
run's start (mean CPU time). CPU time is shown because on a shared machine wall time is
mostly waiting.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import envs
from bouncesim.navigate import navigate_feedback
from bouncesim.robots.kinematic import KinematicRobot
from bouncesim.robots.noise import GaussianNoise
from planners.cells import CellSpace
from planners.exact import ExactNavigator

TARGET_MS = 50.0
ANGLES = (45.0, 90.0, 135.0)


def main(argv=None) -> None:
    """Run the benchmark and print the table."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--env", default="lab")
    ap.add_argument("--sigma", type=float, default=2.0, help="Gaussian turn noise [deg]")
    ap.add_argument("--pairs", type=int, default=10)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    env = envs.load(args.env)
    cells = CellSpace(env)
    rng = np.random.default_rng(args.seed)
    pairs = []
    while len(pairs) < args.pairs:
        s, g = (int(v) for v in rng.integers(0, cells.N, 2))
        if s != g and ExactNavigator(cells, ANGLES).plan(s, g) is not None:
            pairs.append((s, g))
    noise = GaussianNoise(args.sigma)
    cpu, wall, query, ok = [], [], [], 0
    for i, (s, g) in enumerate(pairs):
        c0 = time.process_time()
        ExactNavigator(cells, ANGLES).plan(s, g)          # cold: a fresh navigator
        query.append(1e3 * (time.process_time() - c0))
        run = navigate_feedback(KinematicRobot(env, noise, i), env, s, g, noise,
                                np.random.default_rng([args.seed, i]), angles=ANGLES,
                                cells=cells)
        cpu += list(run.decision_cpu_ms)
        wall += list(run.decision_ms)
        ok += bool(run.success)
    cpu, wall = np.asarray(cpu), np.asarray(wall)
    print(f"{args.env}, σ = {args.sigma:g}°, {len(pairs)} runs ({ok} reached the goal), "
          f"{len(cpu)} decisions")
    print(f"{'':32s}{'median':>9s}{'p95':>9s}{'max':>9s}")
    for name, v in (("decision per bump, CPU [ms]", cpu), ("decision per bump, wall [ms]", wall)):
        print(f"{name:32s}{np.median(v):9.1f}{np.percentile(v, 95):9.1f}{v.max():9.1f}")
    print(f"{'one cold exact query, CPU [ms]':32s}{np.median(query):9.1f}"
          f"{np.percentile(query, 95):9.1f}{max(query):9.1f}")
    share = float(np.mean(cpu <= TARGET_MS))
    print(f"decisions within the {TARGET_MS:g} ms target (CPU): {share:.1%}")


if __name__ == "__main__":
    main()
