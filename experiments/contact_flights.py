"""One flight from the same pose in a physics body and in the twin with that body's contact
rule: where do they end apart, by incidence and by wall (docs/model.md §9; the lroom gap of
docs/readme_physics_mujoco.md).

    python -m experiments.contact_flights [--env experiments/maps/lroom.json]
        [--body pybullet] [--flights 240] [--incidence 2,20] [--rescore DIR --betas 9,10.5]
        [--lockstep ANGLE]

Each flight starts at rest beside a random wall of the map (outer boundary or obstacle),
heading along it and tilted toward it by an incidence drawn uniformly from ``--incidence``
[deg], 0.3–1.2 m back; both bodies drive at 0.3 m/s to their bump. Prints, per incidence
bin and wall kind, the median distance between the two ends, the share more than 5 cm
apart and the mean travel of each body. ``--rescore DIR`` instead scores a stored
``bouncesim validate --out DIR`` run (K = 360, ε = 5°, r = 0.8, the event model) against the
event model with PyBullet's rule at each bump angle of ``--betas``: how the model's TV
depends on β alone. ``--lockstep ANGLE`` instead runs the body's bouncing chain at ANGLE
(each turn ANGLE ± U(5°)) for ``--flights`` flights and flies the twin with the body's own
contact rule from the body's pose after every turn: it prints how many flights end more than
2 cm and 5 cm apart, by the direction of the wall the flight left from (along x, along y or
slanted), and the first of them (docs/model.md Appendix B).
"""

from __future__ import annotations

import glob
import json
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd

import envs
from envs.motion import PYBULLET_CONTACT

from .common import experiment_parser, name_list

BINS = (2.0, 6.0, 8.0, 9.6, 10.0, 10.5, 11.0, 13.0, 20.0)


def _walls(env) -> list:
    """(a, b, kind) of every wall edge: "boundary" or "obstacle"."""
    out = []
    rings = [(env.boundary.exterior, "boundary")] + [(o.exterior, "obstacle")
                                                     for o in env.obstacles]
    for ring, kind in rings:
        c = np.asarray(ring.coords)[:-1]
        out += [(c[i], c[(i + 1) % len(c)], kind) for i in range(len(c))]
    return out


def glancing_starts(env, n: int, incidence: tuple, rng: np.random.Generator) -> list:
    """``n`` start poses (x, y, heading [deg], incidence [deg], wall kind) heading along a
    random wall and tilted toward it by an incidence uniform in ``incidence``.
    """
    from shapely.geometry import Point
    walls, free = _walls(env), env.free_space.buffer(-env.robot_radius * 1.03)
    out, tries = [], 0
    while len(out) < n and tries < 100 * n:
        tries += 1
        a, b, kind = walls[rng.integers(len(walls))]
        p = a + rng.uniform(0.1, 0.9) * (b - a)
        d = (b - a) / np.linalg.norm(b - a)
        inn = np.array([-d[1], d[0]])                   # the normal into the free side
        if not env.free_space.contains(Point(*(p + 0.3 * inn))):
            inn = -inn
        alpha = rng.uniform(*incidence)
        along = d if rng.random() < 0.5 else -d
        hv = np.cos(np.radians(alpha)) * along - np.sin(np.radians(alpha)) * inn
        start = p + 1.01 * env.robot_radius * inn - hv * rng.uniform(0.3, 1.2)
        if free.contains(Point(*start)):
            out.append((float(start[0]), float(start[1]),
                        float(np.degrees(np.arctan2(hv[1], hv[0]))), alpha, kind))
    return out


def compare(env, body: str, starts: list) -> pd.DataFrame:
    """One row per start: both bodies' travel and the distance between their ends."""
    from bouncesim.robots import make_robot
    rows = []
    with make_robot(body, env) as phys, \
            make_robot("kinematic", env, contact=PYBULLET_CONTACT) as twin:
        for x, y, th, alpha, kind in starts:
            ends = []
            for b in (phys, twin):
                b.place(x, y, th)
                b.drive_until_bump(0.3, 60.0)
                ends.append(np.array(b.true_pose()[:2]))
            rows.append({"incidence": alpha, "wall": kind,
                         "apart_m": float(np.hypot(*(ends[0] - ends[1]))),
                         "travel_body": float(np.hypot(ends[0][0] - x, ends[0][1] - y)),
                         "travel_twin": float(np.hypot(ends[1][0] - x, ends[1][1] - y))})
    return pd.DataFrame(rows)


def table(runs: pd.DataFrame) -> pd.DataFrame:
    """Per incidence bin and wall kind: flights, median distance apart [mm], share more than
    5 cm apart, mean travel of each body [m].
    """
    runs = runs.assign(bin=pd.cut(runs.incidence, BINS, right=False))
    return runs.groupby(["bin", "wall"], observed=True).agg(
        flights=("apart_m", "size"), apart_median_mm=("apart_m", lambda v: 1e3 * v.median()),
        apart_over_5cm=("apart_m", lambda v: (v > 0.05).mean()),
        travel_body=("travel_body", "mean"), travel_twin=("travel_twin", "mean")).reset_index()


def _wall_direction(env, x: float, y: float) -> str:
    """"x", "y" or "slanted": the direction of the wall side nearest (x, y)."""
    from shapely.geometry import LineString, Point
    segs = np.asarray(env.wall_segments)
    k = int(np.argmin([Point(x, y).distance(LineString(s)) for s in segs]))
    dx, dy = np.abs(segs[k][1] - segs[k][0])
    ang = np.degrees(np.arctan2(dy, dx))
    return "x" if ang < 1.0 else "y" if ang > 89.0 else "slanted"


