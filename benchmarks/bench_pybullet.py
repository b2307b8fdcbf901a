"""Speed and accuracy of the PyBullet Create 2 at several physics settings, beside a
straightforward reference measured in the same run.

    python -m benchmarks.bench_pybullet [--env lab] [--sim-seconds 60] [--angle 135]
                                        [--repeat 2]

Every row runs the same bounce loop: from the centre of cell 0 facing east, drive at 0.2 m/s
until the bumper closes, turn CCW by ``--angle`` (by clock), repeat until ``--sim-seconds``
of simulated time have passed. Columns:

- ``setting``: physics rate, constraint solver (SI = PyBullet's default sequential impulse
  with its iteration count, or Bullet's exact Dantzig MLCP solver);
- ``step [ms]``, ``poll``: how often the bumper (the contact points) is read: every physics
  step or every 15 ms sensor period;
- ``rt wall`` and ``rt CPU``: simulated seconds per wall-clock second and per second of the
  process's CPU time (the robot's construction is not timed; on an idle machine the two
  agree, on a shared one the CPU figure is the robot's own speed); best of ``--repeat``
  runs;
- ``bumps``, ``gap mean/max [mm]``: at each bump, distance from the simulated body's edge to
  the nearest wall (negative = penetration), from the exact polygon geometry;
- ``turn |err| [deg]``: mean absolute difference between the body's heading change and the
  commanded turn;
- ``scrape [deg/m]``: heading change over 1 m of driving along a wall on the robot's left
  with the heading 1° into it (0 for an ideal symmetric robot; the sequential-impulse solver's
  constraint ordering turns the robot into the wall).

The reference is PyBullet's defaults (240 Hz, sequential-impulse solver with 50 iterations)
with the contacts read after every physics step; the other rows poll every 15 ms. A second
table gives the turn accuracy of the default settings by clock and by encoders.

``--throughput`` instead measures coverage steps (docs/model.md §8) per CPU second: today's
single robot (``execute`` on one :class:`PyBulletRobot`, default physics) against
:class:`~bouncesim.robots.pybullet.batch.PyBulletBatch` worlds of 1, 8, 32 and 64 robots
(``--robots``) simulating every physics step, and the same worlds with the fast-forward of
steady motion (docs/model.md Appendix C), all at 75° with ε = 5°, r = 0.8, K = 72, 0.3 m/s, about
``--budget`` robot-steps per row, plus the fast-forward batch in one process per core
(wall-clock rate over ``--processes`` processes) and the time 10⁶ steps would take at that
rate.

``--fidelity`` runs ``--robots`` (first entry) robots for ``--budget`` robot-steps with
and without the fast-forward (independent seeds) and compares what Appendix C says it keeps: the
gap at the bump, the turn error, the heading change over a flight (bump to bump), bumps per
step, and the coverage histograms (TV between the two runs against the noise floor of two
independent halves of each run, at the same budget).
"""

from __future__ import annotations

import argparse
import math
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np
import shapely

import envs
from bouncesim.robots.pybullet import PyBulletRobot

ROWS = [  # (label, time step [s], solver, solver iterations, poll every step?)
    ("reference (PyBullet defaults)", 1 / 240, "si", 50, True),
    ("240 Hz, SI 50 it", 1 / 240, "si", 50, False),
    ("200 Hz, SI 50 it", 1 / 200, "si", 50, False),
    ("200 Hz, SI 20 it", 1 / 200, "si", 20, False),
    ("200 Hz, SI 10 it", 1 / 200, "si", 10, False),
    ("400 Hz, Dantzig", 1 / 400, "dantzig", 10, False),
    ("240 Hz, Dantzig", 1 / 240, "dantzig", 10, False),
    ("200 Hz, Dantzig (default)", 1 / 200, "dantzig", 10, False),
    ("133 Hz, Dantzig", 0.0075, "dantzig", 10, False),
    ("100 Hz, Dantzig", 1 / 100, "dantzig", 10, False),
]


