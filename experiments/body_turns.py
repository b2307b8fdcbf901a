"""How exact a body's own turns and bumps are: each trial places the body at a random pose,
drives it to its bump, turns it by a bouncing angle and reads its true pose (docs/model.md
§15: the heading error a feedback navigator must be told to expect).

    python -m experiments.body_turns [--bodies mujoco,pybullet] [--env lab] [--trials 90]

Prints, per body and angle, the signed turn error (true turn − commanded) [deg], and the
heading change over each flight with its bump (0 for a body that keeps its heading).
"""

from __future__ import annotations

import sys

import numpy as np
import pandas as pd

import envs

from .common import experiment_parser, name_list

ANGLES = (45.0, 90.0, 135.0)


def _wrap(deg: float) -> float:
    return (deg + 180.0) % 360.0 - 180.0


def measure(kind: str, env, trials: int, rng: np.random.Generator) -> pd.DataFrame:
    """One row per trial: angle, turn_error_deg, flight_rotation_deg."""
    from bouncesim.robots import make_robot
    rows = []
    with make_robot(kind, env) as body:
        for _ in range(trials):
            body.place(*env.random_pose(rng))
            h0 = body.true_pose()[2]
            body.drive_until_bump(0.3, 30.0)
            h1 = body.true_pose()[2]
            a = float(rng.choice(ANGLES))
            body.turn(a)
            rows.append({"body": kind, "angle": a,
                         "turn_error_deg": _wrap(body.true_pose()[2] - h1 - a),
                         "flight_rotation_deg": _wrap(h1 - h0)})
    return pd.DataFrame(rows)


def table(runs: pd.DataFrame) -> pd.DataFrame:
    """Mean, sd and largest |value| of both errors per body and angle (angle "all" too)."""
    out = []
    for (body, angle), d in pd.concat([runs, runs.assign(angle="all")]).groupby(
            ["body", "angle"], sort=False):
        row = {"body": body, "angle": angle, "trials": len(d)}
        for col in ("turn_error_deg", "flight_rotation_deg"):
            v = d[col].to_numpy()
            row |= {f"{col}_mean": v.mean(), f"{col}_sd": v.std(), f"{col}_max": np.abs(v).max()}
        out.append(row)
    return pd.DataFrame(out)


def main(argv: list[str] | None = None) -> int:
    """Measure every body and print the table."""
    p = experiment_parser("body_turns", __doc__.split("\n\n")[0])
    p.add_argument("--bodies", type=name_list, default=("mujoco", "pybullet"),
                   help="bodies (make_robot kinds: kinematic, pybullet, mujoco, ...)")
    p.add_argument("--env", default="lab", help="catalogue map (default lab)")
    p.add_argument("--trials", type=int, default=90, help="trials per body (default 90)")
    args = p.parse_args(argv)
    env = envs.load(args.env)
    trials = 10 if args.quick else args.trials
    runs = pd.concat([measure(k, env, trials, np.random.default_rng(args.seed))
                      for k in args.bodies], ignore_index=True)
    print(table(runs).round(2).to_string(index=False))
    return 0


if __name__ == "__main__":
    sys.exit(main())
