"""Mixes designed for shape or for time (docs/model.md §20b), compared in the twin.

On the two-room map of :mod:`experiments.cover_time` (about 200 cells, a 0.51 m door; nobody
tuned anything on it), with the angles 30°, 75° and 315° at ε = 5°, r = 0.8, three mixes are
designed on the event model: for the TV of the long-run shape to a uniform target
(``objective="tv"``, §16), for the time to cover 90 % of the room (``"cover90"``) and for the
worst idleness (``"idleness"``) of a team of ``robots`` (default 4), the last two over
``horizon`` steps of the mix executed in epochs of 1000 steps. Each mix is then predicted
(the model's metrics) and run in the kinematic twin
(:func:`bouncesim.runs.cover.twin_cover`): E[min(T_90, T)], the share of runs that cover
90 %, C(T), and the promised long-run TV. Writes designs.csv, config.json.

    python -m experiments.cover_design            # K = 360, grid step 0.1 (a few minutes)
    python -m experiments.cover_design --quick    # K = 72, grid step 0.25, short horizon
"""

from __future__ import annotations

import sys
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from bouncesim.runs.cover import twin_cover
from envs.generated import big_two_room
from planners.cells import CellSpace
from planners.coverage import TurnNoise, design_mix, model_for
from planners.coverage.cover_time import LEVELS, coverage_metrics
from planners.coverage.time_design import objective_value
from planners.plan import PolicyMix

from .common import experiment_parser, output_dir, run_main, write_config
from .cover_time import ANGLES, EPS, R

__all__ = ["Config", "main", "run"]

OBJECTIVES = ("tv", "cover90", "idleness")


@dataclass(frozen=True)
class Config:
    """Parameters of one cover_design run.

    Attributes
    ----------
    orientations : int   K
    horizon : int        steps per robot T
    robots : int         team size K the mixes are designed and measured for
    grid : int           n of the simplex grid (step 1/n)
    runs : int           sampled model runs (teams) per candidate and per reported mix
    twin_runs : int      twin runs (teams) per mix
    seed : int
    out : Path
    """

    orientations: int = 360
    horizon: int = 20_000
    robots: int = 4
    grid: int = 10
    runs: int = 300
    twin_runs: int = 200
    seed: int = 0
    out: Path = Path("results") / "cover_design"


def run(config: Config) -> pd.DataFrame:
    """Design the three mixes, predict them and run them in the twin."""
    out = output_dir(config.out)
    env = big_two_room(config.orientations)
    cs = CellSpace(env)
    model, noise = model_for(cs, "event"), TurnNoise(EPS, R)
    seeds = np.random.SeedSequence(config.seed).spawn(3)
    rows = []
    for objective in OBJECTIVES:
        if objective == "tv":
            d = design_mix(model, ANGLES, noise)
            alpha, promised_tv = d.alpha, d.tv
        else:
            d = design_mix(model, ANGLES, noise, objective=objective, horizon=config.horizon,
                           epoch=1000, robots=config.robots, runs=config.runs,
                           grid=config.grid,
                           rng=np.random.default_rng(seeds[0]))
            alpha = d.alpha
            q = np.column_stack([model.analyse(a, noise).q for a in ANGLES]) @ alpha
            promised_tv = 0.5 * float(np.abs(q - 1.0 / cs.P).sum())
        mix = PolicyMix(tuple(ANGLES), tuple(float(a) for a in alpha), EPS, R)
        rec, = coverage_metrics(model, mix, noise, robots=config.robots,
                                horizon=config.horizon, epoch=1000,
                                runs=config.runs, rng=np.random.default_rng(seeds[1]),
                                exact=False, times=[config.horizon])
        tw = twin_cover(env, mix, noise, robots=config.robots, runs=config.twin_runs,
                        horizon=config.horizon,
                        epoch=1000, times=[config.horizon], rng=np.random.default_rng(seeds[2]),
                        cells=cs)
        i90 = LEVELS.index(0.9)
        reach = tw.reach[:, i90]
        twin_t90 = float(np.where(reach >= 0, reach, config.horizon).mean())
        rows.append({"objective": objective, **{f"alpha_{a:g}": float(x)
                                                 for a, x in zip(ANGLES, alpha)},
                     "model_t90_censored": objective_value(rec, "cover90")[0],
                     "twin_t90_censored": twin_t90,
                     "model_cover90_share": 1 - rec.T["0.9"]["not_reached"],
                     "twin_cover90_share": float((reach >= 0).mean()),
                     "model_C_T": float(rec.covered_mean[-1]),
                     "twin_C_T": float(tw.covered[:, -1].mean()),
                     "model_idleness": rec.idleness_worst,
                     "limit_tv_to_uniform": promised_tv})
        print(f"{objective}: alpha {np.round(alpha, 2).tolist()}", flush=True)
    table = pd.DataFrame(rows)
    table.to_csv(out / "designs.csv", index=False)
    write_config(out, {**asdict(config), "map": env.name, "P": cs.P, "angles": list(ANGLES),
                       "eps": EPS, "r": R, "model": "event", "epoch": 1000})
    print(table.to_string(index=False, float_format=lambda v: f"{v:.3f}"))
    return table


def main(argv=None) -> int:
    """Command line: ``python -m experiments.cover_design``."""
    p = experiment_parser("cover_design", __doc__.split("\n\n")[0])
    args = p.parse_args(argv)

    def make():
        if args.quick:
            return Config(orientations=72, horizon=3000, grid=4, runs=100, twin_runs=50,
                          seed=args.seed, out=args.out)
        return Config(seed=args.seed, out=args.out)
    return run_main("cover_design", make, run)


if __name__ == "__main__":
    sys.exit(main())
