"""Exact vs step plans, noise-free in the kinematic twin (docs/model.md §13).

For each map, pairs (start ≠ goal) are drawn uniformly without replacement from the ordered
pairs the step model reaches (Φ = {45°, 90°, 135°}, K = 8, w1 = 1, w2 = 100). Each pair is
planned by both planners and each plan is executed once, noise-free, in the kinematic twin
(front-half bumper) by bump and clock (docs/model.md §21). Maps: the catalogue, a pentagon room
with a hexagonal pillar, and random regular-polygon rooms with a polygonal hole.

    python -m experiments.nav_exact [--quick] [--seed S] [--pairs N] [--out DIR]

Writes ``pairs.csv`` (one row per pair), ``summary.csv`` (per map), ``config.json`` and
``success.png`` (drawn from summary.csv).
"""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

import envs
from bouncesim.plots import save_figure
from bouncesim.robots import make_robot
from bouncesim.runs.execute import execute
from envs import Environment
from envs.generated import PENTAGON, random_polygon_room
from planners.cells import CellSpace
from planners.navigation import Navigator
from planners.navigation.exact import ExactNavigator

from .common import experiment_parser, name_list, output_dir, run_main, write_config

__all__ = ["Config", "map_named", "run", "main"]

ANGLES = (45.0, 90.0, 135.0)
W1, W2 = 1.0, 100.0


@dataclass(frozen=True)
class Config:
    """Parameters of one nav_exact run.

    Attributes
    ----------
    pairs : int            pairs per map
    maps : tuple of str    catalogue names, 'pentagon', or 'randomN' (random room N)
    quick : bool           recorded; ``main`` turns it into a small budget
    seed : int             root seed (random rooms, pair sampling)
    out : Path             output folder
    """

    pairs: int = 200
    maps: tuple = ("lab", "fig1", "complex", "pentagon", "random1", "random2", "random3")
    quick: bool = False
    seed: int = 0
    out: Path = Path("results") / "nav_exact"


def map_named(name: str, seed: int) -> Environment:
    """A catalogue map, ``pentagon`` (:data:`PENTAGON`) or ``randomN`` (random polygon room N
    of root seed ``seed``); the navigation experiments share these names.
    """
    if name == "pentagon":
        return Environment.from_dict(PENTAGON)
    if name.startswith("random"):
        rng = np.random.default_rng(np.random.SeedSequence([seed, 2, int(name[6:])]))
        return random_polygon_room(rng, name)
    return envs.load(name)


def _execute(env, cells, plan, s, g):
    run = execute(plan, make_robot("kinematic", env), start=int(s), goal=int(g), cells=cells)
    return bool(run.success), run.reason


def run_map(name: str, config: Config) -> pd.DataFrame:
    """One row per sampled pair: both plans, their costs, twin outcomes and query times."""
    env = map_named(name, config.seed)
    cells = CellSpace(env)
    step = Navigator(cells, ANGLES, W1, W2)
    exact = ExactNavigator(cells, ANGLES, W1, W2)
    W = step.all_pairs().weights.copy()
    np.fill_diagonal(W, -1.0)
    ii, jj = np.nonzero(W > 0)
    rng = np.random.default_rng(np.random.SeedSequence([config.seed, 1, len(name)]))
    pick = np.sort(rng.choice(len(ii), size=min(config.pairs, len(ii)), replace=False))
    rows = []
    for n, q in enumerate(pick):
        s, g = int(ii[q]), int(jj[q])
        sr = step.plan(s, g)
        c0, t0 = time.process_time(), time.perf_counter()
        er = exact.plan(s, g)
        cpu, wall = time.process_time() - c0, time.perf_counter() - t0
        s_ok, s_why = _execute(env, cells, sr.plan, s, g)
        e_ok, e_why = (_execute(env, cells, er.plan, s, g) if er is not None
                       else (False, "no exact plan"))
        rows.append({"map": name, "pair": n, "start": s, "goal": g, "P": cells.P,
                     "step_plan": str(sr.plan), "step_cost": sr.cost, "step_success": s_ok,
                     "step_reason": s_why, "step_ends_with_bump": sr.plan.labels[-1] != 0,
                     "exact_found": er is not None,
                     "exact_plan": er.plan.exact_text() if er else "",
                     "exact_cost": er.cost if er else np.nan,
                     "exact_bumps": er.plan.bumps if er else -1,
                     "exact_success": e_ok, "exact_reason": e_why,
                     "query_cpu_s": cpu, "query_wall_s": wall})
    return pd.DataFrame(rows)