def bounce_loop(bot: PyBulletRobot, sim_seconds: float, angle: float, every_step: bool,
                speed: float = 0.2):
    """Run the bounce loop; return (wall seconds, CPU seconds, gaps [m], turn errors [deg])."""
    walls = bot.env.walls
    gaps, turn_err = [], []
    t0, w0 = time.process_time(), time.perf_counter()
    while bot.clock() < sim_seconds:
        if every_step:
            bot.drive(speed)
            while not any(bot.bumper()) and bot.clock() < sim_seconds:
                bot.wait(bot.time_step)
            bot.stop()
        else:
            bot.drive_until_bump(speed, sim_seconds - bot.clock() + 1e-9)
        if bot.clock() >= sim_seconds:
            break
        x, y, h0 = bot.true_pose()
        gaps.append(shapely.distance(shapely.points(x, y), walls) - bot.body_radius)
        bot.turn(angle)
        h1 = bot.true_pose()[2]
        turn_err.append((h1 - h0 - angle + 180) % 360 - 180)
    return (time.perf_counter() - w0, time.process_time() - t0, np.array(gaps),
            np.array(turn_err))


def scrape_drift(bot: PyBulletRobot, speed: float = 0.2, dist: float = 1.0) -> float:
    """Heading change [deg] over ``dist`` [m] of driving along the wall on the robot's left
    with the heading 1° into it (an ideal symmetric robot keeps its heading).
    """
    x0, y0, x1, y1 = bot.env.bounds
    bot.place(x0 + 0.25, y1 - bot.body_radius - 0.0005, 1.0)
    bot.drive(speed)
    bot.wait(dist / speed)
    bot.stop()
    return bot.true_pose()[2] - 1.0


def turn_accuracy(env, mode: str, n: int = 20) -> np.ndarray:
    """|error| [deg] of n bump-and-turn cycles (angles 45, 90, 135, 30, 75, 315 in turn) from
    the centre of cell 0 facing east.
    """
    angles = [45, 90, 135, 30, 75, 315]
    errs = []
    with PyBulletRobot(env, turn=mode) as bot:
        for i in range(n):
            a = angles[i % len(angles)]
            if i % 2:
                bot.drive_until_bump(0.2, 30.0)
            h0 = bot.true_pose()[2]
            bot.turn(a)
            errs.append((bot.true_pose()[2] - h0 - a + 180) % 360 - 180)
    return np.abs(errs)


def _mix_setup(env_name: str):
    from planners.cells import CellSpace
    from planners.plan import PolicyMix
    env = envs.load(env_name, orientations=72)
    return env, CellSpace(env), PolicyMix((75.0,), (1.0,), 5.0, 0.8)


def single_rate(env_name: str, steps: int, seed: int = 0) -> tuple[float, float]:
    """(steps per CPU second, bumps per step) of ``execute`` on one default PyBulletRobot."""
    from bouncesim.robots.noise import noise_for_mix
    from bouncesim.runs.execute import execute
    env, cs, mix = _mix_setup(env_name)
    rng = np.random.default_rng(seed)
    with PyBulletRobot(env, noise=noise_for_mix(mix, cs.delta_deg), rng=rng) as bot:
        t0 = time.process_time()
        run = execute(mix, bot, steps=steps, epoch=1000, rng=rng, cells=cs, speed=0.3,
                      record_trace=False)
        cpu = time.process_time() - t0
    return run.steps / cpu, run.bumps / max(run.steps, 1)


def batch_rate(env_name: str, n_robots: int, steps: int, seed: int = 0, fast_forward=None
               ) -> tuple[float, float, int, float]:
    """(robot-steps per CPU second, bumps per step, robot-steps, physics steps per
    robot-step) of one PyBulletBatch.
    """
    from bouncesim.robots.pybullet.batch import PyBulletBatch
    env, cs, mix = _mix_setup(env_name)
    with PyBulletBatch(env, n_robots, seed, cells=cs, fast_forward=fast_forward) as batch:
        res = batch.run(mix, steps)
    return (res.total / res.cpu_s, float(res.bumps.sum()) / res.total, res.total,
            res.physics_steps * n_robots / res.total)