def lockstep(env, body: str, angle: float, flights: int,
             rng: np.random.Generator) -> pd.DataFrame:
    """One row per flight of ``body``'s chain at ``angle`` [deg]: the start pose (after the
    turn), the wall it left from, the two ends and their distance; the twin (with the body's
    declared rule at 0.3 m/s) flies from the body's pose, moved into the free space by at
    most the body's overlap with the walls when it stands a hair inside one.
    """
    from shapely.geometry import Point
    from shapely.ops import nearest_points

    from bouncesim.robots import make_robot
    from bouncesim.runs.feedback import body_contact
    core = env.free_space.buffer(-(env.robot_radius + 2e-5), quad_segs=64)
    rows = []
    with make_robot(body, env) as phys:
        rule = body_contact(phys, 0.3)
        with make_robot("kinematic", env, contact=rule) as twin:
            x, y = env.random_pose(rng)[:2]
            phys.place(x, y, 0.0)
            for _ in range(flights):
                start = phys.true_pose()
                p = Point(*start[:2])
                if not core.contains(p):
                    p = nearest_points(core, p)[0]
                twin.place(p.x, p.y, start[2])
                phys.drive_until_bump(0.3, 60.0)
                twin.drive_until_bump(0.3, 60.0)
                a, b = phys.true_pose(), twin.true_pose()
                rows.append({"x": start[0], "y": start[1], "heading": start[2],
                             "wall": _wall_direction(env, *start[:2]),
                             "body_x": a[0], "body_y": a[1], "twin_x": b[0], "twin_y": b[1],
                             "apart_m": float(np.hypot(a[0] - b[0], a[1] - b[1]))})
                phys.turn(angle + float(rng.uniform(-5.0, 5.0)))
    return pd.DataFrame(rows)


def rescore(env_path, run_dir: Path, betas) -> pd.DataFrame:
    """TV of a stored validate run's counts to the event model with PyBullet's rule at each
    bump angle β [deg] (K = 360, ε = 5°, r = 0.8, as the runs were made).
    """
    from planners.cells import CellSpace
    from planners.coverage import TurnNoise, model_for
    from planners.metrics import tv_distance
    rows = []
    for path in glob.glob(str(run_dir / "**" / "runs.jsonl"), recursive=True):
        rows += [json.loads(line) for line in open(path)]
    if not rows:
        raise envs.UserError(f"{run_dir} holds no runs.jsonl of a validate run.")
    cs = CellSpace(envs.load(env_path, orientations=360))
    out = []
    for beta in betas:
        model = model_for(cs, "event", {"contact": replace(PYBULLET_CONTACT, beta_deg=beta)})
        for ang in sorted({float(r["angles"]) for r in rows}):
            c = sum(np.array(r["counts"].split(), float) for r in rows
                    if float(r["angles"]) == ang)
            q = model.analyse(ang, TurnNoise(5, 0.8)).q
            out.append({"beta_deg": beta, "angle": ang, "tv": float(tv_distance(q, c))})
    return pd.DataFrame(out)


def main(argv: list[str] | None = None) -> int:
    """Compare the flights (or rescore a stored run) and print the table."""
    p = experiment_parser("contact_flights", __doc__.split("\n\n")[0])
    p.add_argument("--env", default="experiments/maps/lroom.json",
                   help="catalogue map or env file (default experiments/maps/lroom.json)")
    p.add_argument("--body", default="pybullet", help="the physics body (default pybullet)")
    p.add_argument("--flights", type=int, default=240, help="flights (default 240)")
    p.add_argument("--incidence", default="2,20", metavar="LO,HI",
                   help="incidence range [deg] (default 2,20)")
    p.add_argument("--rescore", type=Path, default=None, metavar="DIR",
                   help="score a stored `validate --out DIR` run against the event model "
                   "with PyBullet's rule at each of --betas instead")
    p.add_argument("--lockstep", type=float, default=None, metavar="ANGLE",
                   help="run the body's chain at ANGLE [deg] and fly the twin from its pose "
                   "after every turn instead (--flights flights)")
    p.add_argument("--betas", type=name_list, default=("9.0", "9.6", "10.5"),
                   help="bump angles [deg] for --rescore (default 9.0,9.6,10.5)")
    args = p.parse_args(argv)
    try:
        env = envs.load(args.env)
        if args.rescore is not None:
            print(rescore(args.env, args.rescore, [float(b) for b in args.betas])
                  .round(3).to_string(index=False))
            return 0
        lo, hi = (float(v) for v in args.incidence.split(","))
    except ValueError:
        p.error(f"--incidence needs LO,HI in degrees, got {args.incidence!r}")
    except envs.UserError as err:
        p.error(str(err))
    if not 0 < lo < hi < 90:
        p.error(f"--incidence needs 0 < LO < HI < 90, got {args.incidence!r}")
    n = 12 if args.quick else args.flights
    if args.lockstep is not None:
        if not 0 < args.lockstep < 360:
            p.error(f"--lockstep needs an angle in (0, 360), got {args.lockstep:g}")
        runs = lockstep(env, args.body, args.lockstep, n, np.random.default_rng(args.seed))
        far = runs[runs.apart_m > 0.02]
        print(f"{len(runs)} flights at {args.lockstep:g}°: {len(far)} end more than 2 cm "
              f"apart, {int((runs.apart_m > 0.05).sum())} more than 5 cm")
        print(runs.assign(over_2cm=runs.apart_m > 0.02, over_5cm=runs.apart_m > 0.05)
              .groupby("wall")[["over_2cm", "over_5cm"]].sum().astype(int).to_string())
        print(far.head(20).round(3).to_string(index=False))
        return 0
    starts = glancing_starts(env, n, (lo, hi), np.random.default_rng(args.seed))
    print(table(compare(env, args.body, starts)).round(3).to_string(index=False))
    return 0


if __name__ == "__main__":
    sys.exit(main())
