"""Gaussian turn noise in the event model against the kinematic twin, and what the Δ grid
changes (docs/model.md §11a).

    python -m benchmarks.bench_gauss                       # the catalogue at K = 360
    python -m benchmarks.bench_gauss --envs fig1 --twin-steps 4000000

For every map and angle (30°, 75°, 315°): TV between the event model with ``gauss:σ``
(σ = 3°) and a twin histogram with the same Gaussian noise (``--twin-steps`` steps in all,
``--robots`` robots from the uniform start, ``--burn-in`` steps per robot not counted,
seed 0), with the twin's noise floor (seed 0 against seed 1); then the grid noise of the
paper (ε = 5°, r = 0.8, variance 2.2 deg²) against Gaussian noise of the same variance
(σ = 1.48°): TV between the two event predictions, and each against the twin run with its
own noise. Times are CPU seconds (``time.process_time``) of the event model's solve of one
angle with Gaussian noise (the first angle includes casting its flights) and of one twin
run; the load average is printed with every row.
"""

from __future__ import annotations

import argparse
import math
import os
import time

import numpy as np

import envs
from planners.cells import CellSpace
from planners.coverage import TurnNoise, model_for
from planners.metrics import tv_distance

EPS, R = 5.0, 0.8


def matched_sigma(K: int) -> float:
    """σ [deg] of the Gaussian with the variance of the ε = 5°, r = 0.8 grid noise at K."""
    d, p = TurnNoise(EPS, R).support(K)
    return math.sqrt(float(p @ (d * 360.0 / K) ** 2))


def twin(cs: CellSpace, angle: float, steps: int, seed: int, noise, robots: int = 200,
         burn_in: int = 0) -> np.ndarray:
    """Visits per position cell of ``robots`` twin robots, ``steps`` counted steps in all."""
    from bouncesim.robots.kinematic import KinematicBatch
    return KinematicBatch(cs.env, robots, np.random.default_rng(seed), cells=cs).run(
        angle, max(1, steps // robots), noise=noise, burn_in=burn_in).counts


def main(argv=None) -> int:
    """Run the benchmark and print its tables (exit status)."""
    from bouncesim.robots.noise import GaussianNoise, SteppedNoise
    ap = argparse.ArgumentParser(prog="python -m benchmarks.bench_gauss",
                                 description=__doc__.split("\n\n")[0])
    ap.add_argument("--envs", default=",".join(envs.names()))
    ap.add_argument("--angles", default="30,75,315", help="commanded angles [deg]")
    ap.add_argument("--orientations", type=int, default=360)
    ap.add_argument("--sigma", type=float, default=3.0)
    ap.add_argument("--twin-steps", type=int, default=1_000_000,
                    help="counted twin steps per run, all robots together")
    ap.add_argument("--robots", type=int, default=200)
    ap.add_argument("--burn-in", type=int, default=0, help="twin steps per robot not counted")
    ap.add_argument("--no-grid", action="store_true",
                    help="skip the grid against same-variance Gaussian comparison")
    args = ap.parse_args(argv)
    angles = [float(a) for a in args.angles.split(",")]
    tw = dict(robots=args.robots, burn_in=args.burn_in)
    K = args.orientations
    sm = matched_sigma(K)
    print(f"K = {K}; gauss σ = {args.sigma:g}°; grid ε = {EPS:g}°, r = {R} against "
          f"σ = {sm:.3f}° (same variance); twin {args.twin_steps} steps per run, "
          f"{args.robots} robots, burn-in {args.burn_in}")
    print("| map | angle | event CPU [s] | twin CPU [s] | TV(event, twin) σ=3 | twin floor | "
          "TV(grid, gauss) event | TV(grid event, grid twin) | TV(gauss event, gauss twin) "
          "| load |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for name in args.envs.split(","):
        cs = CellSpace(envs.load(name, orientations=K))
        model = model_for(cs, "event")
        for a in angles:
            t0 = time.process_time()
            q3 = model.analyse(a, TurnNoise.gauss(args.sigma)).q
            sec = time.process_time() - t0
            t0 = time.process_time()
            h0 = twin(cs, a, args.twin_steps, 0, GaussianNoise(args.sigma), **tw)
            tsec = time.process_time() - t0
            h1 = twin(cs, a, args.twin_steps, 1, GaussianNoise(args.sigma), **tw)
            grid = "| – | – | – |"
            if not args.no_grid:
                qg = model.analyse(a, TurnNoise(EPS, R)).q
                qm = model.analyse(a, TurnNoise.gauss(sm)).q
                hg = twin(cs, a, args.twin_steps, 0, SteppedNoise(EPS, R, cs.delta_deg), **tw)
                hm = twin(cs, a, args.twin_steps, 0, GaussianNoise(sm), **tw)
                grid = (f"| {tv_distance(qg, qm):.3f} | {tv_distance(qg, hg):.3f} | "
                        f"{tv_distance(qm, hm):.3f} |")
            print(f"| {name} | {a:g} | {sec:.1f} | {tsec:.1f} | {tv_distance(q3, h0):.3f} | "
                  f"{tv_distance(h0, h1):.3f} {grid} {os.getloadavg()[0]:.1f} |", flush=True)
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
