"""How exact a body's own turns and bumps are: each trial places the body at a random pose,
drives it to its bump, turns it by a bouncing angle and reads its true pose (docs/model.md
§15: the heading error a feedback navigator must be told to expect).

    python -m experiments.body_turns [--bodies mujoco,pybullet] [--env lab] [--trials 90]
                                     [--speed 0.3]

Prints, per body and angle, the signed turn error (true turn − commanded) [deg], and the
heading change over each flight with its bump (0 for a body that keeps its heading); then,
per body, the turn errors it would declare to a feedback navigator (docs/model.md §15, "A
body's own turns"): the mean turn error as a known offset, and the scatter of the turns and
of the flights' rotations in quadrature (:func:`declaration`).
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


def measure(kind: str, env, trials: int, rng: np.random.Generator,
            speed: float = 0.3, angles=ANGLES) -> pd.DataFrame:
    """One row per trial (the bump driven at ``speed`` [m/s], the turn by one of ``angles``
    [deg] drawn at random): angle, turn_error_deg, flight_rotation_deg.
    """
    from bouncesim.robots import make_robot
    rows = []
    with make_robot(kind, env) as body:
        for _ in range(trials):
            body.place(*env.random_pose(rng))
            h0 = body.true_pose()[2]
            body.drive_until_bump(speed, 30.0)
            h1 = body.true_pose()[2]
            a = float(rng.choice(angles))
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


def declaration(runs: pd.DataFrame) -> str:
    """The noise spec a body with these trials (one body's rows of :func:`measure`) would
    declare as its ``turn_errors``: ``gauss:S,offset=O`` with O the mean turn error and S the
    standard deviations of the turn errors and of the flights' rotations in quadrature
    (rounded to 0.01°; "none" for a body whose errors round to zero).

    >>> declaration(pd.DataFrame({"turn_error_deg": [-1.0, -1.5],
    ...                           "flight_rotation_deg": [0.0, 0.0]}))
    'gauss:0.25,offset=-1.25'
    """
    off = round(float(runs.turn_error_deg.mean()), 2)
    sd = round(float(np.hypot(runs.turn_error_deg.std(ddof=0),
                              runs.flight_rotation_deg.std(ddof=0))), 2)
    if sd == 0 and off == 0:
        return "none"
    return f"gauss:{sd:g}" + (f",offset={off:g}" if off else "")


def main(argv: list[str] | None = None) -> int:
    """Measure every body and print the table."""
    p = experiment_parser("body_turns", __doc__.split("\n\n")[0])
    p.add_argument("--bodies", type=name_list, default=("mujoco", "pybullet"),
                   help="bodies (make_robot kinds: kinematic, pybullet, mujoco, ...)")
    p.add_argument("--env", default="lab",
                   help="catalogue map or env file (default lab)")
    p.add_argument("--trials", type=int, default=90, help="trials per body (default 90)")
    p.add_argument("--speed", type=float, default=0.3,
                   help="drive speed into each bump [m/s] (default 0.3; a body's turns after "
                   "a bump can depend on it)")
    p.add_argument("--angles", type=name_list, default=tuple(f"{a:g}" for a in ANGLES),
                   help="turn angles [deg] drawn from (default 45,90,135, navigation's; "
                   "30,75,315 are validate's)")
    args = p.parse_args(argv)
    try:
        angles = tuple(float(a) for a in args.angles)
    except ValueError:
        p.error(f"--angles needs numbers in degrees, got {','.join(args.angles)!r}")
    if not angles or not all(0 < a < 360 for a in angles):
        p.error("--angles must lie in (0, 360) degrees.")
    if not 0 < args.speed <= 0.5:
        p.error(f"--speed must lie in (0, 0.5] m/s, got {args.speed:g}")
    try:
        env = envs.load(args.env)
    except envs.UserError as err:
        p.error(str(err))
    trials = 10 if args.quick else args.trials
    runs = pd.concat([measure(k, env, trials, np.random.default_rng(args.seed), args.speed,
                              angles) for k in args.bodies], ignore_index=True)
    print(table(runs).round(2).to_string(index=False))
    for body, d in runs.groupby("body", sort=False):
        print(f"{body} declares turn_errors = {declaration(d)!r}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
