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

``--factor`` fits the error as a known factor and offset, (F − 1)·φ + O, over the angles
(a turn by clock that runs short in proportion to its length as well as by a constant).
``--rest`` measures turns after a bump from rest too (docs/model.md §11b): every other trial
turns by its angle after its bump and drives again; where that turn left it facing its wall
(a flight of length zero, a bump from rest) the next turn by the angle is measured, as the
chain makes such bounces in place. The table and the declarations are then given per
arrival ("flight" or "rest").
"""

from __future__ import annotations

import sys

import numpy as np
import pandas as pd

import envs
from planners.measures import wrap180
from planners.noise import parse_noise_spec
from planners.turn_offsets import spin_sign

from .common import experiment_parser, name_list

ANGLES = (45.0, 90.0, 135.0)


def _wrap(deg: float) -> float:
    return (deg + 180.0) % 360.0 - 180.0


BODY_REST_FLIGHT = 0.005
"""[m] A body's flight shorter than this after a turn is a bump from rest (:func:`measure`):
a physical body pushes up to a few mm into its wall (MuJoCo's up to 4.2 mm); the models'
threshold for their exact flights is :data:`envs.contact.REST_FLIGHT`, 1 mm."""


def measure(kind: str, env, trials: int, rng: np.random.Generator,
            speed: float = 0.3, angles=ANGLES, rest: bool = False) -> pd.DataFrame:
    """One row per trial (the bump driven at ``speed`` [m/s], the turn by one of ``angles``
    [deg] drawn at random): angle, turn_error_deg, flight_rotation_deg, arrival ("flight").

    With ``rest`` every other trial is a bounce in place, as the chain makes them: after its
    bump it turns by its angle and drives again; when that flight is shorter than
    :data:`BODY_REST_FLIGHT` (the turn left it facing its wall: a bump from rest, its length in
    ``rest_flight_m``) the second turn by the angle is the one measured (arrival "rest");
    a trial whose turn took it off the wall is dropped.
    """
    from bouncesim.robots import make_robot
    rows = []
    with make_robot(kind, env) as body:
        for i in range(trials):
            body.place(*env.random_pose(rng))
            h0 = body.true_pose()[2]
            body.drive_until_bump(speed, 30.0)
            a = float(rng.choice(angles))
            row = {"body": kind, "arrival": "flight"}
            if rest and i % 2:
                body.turn(wrap180(a))                    # the shorter way (§21)
                x1, y1, h0 = body.true_pose()
                body.drive_until_bump(speed, 30.0)       # from rest
                x2, y2, _ = body.true_pose()
                row |= {"arrival": "rest", "rest_flight_m": float(np.hypot(x2 - x1, y2 - y1))}
                if row["rest_flight_m"] >= BODY_REST_FLIGHT:
                    continue
            h1 = body.true_pose()[2]
            body.turn(wrap180(a))
            rows.append(row | {"angle": a,
                               "turn_error_deg": _wrap(body.true_pose()[2] - h1 - a),
                               "flight_rotation_deg": _wrap(h1 - h0)})
    return pd.DataFrame(rows)


def table(runs: pd.DataFrame) -> pd.DataFrame:
    """Mean, sd and largest |value| of both errors per body and angle (angle "all" too)."""
    out = []
    runs = runs if "arrival" in runs else runs.assign(arrival="flight")
    for (body, arrival, angle), d in pd.concat([runs, runs.assign(angle="all")]).groupby(
            ["body", "arrival", "angle"], sort=False):
        row = {"body": body, "arrival": arrival, "angle": angle, "trials": len(d)}
        for col in ("turn_error_deg", "flight_rotation_deg"):
            v = d[col].to_numpy()
            row |= {f"{col}_mean": v.mean(), f"{col}_sd": v.std(), f"{col}_max": np.abs(v).max()}
        out.append(row)
    return pd.DataFrame(out)


def declaration(runs: pd.DataFrame, factor: bool | float = False) -> str:
    """The noise spec a body with these trials (one body's rows of :func:`measure`) would
    declare as its ``turn_errors``: ``gauss:S,offset=O`` with O the mean lag (the turn error
    in the sense of the spin ρ = wrap180(φ), the shorter way: a body lags the same either
    way, docs/model.md §11b) and S the standard deviations of the lags and of the flights'
    rotations in quadrature (rounded to 0.01°; "none" for a body whose errors round to zero;
    trials without an angle count as counter-clockwise).

    With ``factor`` True the lag is fitted by least squares as (F − 1)·|ρ| + O over the
    trials' angles (at least two), ``gauss:S,offset=O,factor=F`` with S from the fit's
    residuals (F rounded to 1e-4); with ``factor`` a number F, O is fitted with F fixed
    (a body's turns after a bump from rest, declared with the factor of its turns after a
    flight: the coverage chain shifts the one by the difference of the offsets, §11b).

    >>> declaration(pd.DataFrame({"turn_error_deg": [-1.0, -1.5],
    ...                           "flight_rotation_deg": [0.0, 0.0]}))
    'gauss:0.25,offset=-1.25'
    >>> declaration(pd.DataFrame({"angle": [30.0, 90.0, 300.0], "turn_error_deg": [-1.03,
    ...                           -1.09, 1.06], "flight_rotation_deg": [0.0, 0.0, 0.0]}), True)
    'gauss:0,offset=-1,factor=0.999'
    """
    err = runs.turn_error_deg.to_numpy(dtype=float)
    rho = (wrap180(runs.angle.to_numpy(dtype=float)) if "angle" in runs
           else np.zeros(err.size))
    err, spin = err * spin_sign(rho), np.abs(rho)      # the lag, in the sense of the spin
    f = 1.0
    if factor is True:
        if np.unique(spin).size < 2:
            raise ValueError("a turn factor needs trials at two spins or more.")
        slope, off = np.polyfit(spin, err, 1)
        f, resid = round(1.0 + float(slope), 4), err - (slope * spin + off)
        err = resid + off
    elif factor is not False:
        f = float(factor)
        err = err - (f - 1.0) * spin
    off = round(float(err.mean()), 2)
    sd = round(float(np.hypot(err.std(ddof=0), runs.flight_rotation_deg.std(ddof=0))), 2)
    if sd == 0 and off == 0 and f == 1.0:
        return "none"
    return (f"gauss:{sd:g}" + (f",offset={off:g}" if off else "")
            + (f",factor={f:g}" if f != 1.0 else ""))


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
    p.add_argument("--factor", action="store_true",
                   help="declare a known turn factor and offset, (F - 1)*angle + O, fitted "
                   "over the angles (give two or more), not a mean offset")
    p.add_argument("--rest", action="store_true",
                   help="also measure turns after a bump from rest (every other trial turns "
                   "by its angle after its bump and drives again; where that flight has "
                   "length zero the next turn is measured): tables and declarations per "
                   "arrival")
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
    if args.factor and len(set(angles)) < 2:
        p.error("--factor fits a factor over the angles: give two or more (--angles).")
    runs = pd.concat([measure(k, env, trials, np.random.default_rng(args.seed), args.speed,
                              angles, args.rest) for k in args.bodies], ignore_index=True)
    print(table(runs).round(2).to_string(index=False))
    for body, d in runs.groupby("body", sort=False):
        moving = declaration(d[d.arrival == "flight"], args.factor)
        print(f"{body} declares turn_errors = {moving!r}")
        if args.rest:
            # the turns after a bump from rest with the factor of those after a flight
            f = parse_noise_spec(moving).factor if args.factor else False
            rest = declaration(d[d.arrival == "rest"], f if f is not None else False)
            print(f"{body} declares after a bump from rest {rest!r}")
    if args.rest:
        print(f"flights from rest: at most {runs.rest_flight_m.max() * 1000:.2f} mm "
              f"({(runs.arrival == 'rest').sum()} of {(trials + 1) // 2 * len(args.bodies)} "
              f"trials kept)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