def throughput(env_name: str, robots, budget: int, processes: int) -> None:
    """Print the robot-steps per second table (see the module docstring)."""
    from bouncesim.robots.pybullet.fastforward import FastForward
    print(f"env {env_name}, 75° ε 5° r 0.8, K 72, 0.3 m/s, ~{budget} robot-steps per row "
          f"(CPU seconds of this process; the machine may be shared)")
    print(f"{'body':<40} {'robot-steps':>11} {'steps/CPU s':>11} {'bumps/step':>10} "
          f"{'phys/step':>9} {'vs single':>9}")
    ref, bumps = single_rate(env_name, budget)
    print(f"{'single PyBulletRobot (today)':<40} {budget:11d} {ref:11.1f} {bumps:10.3f} "
          f"{'':>9} {1.0:8.2f}x")
    best = (0.0, 1)
    for ff, tag in ((None, "every step"), (FastForward(), "fast-forward")):
        for n in robots:
            rate, bumps, total, phys = batch_rate(env_name, n, max(2, math.ceil(budget / n)),
                                                  fast_forward=ff)
            if ff is not None:
                best = max(best, (rate, n))
            print(f"{f'PyBulletBatch, {n} robots/world, {tag}':<40} {total:11d} {rate:11.1f} "
                  f"{bumps:10.3f} {phys:9.1f} {rate / ref:8.2f}x")
    n = best[1]
    per = max(2, math.ceil(budget / n))
    t0 = time.perf_counter()
    with ProcessPoolExecutor(processes) as ex:
        outs = list(ex.map(batch_rate, [env_name] * processes, [n] * processes,
                           [per] * processes, range(1, processes + 1),
                           [FastForward()] * processes))
    wall = time.perf_counter() - t0
    total = sum(o[2] for o in outs)
    print(f"{f'{processes} processes x {n} robots, ff (wall)':<40} {total:11d} "
          f"{total / wall:11.1f} {'':>10} {'':>9} {total / wall / ref:8.2f}x")
    print(f"10^6 steps at that wall rate: {1e6 / (total / wall) / 60:.0f} min "
          f"(process start-up and world construction included)")


def flight_stats(env, radius: float, turns) -> dict:
    """Bump gap [mm], turn error [deg] and heading change per flight [deg] of a recorded
    PyBulletBatch run (``BatchRun.turns``).
    """
    rows = [t for per in turns for t in per]
    xy = np.array([(x, y) for x, y, *_ in rows])
    gaps = (shapely.distance(shapely.points(xy), env.walls) - radius) * 1e3
    err = np.abs([(a - b - t + 180.0) % 360.0 - 180.0 for _, _, b, t, a in rows])
    drift = np.abs([(nxt[2] - cur[4] + 180.0) % 360.0 - 180.0
                    for per in turns for cur, nxt in zip(per, per[1:])])
    return {"bumps": len(rows), "gap_mean": gaps.mean(), "gap_min": gaps.min(),
            "gap_max": gaps.max(), "turn_mean": err.mean(), "turn_max": err.max(),
            "drift_mean": drift.mean(), "drift_p99": np.percentile(drift, 99)}


def fidelity(env_name: str, n_robots: int, budget: int, seed: int = 0) -> None:
    """Print what the fast-forward changes (see the module docstring)."""
    from bouncesim.robots.pybullet.batch import PyBulletBatch
    from bouncesim.robots.pybullet.fastforward import FastForward
    from planners.metrics import tv_distance
    env, cs, mix = _mix_setup(env_name)
    steps = max(2, math.ceil(budget / n_robots))
    runs = {}
    for k, (tag, ff) in enumerate((("every step", None), ("fast-forward", FastForward()))):
        with PyBulletBatch(env, n_robots, seed + k, cells=cs, fast_forward=ff) as batch:
            res = batch.run(mix, steps, burn_in=20, record=True)
            radius = batch.host.body_radius
        runs[tag] = res
        st = flight_stats(env, radius, res.turns)
        print(f"{tag:<13} {res.total:6d} steps {res.total / res.cpu_s:7.1f}/CPU s  "
              f"bumps/step {res.bumps.sum() / res.total:.3f}  gap mean/min/max "
              f"{st['gap_mean']:.2f}/{st['gap_min']:.2f}/{st['gap_max']:.2f} mm  turn |err| "
              f"mean/max {st['turn_mean']:.3f}/{st['turn_max']:.3f}°  heading change per "
              f"flight mean/p99 {st['drift_mean']:.3f}/{st['drift_p99']:.3f}°  floor "
              f"{res.floor():.4f}")
    a, b = runs["every step"], runs["fast-forward"]
    print(f"TV(every step, fast-forward) {tv_distance(a.pooled, b.pooled):.4f} at "
          f"{a.total} steps each; halves at {a.total // 2}: TV(every step even, fast-forward "
          f"even) {tv_distance(a.halves()[0], b.halves()[0]):.4f}, TV(every step odd, "
          f"fast-forward odd) {tv_distance(a.halves()[1], b.halves()[1]):.4f}, floors "
          f"{a.floor():.4f} / {b.floor():.4f}")


