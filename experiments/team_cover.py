"""Cover times of a team whose robots bump into each other, against the prediction for robots
that ignore each other (docs/model.md §20a, §24).

The model's team metrics assume K independent robots. Here K = 4 kinematic twins run in one
room (:func:`bouncesim.runs.team_runs.team_coverage`), once passing through each other
(``interact="off"``: the prediction's assumption, each robot from its own uniform start) and
once bumping (``"bump"``: what real robots feel, from distinct uniform start cells). Reported
per map and angle: the mean covered fraction C(t) at a few t (each robot's own steps), the
mean T_90 over the runs that reach 90 % and the share that does; the model's meetings (two
robots counted in one cell at the same own step): the mean first one over the runs that
meet and the share that do, and their number per 1000 steps of one robot (and the model's
closed-form limit); and the bumping team's contacts (flights another robot ended): the mean
first one and their number per 1000 steps. Writes team_cover.csv and config.json.

    python -m experiments.team_cover            # lab (3 angles) and complex (75°), ~10 min
    python -m experiments.team_cover --quick    # lab, 75°, few runs
    python -m experiments.team_cover --case experiments/maps/lroom.json:75:400   # any map
"""

from __future__ import annotations

import math
import sys
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

import envs
from bouncesim.robots.noise import parse_noise
from bouncesim.runs.team_runs import team_coverage
from envs import UserError
from planners.cells import CellSpace
from planners.coverage import TurnNoise, model_for
from planners.coverage.cover_time import coverage_metrics

from .common import experiment_parser, output_dir, run_main, write_config

__all__ = ["Config", "main", "run"]

EPS, R = 5.0, 0.8


@dataclass(frozen=True)
class Config:
    """Parameters of one team_cover run.

    Attributes
    ----------
    cases : tuple of (map, angle [deg], horizon T [steps], times)   what to run
    robots : int        K
    orientations : int  K of the discretisation (headings)
    runs : int          simulated team runs per case and mode
    model_runs : int    sampled model runs (teams) per case
    seed : int
    out : Path
    """

    cases: tuple = field(default_factory=lambda: (
        ("lab", 30.0, 400, (25, 50, 100, 200, 400)),
        ("lab", 75.0, 400, (25, 50, 100, 200, 400)),
        ("lab", 315.0, 400, (25, 50, 100, 200, 400)),
        ("complex", 75.0, 2000, (100, 250, 500, 1000, 2000))))
    robots: int = 4
    orientations: int = 72
    runs: int = 100
    model_runs: int = 1000
    seed: int = 0
    out: Path = Path("results") / "team_cover"


def _t90(first_visit: np.ndarray, T: int) -> int | None:
    """A run's T_90: the first t (own steps) after which 90 % of the cells have a first
    visit, as §20a counts it; None when not within T.
    """
    need = math.ceil(0.9 * first_visit.size - 1e-9)
    seen = np.sort(first_visit[first_visit >= 0])
    return int(seen[need - 1]) + 1 if seen.size >= need and seen[need - 1] < T else None


