"""Benchmark: Create 2 adapter turns and timed drives on a busy host, in real time.

The adapter (:class:`bouncesim.robots.create2.Create2Robot`, this process) drives the OI
emulator over loopback TCP in real time (scale 1). The emulator runs in a process of its own, as the
robot's firmware does on its own processor, and reports the true pose over a pipe. Load:

- ``hogs``: 0, 1 or 2 processes spinning on the CPU (the machine has 2 cores);
- ``jitter``: the adapter acts on every reading 20-50 ms late (uniform, seeded): a sleep is
  injected before each reading is returned to the control loop, as a host that schedules the
  controller late would do.

For each condition and each turn controller (``plain``: stop at the first reading within half
a reading of the target; ``predictive``: slow down near the target, stop early by the expected
lag, correct a measured miss) the table gives the error of 90° turns (alternately CCW and CW)
and of 1 s timed drives at 0.2 m/s (``drive_for``, the final drive of a plan by the clock):
mean and max of |actual - commanded|, and the mean time a turn takes.

Usage::

    python -m benchmarks.bench_turn_load               # 8 turns and 4 drives per cell
    python -m benchmarks.bench_turn_load --quick       # 3 turns, 2 drives, jitter only with 2 hogs
    python -m benchmarks.bench_turn_load --turns 20 --csv turns.csv
"""

from __future__ import annotations

import argparse
import math
import multiprocessing as mp
import time

import numpy as np

from bouncesim.robots.create2 import Create2Robot

ROOM = {"name": "bench-room", "boundary": [[0, 0], [1.7, 0], [1.7, 1.02], [0, 1.02]],
        "robot_radius": 0.17, "discretization": {"cell_size": 0.34, "orientations": 8}}


def _emulator_process(conn) -> None:
    """Serve an OI emulator on TCP; answer 'pose' and 'place' requests on ``conn``."""
    from bouncesim.robots.create2 import OIEmulator
    from envs import Environment
    emu = OIEmulator(Environment.from_dict(ROOM), transport="tcp").start()
    conn.send(emu.url)
    try:
        while True:
            msg = conn.recv()
            if msg[0] == "pose":
                conn.send(emu.true_pose())
            elif msg[0] == "place":
                emu.place(*msg[1])
                conn.send(True)
            else:
                break
    finally:
        emu.close()


def _hog() -> None:
    while True:
        pass


def _jitter(bot: Create2Robot, rng: np.random.Generator) -> None:
    """Make the adapter act on every reading 20-50 ms late."""
    inner = bot._next_state

    def late(*args, **kw):
        st = inner(*args, **kw)
        time.sleep(float(rng.uniform(0.020, 0.050)))
        return st
    bot._next_state = late


def _hdiff(a: float, b: float) -> float:
    return (a - b + 180.0) % 360.0 - 180.0


def measure(url: str, conn, control: str, turns: int, drives: int, jitter: bool,
            rng: np.random.Generator) -> dict:
    """Turn and drive errors of one control mode over an emulator link (with optional jitter)."""
    def pose():
        conn.send(("pose",))
        return conn.recv()

    def place(x, y, h):
        conn.send(("place", (x, y, h)))
        conn.recv()

    with Create2Robot(url, turn_control=control, handle_sigterm=False) as bot:
        if jitter:
            _jitter(bot, rng)
        terr, tdur = [], []
        place(0.85, 0.51, 0.0)
        for i in range(turns):
            a = 90.0 if i % 2 == 0 else -90.0
            h0 = pose()[2]
            t0 = time.monotonic()
            bot.turn(a)
            tdur.append(time.monotonic() - t0)
            time.sleep(0.05)                     # let a late stop land before looking
            terr.append(abs(_hdiff(pose()[2], h0) - a))
        derr = []
        for _ in range(drives):
            place(0.3, 0.51, 0.0)
            x0 = pose()[0]
            bot.drive_for(0.2, 1.0)
            time.sleep(0.05)
            derr.append(abs((pose()[0] - x0) - 0.2) * 1000.0)
    return {"turn_mean": float(np.mean(terr)), "turn_max": float(np.max(terr)),
            "turn_s": float(np.mean(tdur)),
            "drive_mean_mm": float(np.mean(derr)) if derr else math.nan,
            "drive_max_mm": float(np.max(derr)) if derr else math.nan}


def main(argv=None) -> None:
    """Run the turn-under-load benchmark (clock vs encoder turns) and print the table."""
    ap = argparse.ArgumentParser(prog="python -m benchmarks.bench_turn_load",
                                 description=__doc__.split("\n\n")[0])
    ap.add_argument("--turns", type=int, default=8, help="90° turns per cell (default 8)")
    ap.add_argument("--drives", type=int, default=4, help="timed drives per cell (default 4)")
    ap.add_argument("--quick", action="store_true", help="3 turns, 2 drives, fewer conditions")
    ap.add_argument("--seed", type=int, default=0, help="seed of the jitter draws")
    ap.add_argument("--csv", default=None, help="also write the table as CSV")
    args = ap.parse_args(argv)
    turns, drives = (3, 2) if args.quick else (args.turns, args.drives)
    conditions = [(h, j) for h in (0, 1, 2) for j in (False, True)]
    if args.quick:
        conditions = [(0, False), (2, True)]
    ctx = mp.get_context("spawn")
    parent, child = ctx.Pipe()
    emu = ctx.Process(target=_emulator_process, args=(child,), daemon=True)
    emu.start()
    url = parent.recv()
    rng = np.random.default_rng(args.seed)
    rows = []
    print(f"{turns} turns of ±90° and {drives} drives of 0.2 m (0.2 m/s for 1 s) per cell; "
          "real time, emulator in its own process")
    print("| hogs | jitter | control | turn error mean / max [deg] | turn time [s] | "
          "drive error mean / max [mm] |")
    print("|---|---|---|---|---|---|")
    try:
        for hogs, jitter in conditions:
            procs = [ctx.Process(target=_hog, daemon=True) for _ in range(hogs)]
            for p in procs:
                p.start()
            try:
                time.sleep(0.5)
                for control in ("plain", "predictive"):
                    r = measure(url, parent, control, turns, drives, jitter, rng)
                    r.update(hogs=hogs, jitter=jitter, control=control)
                    rows.append(r)
                    print(f"| {hogs} | {'20-50 ms' if jitter else 'none'} | {control} | "
                          f"{r['turn_mean']:.2f} / {r['turn_max']:.2f} | {r['turn_s']:.2f} | "
                          f"{r['drive_mean_mm']:.1f} / {r['drive_max_mm']:.1f} |", flush=True)
            finally:
                for p in procs:
                    p.terminate()
                    p.join()
    finally:
        parent.send(("close",))
        emu.join(timeout=5)
    if args.csv:
        import pandas as pd
        pd.DataFrame(rows).to_csv(args.csv, index=False)
    worst = max(r["turn_max"] for r in rows if r["control"] == "predictive")
    print(f"predictive turns: worst error {worst:.2f}° (target: at most 1.5° in every "
          "condition)")


if __name__ == "__main__":
    main()
