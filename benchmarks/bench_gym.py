"""Benchmark of the Gymnasium environment: bounces per second of ``BounceEnv.step`` against the
bare kinematic twin doing the same bounces (turn, drive until the bumper closes) in the same
run, so the table shows what the environment adds (observation, goal rule, visit counting).

Usage::

    python -m benchmarks.bench_gym                 # lab and complex, 3000 bounces each
    python -m benchmarks.bench_gym --bounces 10000
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

import envs
from bouncesim.gym import BounceEnv
from bouncesim.robots.factory import make_robot
from bouncesim.robots.noise import parse_noise

ANGLES = (45.0, 90.0, 135.0)


def bare_twin(room, noise: str, actions: np.ndarray) -> float:
    """Bounces per second of the twin alone: turn by the angle, drive until a bump."""
    cells_delta = 360.0 / room.orientations
    bot = make_robot("kinematic", room, noise=parse_noise(noise, cells_delta),
                     rng=np.random.default_rng(0))
    x0, y0, x1, y1 = room.bounds
    timeout = (math.hypot(x1 - x0, y1 - y0) + room.cell_size) / 0.2
    bot.drive_until_bump(0.2, timeout)
    t = time.perf_counter()
    for a in actions:
        bot.turn(ANGLES[a])
        bot.drive_until_bump(0.2, timeout)
    return len(actions) / (time.perf_counter() - t)


def environment(room, task: str, noise: str, actions: np.ndarray) -> float:
    """Bounces per second of ``BounceEnv.step`` (resets excluded from the clock)."""
    env = BounceEnv(room, task, angles=ANGLES, noise=noise, max_steps=len(actions) + 1)
    env.reset(seed=0)
    t = time.perf_counter()
    for a in actions:
        _, _, terminated, _, _ = env.step(int(a))
        if terminated:
            pause = time.perf_counter()
            env.reset()
            t += time.perf_counter() - pause
    return len(actions) / (time.perf_counter() - t)


def main(argv=None) -> int:
    """Print the table (bounces per second) for lab and complex, exact and noisy turns."""
    p = argparse.ArgumentParser(prog="python -m benchmarks.bench_gym", description=__doc__)
    p.add_argument("--bounces", type=int, default=3000)
    args = p.parse_args(argv)
    actions = np.random.default_rng(1).integers(len(ANGLES), size=args.bounces)
    print(f"{'env':8s} {'noise':20s} {'twin /s':>9s} {'navigate /s':>12s} {'cover /s':>9s}")
    for name in ("lab", "complex"):
        room = envs.load(name)
        for noise in ("none", "model:eps=45,r=0.9"):
            twin = bare_twin(room, noise, actions)
            nav = environment(room, "navigate", noise, actions)
            cov = environment(room, "cover", noise, actions)
            print(f"{name:8s} {noise:20s} {twin:9.0f} {nav:12.0f} {cov:9.0f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