def run(config: Config) -> pd.DataFrame:
    """Every case: the model's independent-team prediction, the passing and bumping teams."""
    out = output_dir(config.out)
    rows = []
    root = np.random.SeedSequence(config.seed)
    for (name, angle, T, times), ss in zip(config.cases, root.spawn(len(config.cases))):
        env = envs.load(name, orientations=config.orientations)
        cs = CellSpace(env)
        noise = TurnNoise(EPS, R)
        body_noise = parse_noise(f"model:eps={EPS:g},r={R:g}", cs.delta_deg)
        fine = sorted(set(range(1, T + 1, max(1, T // 200))) | set(times))
        model_rng, sim_ss = np.random.default_rng(ss.spawn(1)[0]), ss.spawn(1)[0]
        rec, = coverage_metrics(model_for(cs, "event"), angle, noise, robots=config.robots,
                                horizon=T, runs=config.model_runs, rng=model_rng, exact=False,
                                times=fine)
        idx = [fine.index(t) for t in times]
        t90, met = rec.T["0.9"], rec.meeting
        rows.append({"map": name, "angle": angle, "mode": "model (independent)",
                     **{f"C({t})": float(rec.covered_mean[i]) for t, i in zip(times, idx)},
                     "T90_mean": t90["mean"], "reach90": 1 - t90["not_reached"],
                     "meet_first": met["first"]["mean"],
                     "meet_reached": 1 - met["first"]["not_reached"],
                     "colocated_per_1000": met["per_1000"],
                     "colocated_limit": met["per_1000_limit"],
                     "contacts_per_1000": 0.0, "runs": config.model_runs})
        for mode, seeds in zip(("off", "bump"), sim_ss.spawn(2)):
            cov, t90s, meet, contact = [], [], [], []
            colo = touches = steps = 0
            for s in seeds.spawn(config.runs):
                rng = np.random.default_rng(s)
                # passing robots start independently, as the prediction's; bumping robots
                # in distinct cells (they are disks)
                starts = rng.integers(cs.N, size=config.robots) if mode == "off" else None
                res = team_coverage(env, angle, body_noise, robots=config.robots, steps=T,
                                    burn_in=0, interact=mode, rng=rng, cells=cs,
                                    starts=starts)
                cov.append(res.covered(fine))
                t90s.append(_t90(res.first_visit, T))
                meet.append(res.first_meeting)
                contact.append(res.first_contact)
                colo += res.colocations
                touches += res.meetings
                steps += int(res.per_robot.sum()) + res.dropped
            cov = np.array(cov)
            got = [t for t in t90s if t is not None]
            mean_t90 = float(np.mean(got)) if got else float("nan")
            share = len(got) / len(t90s)
            met_at = np.array([m for m in meet if m >= 0], dtype=float)
            hits = np.array([c for c in contact if c >= 0], dtype=float)
            rows.append({"map": name, "angle": angle, "mode": f"twin team, {mode}",
                         **{f"C({t})": float(cov[:, i].mean()) for t, i in zip(times, idx)},
                         "T90_mean": mean_t90, "reach90": share,
                         "meet_first": float(met_at.mean()) if met_at.size else float("nan"),
                         "meet_reached": met_at.size / len(meet),
                         "colocated_per_1000": 2000.0 * colo / (config.robots * T * config.runs),
                         "colocated_limit": float("nan"),
                         "contact_first": float(hits.mean()) if hits.size else float("nan"),
                         "contacts_per_1000": 1000.0 * touches / steps, "runs": config.runs})
            print(f"{name} {angle:g}° {mode}: done", flush=True)
    table = pd.DataFrame(rows)
    table.to_csv(out / "team_cover.csv", index=False)
    write_config(out, {**asdict(config), "eps": EPS, "r": R, "model": "event"})
    with pd.option_context("display.width", 200):
        print(table.to_string(index=False, float_format=lambda v: f"{v:.3f}"))
    return table


def _case(text: str) -> tuple:
    """``MAP:ANGLE:T`` as a case of :class:`Config` (the map may hold no colon)."""
    try:
        name, angle, T = text.rsplit(":", 2)
        angle, T = float(angle), int(T)
    except ValueError:
        raise UserError(f"--case takes MAP:ANGLE:T, got {text!r}.") from None
    if T < 16:
        raise UserError(f"--case needs a horizon of at least 16 steps, got {T}.")
    return name, angle, T, tuple(sorted({T // 16, T // 8, T // 4, T // 2, T}))


def main(argv=None) -> int:
    """Command line: ``python -m experiments.team_cover``."""
    p = experiment_parser("team_cover", __doc__.split("\n\n")[0])
    p.add_argument("--case", action="append", default=None, metavar="MAP:ANGLE:T",
                   help="run this map (catalogue name or file), angle [deg] and horizon T "
                   "[steps] instead of the default cases (C(t) at T/16, T/8, T/4, T/2, T); "
                   "repeat for more")
    args = p.parse_args(argv)

    def make():
        if args.case:
            return Config(cases=tuple(_case(c) for c in args.case), seed=args.seed,
                          out=args.out, **({"runs": 10, "model_runs": 200}
                                           if args.quick else {}))
        if args.quick:
            return Config(cases=(("lab", 75.0, 200, (25, 50, 100, 200)),), runs=10,
                          model_runs=200, seed=args.seed, out=args.out)
        return Config(seed=args.seed, out=args.out)
    return run_main("team_cover", make, run)


if __name__ == "__main__":
    sys.exit(main())
