"""Benchmark of the kinematic twin: robot-steps per second, single and batched.

A *robot-step* is one docs/model.md §8 step: a forward move of h, or a move to contact plus the
in-place rotation. Rows, per environment:

- ``shapely reference``: a straightforward per-robot stepper: ``env.segments_free`` decides
  whether the step of length h is free; if not, the contact is found by bisection on the
  shapely distance from the swept segment to the walls (45 halvings, 1e-14 m).
- ``KinematicRobot + execute``: one twin driven through the Robot interface by the
  coverage executor (what a Monte-Carlo run over the Robot interface costs).
- ``KinematicBatch``: the vectorised batch (capsule ray casts, numpy over robots x nearby
  walls), at several batch sizes.

The ``agree`` column checks the twin against the reference: the fraction of the reference's
steps for which the twin's capsule ray cast, from the very same state, moves the same distance
(within 1e-6 m). (Whole trajectories are not compared: they part ways chaotically after the
first rounding-level tie, e.g. a contact exactly on a cell border.)

Usage::

    python -m benchmarks.bench_twin                 # lab and complex
    python -m benchmarks.bench_twin --quick         # smaller budgets
    python -m benchmarks.bench_twin --envs lab --sizes 1,1000,100000
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import shapely

import envs
from bouncesim.robots.kinematic import KinematicBatch, KinematicRobot
from bouncesim.runs.execute import execute
from envs.motion import casters, drive_distance, step, unit
from planners.cells import CellSpace

ANGLE = 135.0


class ShapelyStepper:
    """The reference: one robot, one step at a time, with shapely distance queries."""

    def __init__(self, env, cells: CellSpace, z: int) -> None:
        self.env, self.cells = env, cells
        x, y, h = cells.pose(z)
        self.pos = np.array([x, y])
        self.heading = h
        self.r = env.robot_radius

    def _free(self, c, t, u) -> bool:
        seg = shapely.linestrings([c, c + t * u])
        return shapely.distance(seg, self.env.walls) >= self.r - self.env.tol

    def step(self, angle: float) -> tuple[int, float]:
        """One step; returns (counted cell, distance moved [m])."""
        h = self.cells.h
        c, u = self.pos, unit(self.heading)
        if self.env.segments_free(c[None], (c + h * u)[None])[0]:
            p = int(self.cells.cell_of_point(c[None])[0])
            self.pos = c + h * u
            return p, h
        lo, hi = 0.0, h
        for _ in range(45):
            mid = 0.5 * (lo + hi)
            if self._free(c, mid, u):
                lo = mid
            else:
                hi = mid
        move = drive_distance(lo)
        self.pos = c + move * u
        p = int(self.cells.cell_of_point(self.pos[None])[0])
        if not step(move, h)[1]:           # a contact at the full step is a forward step
            return int(self.cells.cell_of_point(c[None])[0]), move
        self.heading = (self.heading + angle) % 360.0
        return p, move


def _timed(fn):
    t = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - t


def bench_env(name: str, sizes, budget: int, ref_steps: int, seed: int,
              max_steps: int = 20_000) -> list[dict]:
    """Steps per second of the twin at each batch size in one environment, with its TV to a
    reference run.
    """
    env = envs.load(name)
    cells = CellSpace(env)
    rng = np.random.default_rng(seed)
    rows = []

    # reference: a few robots; every step's state is kept to check the twin against it
    n_ref = 4
    starts = rng.integers(0, cells.N, size=n_ref)
    per = max(1, ref_steps // n_ref)
    states, moves = [], []

    def run_ref():
        for z in starts:
            st = ShapelyStepper(env, cells, int(z))
            for _ in range(per):
                states.append((*st.pos, st.heading))
                moves.append(st.step(ANGLE)[1])
    _, dt = _timed(run_ref)
    ref_rate = n_ref * per / dt
    # agreement: from the reference's own states, the twin's capsule cast gives the same
    # step (the same move within 1e-6 m); trajectories themselves diverge chaotically
    # after the first rounding-level tie, so states are compared, not whole runs
    st = np.array(states)
    caster, _ = casters(env)
    free = caster.cast(st[:, :2], unit(st[:, 2]))
    twin_moves, _ = step(drive_distance(free), cells.h)
    agree = float(np.mean(np.abs(twin_moves - np.array(moves)) <= 1e-6))
    rows.append(dict(env=name, method="shapely reference", robots=1, steps=n_ref * per,
                     seconds=dt, rate=ref_rate, agree=f"{agree:.4f}"))

    # one twin through the Robot interface
    steps_robot = max(200, budget // 50)
    bot = KinematicRobot(env)
    _, dt = _timed(lambda: execute(ANGLE, bot, steps=steps_robot, epoch=steps_robot,
                                   rng=np.random.default_rng(seed),
                                   cells=cells, record_trace=False))
    rows.append(dict(env=name, method="KinematicRobot + execute", robots=1,
                     steps=steps_robot, seconds=dt, rate=steps_robot / dt, agree=""))

    for n in sizes:
        steps = min(max(20, budget // n), max_steps)
        b = KinematicBatch(env, n, np.random.default_rng(seed))
        b.run(ANGLE, 2)                                     # warm-up
        res, dt = _timed(lambda b=b, steps=steps: b.run(ANGLE, steps))
        rows.append(dict(env=name, method="KinematicBatch", robots=n, steps=res.total,
                         seconds=dt, rate=res.total / dt, agree=""))
    for r in rows:
        r["speedup"] = r["rate"] / ref_rate
    return rows


def main(argv=None) -> None:
    """Run the kinematic-twin benchmark and print the table."""
    ap = argparse.ArgumentParser(prog="python -m benchmarks.bench_twin", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--envs", default="lab,complex")
    ap.add_argument("--sizes", default="1,100,1000,10000")
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    sizes = [int(s) for s in args.sizes.split(",")]
    budget = 100_000 if args.quick else 1_000_000
    ref_steps = 200 if args.quick else 1000
    rows = []
    for name in args.envs.split(","):
        rows += bench_env(name, sizes, budget, ref_steps, args.seed)
    hdr = (f"{'env':<8} {'method':<30} {'robots':>7} {'robot-steps':>12} {'time [s]':>9} "
           f"{'robot-steps/s':>14} {'vs ref':>9} {'agree':>6}")
    print(hdr)
    print("-" * len(hdr))
    for r in rows:
        print(f"{r['env']:<8} {r['method']:<30} {r['robots']:>7} {r['steps']:>12,} "
              f"{r['seconds']:>9.2f} {r['rate']:>14,.0f} {r['speedup']:>8.0f}x "
              f"{r['agree']:>6}")
    print(f"\nangle {ANGLE:g}°, no noise. 'agree': fraction of the reference's steps for which "
          f"the twin's ray cast from the same state moves the same distance (within 1e-6 m).")


if __name__ == "__main__":
    main()