def main(argv=None) -> None:
    """Run the PyBullet benchmark (real-time factor, bump latency) and print the table."""
    ap = argparse.ArgumentParser(prog="python -m benchmarks.bench_pybullet",
                                 description=__doc__.split("\n\n")[0])
    ap.add_argument("--env", default="lab")
    ap.add_argument("--sim-seconds", type=float, default=60.0)
    ap.add_argument("--angle", type=float, default=135.0)
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--throughput", action="store_true",
                    help="robot-steps per second of PyBulletBatch against one robot instead")
    ap.add_argument("--robots", default="1,8,32,64", help="robots per world (--throughput)")
    ap.add_argument("--budget", type=int, default=256,
                    help="robot-steps per row (--throughput)")
    ap.add_argument("--processes", type=int, default=2, help="processes (--throughput)")
    ap.add_argument("--fidelity", action="store_true",
                    help="what the fast-forward changes, against every physics step")
    ap.add_argument("--seed", type=int, default=0, help="seed (--fidelity)")
    args = ap.parse_args(argv)
    if args.fidelity:
        fidelity(args.env, int(args.robots.split(",")[0]), args.budget, args.seed)
        return
    if args.throughput:
        throughput(args.env, [int(n) for n in args.robots.split(",")], args.budget,
                   args.processes)
        return
    env = envs.load(args.env)
    print(f"env {env.name}, {args.sim_seconds:g} s simulated per row, bounce angle "
          f"{args.angle:g}°, drive 0.2 m/s, turns by clock at 0.1 m/s")
    head = (f"{'setting':<30} {'step [ms]':>9} {'poll':>6} {'rt wall':>7} {'rt CPU':>6} "
            f"{'bumps':>5} {'gap mean [mm]':>13} {'gap max':>8} {'gap min':>8} "
            f"{'turn |err| [deg]':>16} {'scrape [deg/m]':>14} {'vs ref':>6}")
    print(head)
    print("-" * len(head))
    ref = None
    for label, ts, solver, iters, every in ROWS:
        rtf = rtw = 0.0
        for _ in range(max(1, args.repeat)):   # deterministic: every repeat is the same run
            with PyBulletRobot(env, time_step=ts, solver=solver,
                               solver_iterations=iters) as bot:
                wall, cpu, gaps, errs = bounce_loop(bot, args.sim_seconds, args.angle, every)
                rtf = max(rtf, bot.clock() / cpu)
                rtw = max(rtw, bot.clock() / wall)
                drift = scrape_drift(bot)
        ref = ref or rtf
        poll = "step" if every else "15 ms"
        print(f"{label:<30} {ts * 1e3:9.2f} {poll:>6} {rtw:7.0f} {rtf:6.0f} {len(gaps):5d} "
              f"{gaps.mean() * 1e3:13.2f} {gaps.max() * 1e3:8.2f} {gaps.min() * 1e3:8.2f} "
              f"{np.abs(errs).mean():16.3f} {drift:14.2f} {rtf / ref:5.1f}x")
    print("(rt = simulated seconds per wall-clock / CPU second; vs ref compares rt CPU; "
          "gap = body edge to the nearest wall at the bump, negative = penetration)")
    print()
    print("default settings, 20 bump-and-turn cycles (45, 90, 135, 30, 75, 315°):")
    print(f"{'turn by':<10} {'mean |err| [deg]':>16} {'max |err| [deg]':>15}")
    for mode in ("clock", "encoders"):
        e = turn_accuracy(env, mode)
        print(f"{mode:<10} {e.mean():16.3f} {e.max():15.3f}")


if __name__ == "__main__":
    main()