def summarise(pairs: pd.DataFrame) -> pd.DataFrame:
    """Per map: pairs, step success, exact plans found, exact success (of all pairs and of
    those found), and the exact planner's query time (median and max CPU seconds).
    """
    g = pairs.groupby("map", sort=False)
    return pd.DataFrame({
        "pairs": g.size(), "step_success": g.step_success.mean(),
        "exact_found": g.exact_found.mean(), "exact_success": g.exact_success.mean(),
        "exact_success_of_found": g.apply(
            lambda d: d.exact_success[d.exact_found].mean(), include_groups=False),
        "query_cpu_median_s": g.query_cpu_s.median(), "query_cpu_max_s": g.query_cpu_s.max(),
    }).reset_index()


def draw(summary_csv: Path, path: Path) -> None:
    """Bars: noise-free twin success of step and exact plans per map."""
    import matplotlib.pyplot as plt
    d = pd.read_csv(summary_csv)
    x = np.arange(len(d))
    fig, ax = plt.subplots(figsize=(7.5, 3.8))
    ax.bar(x - 0.2, d.step_success, 0.4, label="step model (paper)", color="#bbbbbb")
    ax.bar(x + 0.2, d.exact_success, 0.4, label="exact planner", color="#3b75af")
    for xi, v in zip(x, d.exact_success):
        ax.text(xi + 0.2, v + 0.01, f"{v:.2f}", ha="center", fontsize=7)
    for xi, v in zip(x, d.step_success):
        ax.text(xi - 0.2, v + 0.01, f"{v:.2f}", ha="center", fontsize=7)
    ax.set_xticks(x, d["map"])
    ax.set_ylim(0, 1.12)
    ax.set_ylabel("noise-free success in the twin")
    ax.set_title(f"Step-reachable pairs ({int(d.pairs.iloc[0])} per map), "
                 "Φ = {45°, 90°, 135°}, K = 8", fontsize=9)
    ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.1), ncol=2)
    fig.tight_layout()
    save_figure(fig, path, dpi=130)


def run(config: Config) -> Path:
    """Run every map, write pairs.csv, summary.csv, config.json and success.png."""
    if config.pairs < 1:
        raise envs.UserError(f"--pairs must be at least 1, got {config.pairs}.")
    out = output_dir(config.out)
    write_config(out, {"experiment": "nav_exact", "seed": config.seed, "quick": config.quick,
                       "pairs_per_map": config.pairs, "maps": list(config.maps),
                       "angles": list(ANGLES), "w1": W1, "w2": W2,
                       "robot": "kinematic twin, front-half bumper, noise-free, 0.2 m/s",
                       "pair_sampling": "uniform without replacement over the ordered pairs "
                       "(start != goal) the step model reaches"})
    pairs = pd.concat([run_map(m, config) for m in config.maps], ignore_index=True)
    pairs.to_csv(out / "pairs.csv", index=False)
    summary = summarise(pairs)
    summary.to_csv(out / "summary.csv", index=False)
    draw(out / "summary.csv", out / "success.png")
    print(summary.to_string(index=False, float_format=lambda v: f"{v:.3f}"))
    return out


def main(argv=None) -> int:
    """Parse the command line into a :class:`Config` and :func:`run` it (exit status)."""
    p = experiment_parser("nav_exact", __doc__.splitlines()[0])
    p.add_argument("--pairs", type=int, default=None,
                   help="pairs per map (default 200; 10 with --quick)")
    p.add_argument("--maps", default=",".join(Config.maps),
                   help="maps: catalogue names, pentagon, randomN")
    args = p.parse_args(argv)
    pairs = args.pairs if args.pairs is not None else (10 if args.quick else 200)
    return run_main("nav_exact", lambda: Config(
        pairs=pairs, maps=name_list(args.maps), quick=args.quick, seed=args.seed,
        out=args.out), run)


if __name__ == "__main__":
    sys.exit(main())
