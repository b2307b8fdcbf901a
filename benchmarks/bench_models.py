"""Speed and accuracy of the coverage models on Table I's setting, side by side.

    python -m benchmarks.bench_models                 # complex, K = 360, 0.34 m cells
    python -m benchmarks.bench_models --env lab --twin-steps 1000000
    python -m benchmarks.bench_models --env office-pinhole   # the slowly mixing two rooms

For each model (step = the paper's chain and the straightforward reference; sampled =
generalized cell mapping; event = bump-to-bump) at its default settings: the wall and CPU
time to compute the three chains (30°, 75°, 315°, ε = 5°, r = 0.8) and the policy mix α for
the uniform target, the largest TV over the three angles between the predicted coverage and
a kinematic-twin histogram (``--twin-steps`` per angle, seed 0), and the resulting α. The
twin's seed-to-seed noise floor is printed under the table. The last timing column is the
mix's time-shared coverage in ``--epoch``-step epochs (:mod:`planners.coverage.timeshare`), computed
after the pipeline (its model already built). Each model runs in a fresh state (no cached
flights), one after the other in the same process.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from envs.generated import load_map
from planners.cells import CellSpace
from planners.coverage import (
    MODELS,
    TurnNoise,
    clear_cache,
    design_mix,
    model_for,
    timeshared_coverage,
)
from planners.metrics import tv_distance

ANGLES = (30.0, 75.0, 315.0)
EPS, R = 5.0, 0.8



def twin_counts(cs: CellSpace, angle: float, steps: int, seed: int) -> np.ndarray:
    """Visits per position cell of 200 twin robots at one angle [§11 noise], ``steps`` steps
    each.
    """
    from bouncesim.robots.kinematic import KinematicBatch
    from bouncesim.robots.noise import SteppedNoise
    n = 200
    res = KinematicBatch(cs.env, n, np.random.default_rng(seed), cells=cs).run(
        angle, max(1, steps // n), noise=SteppedNoise(EPS, R, cs.delta_deg))
    return res.counts


def main(argv=None) -> int:
    """Run the model benchmark and print its table (exit status)."""
    ap = argparse.ArgumentParser(prog="python -m benchmarks.bench_models",
                                 description=__doc__.split("\n\n")[0])
    ap.add_argument("--env", default="complex",
                    help="a catalogue map or a map of envs.generated (office, office-pinhole, "
                    "office-wide)")
    ap.add_argument("--orientations", type=int, default=360)
    ap.add_argument("--twin-steps", type=int, default=2_000_000,
                    help="twin steps per angle for the accuracy column (default 2e6)")
    ap.add_argument("--models", default=",".join(MODELS),
                    help=f"comma-separated coverage models (default {','.join(MODELS)})")
    ap.add_argument("--epoch", type=int, default=1000,
                    help="steps per epoch of the time-shared mix column (default 1000; 0 skips)")
    args = ap.parse_args(argv)
    rows = []
    cs0 = CellSpace(load_map(args.env, args.orientations))
    _ = cs0.forward
    hist = {a: twin_counts(cs0, a, args.twin_steps, 0) for a in ANGLES}
    floor = max(tv_distance(hist[a], twin_counts(cs0, a, args.twin_steps, 1)) for a in ANGLES)
    for model in args.models.split(","):
        clear_cache()
        cs = CellSpace(load_map(args.env, args.orientations))
        w0, c0 = time.perf_counter(), time.process_time()
        _ = cs.forward
        cm = model_for(cs, model)
        res = design_mix(cm, ANGLES, TurnNoise(EPS, R))
        wall, cpu = time.perf_counter() - w0, time.process_time() - c0
        tv = max(tv_distance(ac.q, hist[a]) for a, ac in zip(ANGLES, res.per_angle))
        mix_wall = float("nan")
        if args.epoch > 0:
            w1 = time.perf_counter()
            timeshared_coverage(cm, res.mix, epoch=args.epoch)
            mix_wall = time.perf_counter() - w1
        rows.append((model, wall, cpu, tv, res.alpha, mix_wall))
    print(f"{args.env}, K = {args.orientations}, P = {cs0.P}, N = {cs0.N}; angles 30/75/315, "
          f"eps {EPS:g}°, r {R}; twin {args.twin_steps} steps per angle")
    print(f"{'model':>8} {'wall [s]':>9} {'CPU [s]':>8} {'vs step':>8} {'max TV':>7} "
          f"{'mix in epochs [s]':>18}  alpha")
    base = rows[0][1] if rows and rows[0][0] == "step" else None
    for model, wall, cpu, tv, alpha, mix_wall in rows:
        rel = f"{wall / base:7.1f}x" if base else "     -"
        print(f"{model:>8} {wall:9.2f} {cpu:8.2f} {rel:>8} {tv:7.3f} {mix_wall:18.2f}  "
              + " / ".join(f"{a:.3f}" for a in alpha))
    print(f"twin noise floor (seed 0 vs seed 1, max over angles): TV {floor:.3f}")
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
