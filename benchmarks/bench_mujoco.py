"""Speed and accuracy of the MuJoCo Create 2 beside the PyBullet one, measured in the same run.

    python -m benchmarks.bench_mujoco [--env lab] [--sim-seconds 300] [--angle 135]
                                      [--budget 4000] [--robots 16]

Table 1, one robot, the bounce loop: from the centre of cell 0 facing east, drive at 0.2 m/s
until the bumper closes, turn CCW by ``--angle`` by clock, repeat for ``--sim-seconds`` of
simulated time. Columns: ``rt CPU`` (simulated seconds per CPU second of this process, the
robot's construction not timed), ``bounces/CPU s``, ``gap mean/min [mm]`` (body edge to the
nearest wall at each bump, from the exact polygons; negative = overlap) and ``turn |err|
[deg]`` (heading change against the commanded turn, mean and max).

Table 2, coverage steps (docs/model.md §8) per CPU second at 75°, ε = 5°, r = 0.8, K = 72,
0.3 m/s, about ``--budget`` robot-steps per row: ``execute`` on one robot, and a batch world
of ``--robots`` robots that ignore each other (PyBullet every physics step and with its
fast-forward, MuJoCo every physics step).
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np
import shapely

import envs


def bounce_loop(bot, sim_seconds: float, angle: float, speed: float = 0.2):
    """(CPU seconds, bounces, gaps [m], turn errors [deg]) of the bounce loop on ``bot``."""
    walls = bot.env.walls
    gaps, errs = [], []
    c0 = time.process_time()
    while bot.clock() < sim_seconds:
        ev = bot.drive_until_bump(speed, sim_seconds - bot.clock() + 1e-9)
        if not ev.bumped:
            break
        x, y, h0 = bot.true_pose()
        gaps.append(shapely.distance(shapely.points(x, y), walls) - bot.body_radius)
        bot.turn(angle)
        errs.append((bot.true_pose()[2] - h0 - angle + 180) % 360 - 180)
    return time.process_time() - c0, len(gaps), np.array(gaps), np.abs(errs)


def _bodies():
    from bouncesim.robots.mujoco import MuJoCoRobot
    from bouncesim.robots.pybullet import PyBulletRobot
    return (("PyBullet (Dantzig, 200 Hz)", PyBulletRobot),
            ("MuJoCo (elliptic cone, 200 Hz)", MuJoCoRobot))


def table_bounce(env_name: str, sim_seconds: float, angle: float) -> None:
    """Print table 1."""
    print(f"Table 1: bounce loop on {env_name}, {angle:g}° turns, {sim_seconds:g} s simulated, "
          f"0.2 m/s")
    print(f"{'body':<32} {'rt CPU':>7} {'bounces/CPU s':>13} {'bounces':>7} "
          f"{'gap mean/min [mm]':>17} {'turn |err| mean/max':>19}")
    for label, cls in _bodies():
        with cls(env_name) as bot:
            cpu, n, gaps, errs = bounce_loop(bot, sim_seconds, angle)
        print(f"{label:<32} {bot.clock() / cpu:7.0f} {n / cpu:13.1f} {n:7d} "
              f"{gaps.mean() * 1e3:8.2f}/{gaps.min() * 1e3:<8.2f} "
              f"{errs.mean():9.2f}/{errs.max():<9.2f}")


def _mix_setup(env_name: str):
    from planners.cells import CellSpace
    from planners.plan import PolicyMix
    env = envs.load(env_name, orientations=72)
    return env, CellSpace(env), PolicyMix((75.0,), (1.0,), 5.0, 0.8)


def single_rate(cls, env_name: str, steps: int, seed: int = 0) -> tuple[float, float]:
    """(steps per CPU second, bumps per step) of ``execute`` on one robot of class ``cls``."""
    from bouncesim.robots.noise import noise_for_mix
    from bouncesim.runs.execute import execute
    env, cs, mix = _mix_setup(env_name)
    rng = np.random.default_rng(seed)
    with cls(env, noise=noise_for_mix(mix, cs.delta_deg), rng=rng) as bot:
        c0 = time.process_time()
        run = execute(mix, bot, steps=steps, epoch=1000, rng=rng, cells=cs, speed=0.3,
                      record_trace=False)
        cpu = time.process_time() - c0
    return run.steps / cpu, run.bumps / max(run.steps, 1)


def batch_rate(make, env_name: str, n: int, steps: int, seed: int = 0):
    """(robot-steps per CPU second, bumps per step, robot-steps) of one batch world."""
    env, cs, mix = _mix_setup(env_name)
    with make(env, n, seed, cells=cs) as batch:
        res = batch.run(mix, steps)
    return res.total / res.cpu_s, float(res.bumps.sum()) / res.total, res.total


def table_throughput(env_name: str, budget: int, robots: int) -> None:
    """Print table 2."""
    from bouncesim.robots.mujoco.batch import MuJoCoBatch
    from bouncesim.robots.pybullet.batch import PyBulletBatch
    print(f"\nTable 2: coverage steps on {env_name}, 75° ε 5° r 0.8, K 72, 0.3 m/s, "
          f"~{budget} robot-steps per row (CPU seconds of this process)")
    print(f"{'body':<44} {'robot-steps':>11} {'steps/CPU s':>11} {'bumps/step':>10}")
    for label, cls in _bodies():
        rate, bumps = single_rate(cls, env_name, budget)
        print(f"{'one ' + label.split()[0] + 'Robot, execute':<44} {budget:11d} {rate:11.1f} "
              f"{bumps:10.3f}")
    per = max(2, math.ceil(budget / robots))
    rows = (("PyBulletBatch, every step", lambda *a, **k: PyBulletBatch(*a, fast_forward=None,
                                                                        **k)),
            ("PyBulletBatch, fast-forward", PyBulletBatch),
            ("MuJoCoBatch, every step", MuJoCoBatch))
    for label, make in rows:
        rate, bumps, total = batch_rate(make, env_name, robots, per)
        print(f"{f'{label}, {robots} robots':<44} {total:11d} {rate:11.1f} {bumps:10.3f}")


def main(argv=None) -> int:
    """Run both tables."""
    p = argparse.ArgumentParser(prog="python -m benchmarks.bench_mujoco",
                                description=__doc__.split("\n\n")[0])
    p.add_argument("--env", default="lab")
    p.add_argument("--sim-seconds", type=float, default=300.0)
    p.add_argument("--angle", type=float, default=135.0)
    p.add_argument("--budget", type=int, default=4000)
    p.add_argument("--robots", type=int, default=16)
    args = p.parse_args(argv)
    table_bounce(args.env, args.sim_seconds, args.angle)
    table_throughput(args.env, args.budget, args.robots)
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
