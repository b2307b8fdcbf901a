"""Reliable vs exact plans under Gaussian turn noise, in the kinematic twin (docs/model.md §14).

    python -m experiments.nav_reliable [--quick] [--seed S] [--pairs N] [--runs R]
                                       [--sigma DEG] [--w2-factors 1,0.1,0.01]
                                       [--maps lab,random1] [--out DIR]

For each map, pairs (start ≠ goal) are drawn uniformly without replacement from the ordered
pairs the exact planner reaches (Φ = {45°, 90°, 135°}, K = 8, w1 = 1, w2 = 100). Each pair is
planned by the exact planner (§13) and by the reliable planner (§14, ``gauss:σ``, default
particles and slack); each plan is executed ``runs`` times in the kinematic twin with
Gaussian turn noise σ (its own seeded draws), through the executor (§21). The particle set of
500 particles also measure how each plan funnels uncertainty: the spread of the contact
points (RMS distance from the planned contact) at every bump; a bump whose spread is below
the one before it is a funnel (a wall or corner took position error out), one whose spread
grows by more than h/2 a split (the particles met different walls: an outcome that flips
on a small heading error).

Writes ``pairs.csv`` (one row per pair and planner), ``summary.csv`` (per map and planner,
with 95 % Wilson intervals of the pooled twin success), ``config.json`` and
``success.png`` (drawn from the two CSVs).
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
from bouncesim.robots.kinematic import KinematicRobot
from bouncesim.robots.noise import GaussianNoise
from bouncesim.runs.execute import execute
from planners.cells import CellSpace
from planners.navigation.reliable import W2_FACTORS, ReliableNavigator, draw_turns, rollout, wilson

from .common import experiment_parser, name_list, output_dir, run_main, write_config
from .nav_exact import map_named

__all__ = ["Config", "funnel_stats", "run", "main"]

ANGLES = (45.0, 90.0, 135.0)
W1, W2 = 1.0, 100.0


@dataclass(frozen=True)
class Config:
    """Parameters of one nav_reliable run.

    Attributes
    ----------
    pairs : int            pairs per map
    runs : int             twin executions per plan
    sigma : float          Gaussian turn noise σ [deg]
    particles : int        the reliable planner's particles per estimate
    w2_factors : tuple     its angle-change weight factors (docs/model.md §14)
    maps : tuple of str    catalogue names, 'pentagon' or 'randomN' (nav_exact's rooms)
    quick : bool           recorded; ``main`` turns it into a small budget
    seed : int             root seed
    out : Path             output folder
    """

    pairs: int = 60
    runs: int = 100
    sigma: float = 2.0
    particles: int = 1000
    w2_factors: tuple = W2_FACTORS
    maps: tuple = ("lab", "random1")
    quick: bool = False
    seed: int = 0
    out: Path = Path("results") / "nav_reliable"


def funnel_stats(cells, route, start, goal, sigma, rng) -> dict:
    """Spread of the contact points [m] at each bump of a plan (RMS distance from the
    planned contact over the particles still running), the funnels (bumps whose spread is
    below the previous bump's), the splits (spread up by more than h/2) and the final
    position spread [m].
    """
    turns = draw_turns(f"gauss:{sigma:g}", route.plan, 500, rng, cells.delta_deg)
    ro = rollout(cells, route.plan, start, goal, turns)
    planned = np.array([p[:2] for p in route.poses[1:-1]]).reshape(-1, 2)
    d = np.sqrt(((ro.contacts - planned[None]) ** 2).sum(-1))          # (n, bumps)
    spread = np.sqrt(np.nanmean(d ** 2, axis=0)) if d.shape[1] else np.zeros(0)
    fin = np.sqrt(((ro.poses[:, :2] - np.asarray(route.poses[-1][:2])) ** 2).sum(1))
    drops = np.diff(spread) < -1e-6 if spread.size > 1 else np.zeros(0, dtype=bool)
    jumps = np.diff(spread) > cells.h / 2 if spread.size > 1 else np.zeros(0, dtype=bool)
    return {"funnels": int(drops.sum()), "splits": int(jumps.sum()),
            "max_contact_spread_m": float(np.nanmax(spread)) if spread.size else 0.0,
            "last_contact_spread_m": float(spread[-1]) if spread.size else 0.0,
            "final_spread_m": float(np.sqrt(np.mean(fin ** 2)))}


def _twin(env, cells, plan, s, g, sigma, runs, rng) -> int:
    bot = KinematicRobot(env, GaussianNoise(sigma), rng=rng)
    return sum(bool(execute(plan, bot, start=s, goal=g, cells=cells).success)
               for _ in range(runs))


def run_map(name: str, config: Config) -> pd.DataFrame:
    """Two rows per sampled pair (exact, reliable): plan, cost, predicted and twin success,
    funnel statistics and planning time.
    """
    env = map_named(name, config.seed)
    cells = CellSpace(env)
    ss = np.random.SeedSequence([config.seed, 13, len(name), sum(map(ord, name))])
    pick_rng, plan_rng, twin_rng, fun_rng = (np.random.default_rng(s) for s in ss.spawn(4))
    rel = ReliableNavigator(cells, ANGLES, f"gauss:{config.sigma:g}", W1, W2,
                            w2_factors=config.w2_factors, particles=config.particles,
                            rng=plan_rng)
    rows = []
    tried = 0
    while len(rows) < 2 * config.pairs and tried < 50 * config.pairs:
        tried += 1
        s, g = (int(v) for v in pick_rng.integers(0, cells.N, 2))
        if s == g:
            continue
        exact = rel.exact.plan(s, g)
        if exact is None:
            continue
        t0 = time.process_time()
        route = rel.plan(s, g)
        cpu = time.process_time() - t0
        pair = len(rows) // 2
        for planner, r, p in (("exact", exact, route.p_exact), ("reliable", route,
                                                                route.p_success)):
            k = _twin(env, cells, r.plan, s, g, config.sigma, config.runs, twin_rng)
            rows.append({"map": name, "pair": pair, "start": s, "goal": g,
                         "planner": planner, "plan": r.plan.exact_text(), "cost": r.cost,
                         "bumps": r.plan.bumps, "angles_used": r.plan.angles_used,
                         "final_m": r.plan.final_m, "p_predicted": p,
                         "twin_successes": k, "twin_runs": config.runs,
                         "candidates": route.candidates, "chosen": route.chosen,
                         "plan_cpu_s": cpu if planner == "reliable" else np.nan,
                         **funnel_stats(cells, r, s, g, config.sigma, fun_rng)})
    return pd.DataFrame(rows)


def summarise(pairs: pd.DataFrame) -> pd.DataFrame:
    """Per map and planner: pooled twin success with its Wilson interval (of the pooled
    runs: pair-to-pair variation is not in it), the mean gain over the exact plan of the
    same pair with its standard error over pairs, mean predicted success, changed plans,
    cost, bumps, final drive, funnels, splits and spreads.
    """
    out = []
    rate = pairs.twin_successes / pairs.twin_runs
    for (m, planner), d in pairs.groupby(["map", "planner"], sort=False):
        k, n = int(d.twin_successes.sum()), int(d.twin_runs.sum())
        lo, hi = wilson(k, n)
        base = pairs[(pairs["map"] == m) & (pairs.planner == "exact")]
        gain = rate[d.index].to_numpy() - rate[base.index].to_numpy()    # paired by pair
        out.append({"map": m, "planner": planner, "pairs": len(d), "twin_success": k / n,
                    "ci_low": lo, "ci_high": hi, "p_predicted": d.p_predicted.mean(),
                    "gain_vs_exact": gain.mean(),
                    "gain_se": gain.std(ddof=1) / np.sqrt(len(gain)) if len(gain) > 1 else 0,
                    "changed_plans": float((d.chosen > 0).mean()),
                    "median_cost": d.cost.median(), "mean_bumps": d.bumps.mean(),
                    "mean_final_m": d.final_m.mean(), "mean_funnels": d.funnels.mean(),
                    "funnels_per_bump": d.funnels.sum() / max(d.bumps.sum(), 1),
                    "mean_splits": d.splits.mean(),
                    "median_final_spread_m": d.final_spread_m.median(),
                    "median_plan_cpu_s": d.plan_cpu_s.median()})
    return pd.DataFrame(out)


def draw(summary_csv: Path, pairs_csv: Path, path: Path) -> None:
    """Left: twin success per map and planner (95 % Wilson bars); right: predicted vs twin
    success per plan.
    """
    import matplotlib.pyplot as plt
    s, p = pd.read_csv(summary_csv), pd.read_csv(pairs_csv)
    maps = list(dict.fromkeys(s["map"]))
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(9, 3.8))
    x = np.arange(len(maps))
    for off, planner, colour in ((-0.2, "exact", "#bbbbbb"), (0.2, "reliable", "#3b75af")):
        d = s[s.planner == planner].set_index("map").loc[maps]
        ax.bar(x + off, d.twin_success, 0.4, color=colour, label=f"{planner} plans",
               yerr=[d.twin_success - d.ci_low, d.ci_high - d.twin_success], capsize=3)
        for xi, v in zip(x, d.twin_success):
            ax.text(xi + off, v + 0.04, f"{v:.2f}", ha="center", fontsize=7)
        q = p[p.planner == planner]
        bx.scatter(q.p_predicted, q.twin_successes / q.twin_runs, s=10, color=colour,
                   label=planner, alpha=0.8)
    ax.axhline(0.5, color="k", lw=0.6, ls=":")
    ax.set_xticks(x, maps)
    ax.set_ylim(0, 1.1)
    ax.set_ylabel("twin success")
    ax.legend(fontsize=7, loc="upper left")
    ax.set_title(f"Random reachable pairs ({int(s.pairs.iloc[0])} per map)", fontsize=9)
    bx.plot([0, 1], [0, 1], color="k", lw=0.6)
    bx.set_xlabel("predicted p_success (particles)")
    bx.set_ylabel(f"twin success ({int(p.twin_runs.iloc[0])} runs)")
    bx.set_title("Prediction vs twin, per plan", fontsize=9)
    bx.legend(fontsize=7)
    fig.tight_layout()
    save_figure(fig, path, dpi=130)


def run(config: Config) -> Path:
    """Run every map, write pairs.csv, summary.csv, config.json and success.png."""
    if config.pairs < 1 or config.runs < 1:
        raise envs.UserError("--pairs and --runs must be at least 1.")
    out = output_dir(config.out)
    write_config(out, {"experiment": "nav_reliable", "seed": config.seed,
                       "quick": config.quick, "pairs_per_map": config.pairs,
                       "runs_per_plan": config.runs, "sigma_deg": config.sigma,
                       "particles": config.particles, "maps": list(config.maps),
                       "w2_factors": list(config.w2_factors),
                       "angles": list(ANGLES), "w1": W1, "w2": W2,
                       "robot": "kinematic twin, front-half bumper, gauss noise, 0.2 m/s",
                       "pair_sampling": "uniform, with replacement, over the ordered pairs "
                       "(start != goal) with an exact plan"})
    pairs = pd.concat([run_map(m, config) for m in config.maps], ignore_index=True)
    pairs.to_csv(out / "pairs.csv", index=False)
    summary = summarise(pairs)
    summary.to_csv(out / "summary.csv", index=False)
    draw(out / "summary.csv", out / "pairs.csv", out / "success.png")
    print(summary.to_string(index=False, float_format=lambda v: f"{v:.3f}"))
    return out


def main(argv=None) -> int:
    """Parse the command line into a :class:`Config` and :func:`run` it (exit status)."""
    p = experiment_parser("nav_reliable", __doc__.splitlines()[0])
    p.add_argument("--pairs", type=int, default=None,
                   help="pairs per map (default 60; 4 with --quick)")
    p.add_argument("--runs", type=int, default=None,
                   help="twin runs per plan (default 100; 20 with --quick)")
    p.add_argument("--sigma", type=float, default=2.0, help="turn noise σ [deg] (default 2)")
    p.add_argument("--w2-factors", default=",".join(f"{f:g}" for f in W2_FACTORS),
                   help="the reliable planner's angle-change weight factors (default "
                   "1,0.1,0.01; 1 alone: candidates within the slack at the user's weights)")
    p.add_argument("--maps", default=",".join(Config.maps),
                   help="maps: catalogue names, pentagon, randomN")
    args = p.parse_args(argv)
    return run_main("nav_reliable", lambda: Config(
        pairs=args.pairs or (4 if args.quick else 60),
        runs=args.runs or (20 if args.quick else 100), sigma=args.sigma,
        w2_factors=tuple(float(f) for f in args.w2_factors.split(",") if f),
        maps=name_list(args.maps), quick=args.quick, seed=args.seed, out=args.out), run)


if __name__ == "__main__":
    sys.exit(main())
