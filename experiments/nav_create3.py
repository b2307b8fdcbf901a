"""The same plans on the Create 2 and the Create 3 emulators, and on the kinematic twin they both
move: the Fig. 3 plans (the paper's step plans and the exact planner's plans for the same
queries) and a feedback run, noise-free and under rotation noise.

    python -m experiments.nav_create3 [--quick] [--seed 0] [--out results/nav_create3]

Both emulators run in lockstep with their adapters (emulated time), so the table is the same on
any machine. The Create 2 emulator is reached through its Open Interface bytes on a
pseudo-terminal, the Create 3 emulator through iRobot's packet protocol; the bodies are the
same twin, so the final poses differ only by how each adapter drives and turns (the Create 2
by wheel encoders, the Create 3 by its own turn command) and by when each sees the bump.
Writes ``runs.csv`` (one row per run) and ``poses.csv`` (final poses side by side).
"""

from __future__ import annotations

import sys
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from bouncesim.robots import make_robot
from bouncesim.robots.noise import GaussianNoise, NoNoise
from bouncesim.runs.execute import execute, navigate_feedback

from .common import experiment_parser, output_dir, run_main, write_config
from .nav_fig3 import exact_routes, plan_routes

__all__ = ["BODIES", "Config", "main", "run"]

BODIES = ("kinematic", "emulator", "create3-emulator")
# the twin with the emulators' bumper arc (80° from the heading, PyBullet's; see
# experiments/nav_fig3_physics.py), so that the three bodies differ only in their adapters
_OPTIONS = {"kinematic": {"glance_deg": 80.0}, "emulator": {"lockstep": True},
            "create3-emulator": {}}


@dataclass(frozen=True)
class Config:
    """Parameters of one run (written to ``config.json``).

    Attributes
    ----------
    angles : tuple of float   bouncing angles Φ [deg] of the Fig. 3 plans
    feedback : (int, int)     start and goal z of the feedback run (lab)
    sigma : float             rotation noise σ [deg] of the noisy runs
    noisy_runs : int          noisy runs per query and body
    seed : int                root seed
    out : Path
    """

    angles: tuple[float, ...] = (90.0, 135.0)
    feedback: tuple[int, int] = (103, 8)
    sigma: float = 2.0
    noisy_runs: int = 5
    seed: int = 0
    out: Path = Path("results") / "nav_create3"


def _queries(config: Config):
    env, cells, _, routes, table = plan_routes(config.angles)
    exact = exact_routes(cells, table, config.angles)
    out = []
    for (_, row), step, ex in zip(table.iterrows(), routes, exact):
        out.append((f"{row['plan']} step", step))
        out.append((f"{row['plan']} exact", ex))
    return env, cells, out


def run(config: Config) -> pd.DataFrame:
    """Every query on every body, noise-free and ``noisy_runs`` times under gauss:σ."""
    out = output_dir(config.out)
    env, cells, queries = _queries(config)
    jobs = [(label, body, rep) for label, _ in queries + [("feedback", None)]
            for body in BODIES for rep in range(config.noisy_runs + 1)]
    seeds = np.random.SeedSequence(config.seed).spawn(config.noisy_runs + 1)
    routes = dict(queries)
    rows = []
    for label, body, rep in jobs:
        noise = NoNoise() if rep == 0 else GaussianNoise(config.sigma)
        rng = np.random.default_rng(seeds[rep])        # the same draws on every body
        robot = make_robot(body, env, noise=noise, rng=rng, **_OPTIONS[body])
        try:
            if label == "feedback":
                start, goal = config.feedback
                result = navigate_feedback(robot, env, start, goal, config.sigma if rep else 0.0,
                                           np.random.default_rng(seeds[rep]),
                                           angles=(45.0, 90.0, 135.0), cells=cells)
            else:
                route = routes[label]
                result = execute(route.plan, robot, start=route.start, goal=route.goal,
                                 cells=cells)
        finally:
            robot.close()
        x, y, h = result.final_pose
        rows.append({"query": label, "body": body, "noise": "none" if rep == 0 else
                     f"gauss:{config.sigma:g}", "rep": rep, "success": bool(result.success),
                     "reason": result.reason, "bumps": result.bumps, "final_x": x,
                     "final_y": y, "final_heading": h % 360.0})
    runs = pd.DataFrame(rows)
    runs.to_csv(out / "runs.csv", index=False)
    poses = _poses(runs)
    poses.to_csv(out / "poses.csv", index=False)
    write_config(out, {**asdict(config), "bodies": list(BODIES),
                       "seeding": "SeedSequence(seed).spawn(noisy_runs + 1); run rep uses "
                       "spawn rep on every body (rep 0: noise-free)"})
    summary = runs.groupby(["query", "body", "noise"], sort=False)["success"].mean()
    print(summary.unstack("body").to_string(float_format=lambda v: f"{v:.2f}"))
    return runs


def _poses(runs: pd.DataFrame) -> pd.DataFrame:
    """Final poses of each run on the two emulators beside the twin's, with the gaps."""
    key = ["query", "noise", "rep"]
    wide = runs.pivot_table(index=key, columns="body",
                            values=["final_x", "final_y", "final_heading", "success"],
                            aggfunc="first", sort=False)
    out = wide.index.to_frame(index=False)
    for body in BODIES:
        out[f"success_{body}"] = wide["success"][body].to_numpy().astype(bool)
    for body in BODIES[1:]:
        dx = wide["final_x"][body] - wide["final_x"]["kinematic"]
        dy = wide["final_y"][body] - wide["final_y"]["kinematic"]
        dh = (wide["final_heading"][body] - wide["final_heading"]["kinematic"] + 180) % 360 - 180
        out[f"gap_m_{body}"] = np.hypot(dx, dy).to_numpy()
        out[f"gap_deg_{body}"] = dh.abs().to_numpy()
    return out


def main(argv=None) -> int:
    """Command line: ``python -m experiments.nav_create3``."""
    p = experiment_parser("nav_create3", __doc__.split("\n\n")[0])
    p.add_argument("--noisy-runs", type=int, default=None,
                   help="noisy runs per query and body (default 5; --quick 1)")
    args = p.parse_args(argv)

    def make():
        n = args.noisy_runs if args.noisy_runs is not None else (1 if args.quick else 5)
        return Config(noisy_runs=n, seed=args.seed, out=args.out)
    return run_main("nav_create3", make, run)


if __name__ == "__main__":
    sys.exit(main())
