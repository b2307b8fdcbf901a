"""Navigation Monte-Carlo: success of shortest bouncing plans under rotation noise.

    python -m experiments.nav_montecarlo [--quick] [--seed 0] [--out results/nav_montecarlo]
                                         [--workers N | --dask-local N | --dask ADDRESS]

For a seeded sample of reachable (start, goal) pairs of `lab` and `complex` (shortest plans
from the all-pairs table at the catalogue discretisation, Φ = {45°, 90°, 135°}, w1 = 1,
w2 = 100, as in ``experiments.allpairs_fig7``), the planned observation strings are executed
by :func:`bouncesim.runs.execute.execute` in the kinematic twin (every pair) and in PyBullet (a
subset of the pairs), under Gaussian rotation noise σ and the docs/model.md §7 model (ε = Δ, several
r). Every execution is one trial of :mod:`bouncesim.runs.sweep` (seeded, resumable, any executor).

Outputs in ``--out``: ``runs.csv`` (one row per trial), ``runs.jsonl`` (the resume journal),
``summary_noise.csv``, ``summary_length.csv``, ``summary_angles.csv``,
``summary_headings.csv``, ``summary_paired.csv`` (both backends on the PyBullet pairs only;
all with success rates and 95 % Wilson intervals), ``config.json`` and
``success.png`` and ``success_by_length.png`` (drawn from runs.csv alone: ``--plot-only``
redraws them).
"""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass, replace
from functools import lru_cache
from pathlib import Path

import numpy as np
import pandas as pd

import envs
from bouncesim.robots.noise import parse_noise
from bouncesim.runs.execute import execute
from bouncesim.runs.executors import add_executor_args, make_executor
from bouncesim.runs.sweep import Sweep
from planners.cells import CellSpace
from planners.navigation import Navigator
from planners.plan import Plan

from .common import experiment_parser, output_dir
from .nav_fig3_physics import TWIN_GLANCE_DEG, make_robot

__all__ = ["LENGTH_BINS", "Config", "build_trials", "draw", "draw_by_length", "heading_class",
           "main", "nav_trial", "run", "sample_pairs", "summarise", "wilson"]

ENVS = ("lab", "complex")
ANGLES = (45.0, 90.0, 135.0)
W1, W2 = 1.0, 100.0
LENGTH_BINS = (0, 5, 10, 20, 40, np.inf)
"""Plan length bins (number of symbols: zeros plus angles): (0, 5], (5, 10], ..."""
CONFIDENCE = 0.95

FULL = {"pairs": 300, "physics_pairs": 40, "sigmas": (0.0, 1.0, 2.0, 5.0, 10.0),
        "model_r": (0.99, 0.95, 0.9), "reps": 10, "physics_reps": 2}
QUICK = {"pairs": 12, "physics_pairs": 2, "sigmas": (0.0, 2.0, 10.0), "model_r": (0.9,),
         "reps": 3, "physics_reps": 1}


# ============================================================================ the trial
@lru_cache(maxsize=4)
def _world(name: str):
    env = envs.load(name)
    return env, CellSpace(env)


def nav_trial(params: dict, rng: np.random.Generator) -> dict:
    """Execute one plan once: the sweep's trial function (pure in ``params`` and ``rng``).

    ``params``: env, start, goal (configuration indices), plan (observation string), backend
    ('kinematic' or 'pybullet'), noise (``parse_noise`` spec). The rng drives the noise.
    """
    env, cells = _world(params["env"])
    noise = parse_noise(params["noise"], cells.delta_deg)
    t0 = time.perf_counter()
    robot = make_robot(params["backend"], env, noise, rng)
    try:
        run = execute(Plan.parse(params["plan"]), robot, start=int(params["start"]),
                      goal=int(params["goal"]), cells=cells)
    finally:
        robot.close()
    wall = time.perf_counter() - t0
    fx, fy, fh = run.final_pose
    return {"success": bool(run.success), "completed": bool(run.completed),
            "reason": run.reason, "bumps_executed": int(run.bumps),
            "deviations": len(run.deviations),
            "early": sum(d.kind == "early" for d in run.deviations),
            "late": sum(d.kind == "late" for d in run.deviations),
            "position_error_m": float(run.position_error),
            "heading_error_deg": float(run.heading_error),
            "final_x": float(fx), "final_y": float(fy), "final_heading": float(fh),
            "sim_time_s": float(run.elapsed), "wall_s": wall}


# ============================================================================ pairs and trials
def heading_class(start_heading: float, plan) -> str:
    """'axis' when every heading along the plan is a multiple of 90°, else 'diagonal'.

    In a room with walls on the grid lines an axis-aligned plan stays on cell centres; a
    diagonal heading does not always (see docs/readme_montecarlo.md).
    """
    h = float(start_heading)
    heads = [h]
    for a in plan.angles:
        h += a
        heads.append(h)
    return "axis" if all(abs(x / 90.0 - round(x / 90.0)) < 1e-9 for x in heads) else "diagonal"


def sample_pairs(name: str, n: int, rng: np.random.Generator) -> pd.DataFrame:
    """``n`` reachable ordered pairs (start ≠ goal) drawn uniformly without replacement, with
    their shortest plans.
    """
    _, cells = _world(name)
    ap = Navigator(cells, ANGLES, W1, W2).all_pairs()
    W = ap.weights.copy()
    np.fill_diagonal(W, -1.0)
    ii, jj = np.nonzero(W > 0)
    pick = np.sort(rng.choice(len(ii), size=min(n, len(ii)), replace=False))
    rows = []
    for pair, s in enumerate(pick):
        route = ap.route(int(ii[s]), int(jj[s]))
        plan = route.plan
        rows.append({"env": name, "pair": pair, "start": route.start, "goal": route.goal,
                     "plan": str(plan), "length": len(plan.labels), "plan_bumps": plan.bumps,
                     "angles_used": plan.angles_used, "cost": route.cost,
                     "headings": heading_class(cells.pose(route.start)[2], plan)})
    return pd.DataFrame(rows)


def noise_levels(delta_deg: float, sigmas, model_r) -> list[tuple[str, str, float]]:
    """(spec, kind, level): Gaussian σ [deg] and the §7 model at ε = Δ with level 1 − r."""
    out = [(f"gauss:{s:g}", "gauss", float(s)) for s in sigmas]
    out += [(f"model:eps={delta_deg:g},r={r:g}", "model", round(1.0 - r, 10)) for r in model_r]
    return out


def build_trials(pairs: pd.DataFrame, budget: dict) -> list[dict]:
    """Every (pair, backend, noise level, repetition) as sweep parameters.

    Exact levels (σ = 0) run once: the plan and the simulators are then deterministic.
    """
    trials = []
    for _, p in pairs.iterrows():
        _, cells = _world(p["env"])
        backends = [("kinematic", budget["reps"])]
        if p["pair"] < budget["physics_pairs"]:
            backends.append(("pybullet", budget["physics_reps"]))
        for backend, reps in backends:
            for spec, kind, level in noise_levels(cells.delta_deg, budget["sigmas"],
                                                  budget["model_r"]):
                for rep in range(1 if level == 0 else reps):
                    trials.append({"env": p["env"], "pair": int(p["pair"]),
                                   "start": int(p["start"]), "goal": int(p["goal"]),
                                   "plan": p["plan"], "length": int(p["length"]),
                                   "plan_bumps": int(p["plan_bumps"]),
                                   "angles_used": int(p["angles_used"]),
                                   "headings": p["headings"], "backend": backend,
                                   "noise": spec, "noise_kind": kind, "noise_level": level,
                                   "rep": rep})
    return trials


# ============================================================================ statistics
def wilson(k, n, confidence: float = CONFIDENCE) -> tuple[np.ndarray, np.ndarray]:
    """Wilson score interval for k successes in n trials (arrays broadcast; NaN when n = 0).

    Computed with ``scipy.stats.binomtest(k, n).proportion_ci(method='wilson')``.
    """
    from scipy.stats import binomtest
    k_arr, n_arr = np.broadcast_arrays(np.asarray(k, dtype=int), np.asarray(n, dtype=int))
    lo = np.full(k_arr.shape, np.nan)
    hi = np.full(k_arr.shape, np.nan)
    for idx in np.ndindex(k_arr.shape):
        if n_arr[idx] > 0:
            ci = binomtest(int(k_arr[idx]), int(n_arr[idx])).proportion_ci(
                confidence_level=confidence, method="wilson")
            lo[idx], hi[idx] = ci.low, ci.high
    return lo, hi


def length_bin(length) -> pd.Series:
    """Plan length (symbols) binned into LENGTH_BINS, labelled '1-5', '6-10', ..., '41+'."""
    labels = []
    for a, b in zip(LENGTH_BINS[:-1], LENGTH_BINS[1:]):
        labels.append(f"{a + 1}+" if np.isinf(b) else f"{a + 1}-{b}")
    return pd.cut(pd.Series(length), bins=list(LENGTH_BINS), labels=labels).astype(str)


def summarise(runs: pd.DataFrame, by: list[str]) -> pd.DataFrame:
    """Success rate with a 95 % Wilson interval per group, plus mean deviations and median
    final position error.
    """
    runs = runs.copy()
    if "length_bin" in by:
        labels = length_bin([b + 1 for b in LENGTH_BINS[:-1]]).tolist()     # in bin order
        runs["length_bin"] = pd.Categorical(length_bin(runs["length"]).values,
                                            categories=labels, ordered=True)
    keys = ["env", "backend", "noise_kind", "noise_level", "noise", *by]
    g = runs.groupby(keys, sort=True, dropna=False, observed=True)
    out = g.agg(trials=("success", "size"), successes=("success", "sum"),
                pairs=("pair", "nunique"), mean_deviations=("deviations", "mean"),
                median_position_error_m=("position_error_m", "median")).reset_index()
    out["successes"] = out["successes"].astype(int)
    out["success_rate"] = out["successes"] / out["trials"]
    out["ci_low"], out["ci_high"] = wilson(out["successes"].to_numpy(),
                                           out["trials"].to_numpy())
    return out


# ============================================================================ figure
def draw(runs_csv: Path, path: Path) -> None:
    """Success rate against noise, one curve per (environment, backend), from runs.csv."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from bouncesim.plots import save_figure

    runs = pd.read_csv(runs_csv)
    s = summarise(runs, [])
    fig, axes = plt.subplots(1, 2, figsize=(10.5, 4.0), sharey=True)
    styles = {"kinematic": "-", "pybullet": "--"}
    markers = {"lab": "o", "complex": "s"}
    colours = {("lab", "kinematic"): "C0", ("lab", "pybullet"): "C9",
               ("complex", "kinematic"): "C3", ("complex", "pybullet"): "C1"}
    for ax, kind, xlabel in ((axes[0], "gauss", "Gaussian rotation noise σ [deg]"),
                             (axes[1], "model", "docs/model.md §7 noise: 1 − r (ε = Δ = 45°)")):
        groups = list(s.groupby(["env", "backend"], sort=False))
        levels = s.loc[s["noise_kind"] == kind, "noise_level"]
        span = float(levels.max()) if len(levels) and levels.max() > 0 else 1.0
        for i, ((env, backend), sub) in enumerate(groups):
            dodge = (i - (len(groups) - 1) / 2) * 0.008 * span     # keep error bars apart
            exact = sub[sub["noise_level"] == 0]
            part = sub[sub["noise_kind"] == kind]
            if kind == "model":            # the noise-free point is r = 1
                part = pd.concat([exact, part])
            part = part.sort_values("noise_level")
            if part.empty:
                continue
            x = part["noise_level"].to_numpy() + dodge
            y = part["success_rate"].to_numpy()
            err = np.vstack([y - part["ci_low"].to_numpy(), part["ci_high"].to_numpy() - y])
            n = int(part["pairs"].max())
            ax.errorbar(x, y, yerr=err, ls=styles.get(backend, ":"),
                        marker=markers.get(env, "^"), ms=4, capsize=3,
                        color=colours.get((env, backend)),
                        label=f"{env}, {backend} ({n} pairs)")
        ax.set_xlabel(xlabel)
        ax.grid(alpha=0.3)
        ax.set_ylim(-0.02, 1.02)
    axes[0].set_ylabel("success rate (95 % Wilson interval)")
    axes[0].legend(fontsize=8, loc="upper right")
    fig.suptitle("Shortest bouncing plans (Φ = {45°, 90°, 135°}) executed under rotation noise",
                 fontsize=10)
    save_figure(fig, path, dpi=130)


def draw_by_length(runs_csv: Path, path: Path, backend: str = "kinematic") -> None:
    """Success rate against plan length (binned), one curve per noise level, one panel per
    environment, for one backend, from runs.csv.
    """
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from bouncesim.plots import save_figure

    runs = pd.read_csv(runs_csv)
    runs = runs[runs["backend"] == backend]
    if runs.empty:
        return
    s = summarise(runs, ["length_bin"])
    names = list(dict.fromkeys(runs["env"]))
    fig, axes = plt.subplots(1, len(names), figsize=(5.2 * len(names), 4.0), sharey=True,
                             squeeze=False)
    for ax, env in zip(axes[0], names):
        sub = s[s["env"] == env]
        bins = list(sub["length_bin"].cat.categories)
        levels = sub.drop_duplicates("noise").sort_values(["noise_kind", "noise_level"])
        for i, (_, lev) in enumerate(levels.iterrows()):
            part = sub[sub["noise"] == lev["noise"]]
            x = np.array([bins.index(b) for b in part["length_bin"]]) + 0.04 * (
                i - (len(levels) - 1) / 2)
            y = part["success_rate"].to_numpy()
            err = np.vstack([y - part["ci_low"].to_numpy(), part["ci_high"].to_numpy() - y])
            ax.errorbar(x, y, yerr=err, marker="o" if lev["noise_kind"] == "gauss" else "s",
                        ms=3.5, capsize=2, lw=1.2,
                        ls="-" if lev["noise_kind"] == "gauss" else "--", label=lev["noise"])
        mine = runs[runs["env"] == env].drop_duplicates("pair")
        n_by_bin = mine.assign(b=length_bin(mine["length"]).values).groupby("b").size()
        ax.set_xticks(range(len(bins)))
        ax.set_xticklabels([f"{b}\n({int(n_by_bin.get(b, 0))} pairs)" for b in bins],
                           fontsize=8)
        ax.set_xlabel("plan length [symbols]")
        ax.set_title(f"{env}, {backend}", fontsize=10)
        ax.grid(alpha=0.3)
        ax.set_ylim(-0.02, 1.02)
    axes[0][0].set_ylabel("success rate (95 % Wilson interval)")
    axes[0][-1].legend(fontsize=7, loc="upper right")
    save_figure(fig, path, dpi=130)


# ============================================================================ main
@dataclass(frozen=True)
class Config:
    """Parameters of one nav_montecarlo run (``main`` fills the budget from FULL or QUICK).

    Attributes
    ----------
    pairs : int               pairs per environment
    physics_pairs : int       of those, pairs also run in PyBullet (0 for none)
    reps : int                noisy repetitions per pair and level in the twin
    physics_reps : int        noisy repetitions per pair and level in PyBullet
    sigmas : tuple of float   Gaussian rotation noise σ [deg]
    model_r : tuple of float  r of the docs/model.md §7 noise at ε = Δ
    envs : tuple of str       environments
    restart : bool            delete the output folder's earlier sweep instead of resuming it
    plot_only : bool          redraw the figures and summaries from an existing runs.csv
    quick : bool              recorded; ``main`` turns it into the QUICK budget
    seed : int                root seed (pair sampling and the sweep)
    out : Path                output folder
    workers, dask_local, dask : the executor (see ``add_executor_args``)
    progress : bool           show a progress bar
    """

    pairs: int = FULL["pairs"]
    physics_pairs: int = FULL["physics_pairs"]
    reps: int = FULL["reps"]
    physics_reps: int = FULL["physics_reps"]
    sigmas: tuple[float, ...] = FULL["sigmas"]
    model_r: tuple[float, ...] = FULL["model_r"]
    envs: tuple[str, ...] = ENVS
    restart: bool = False
    plot_only: bool = False
    quick: bool = False
    seed: int = 0
    out: Path = Path("results") / "nav_montecarlo"
    workers: int | None = None
    dask_local: int | None = None
    dask: str | None = None
    progress: bool = True


def run(config: Config) -> Path:
    """Sample the pairs, run (or resume) the sweep, write the summaries and figures.

    With ``plot_only``, redraw from an existing runs.csv. Raises :class:`envs.UserError` for
    a bad budget, a missing runs.csv or a different earlier sweep; returns the output folder.
    """
    out = output_dir(config.out)
    if config.plot_only:
        if not (out / "runs.csv").exists():
            raise envs.UserError(f"{out / 'runs.csv'} does not exist; run the sweep first.")
        _report(out, pd.read_csv(out / "runs.csv"))
        return out
    for key in ("pairs", "reps"):
        if getattr(config, key) < 1:
            raise envs.UserError(f"--{key} must be at least 1, got {getattr(config, key)}.")
    if config.physics_pairs > 0:
        try:
            import pybullet  # noqa: F401
        except ImportError:
            print("nav_montecarlo: pybullet is not installed; running the twin only.")
            config = replace(config, physics_pairs=0)
    budget = {key: getattr(config, key) for key in FULL}
    names = list(config.envs)
    pair_rng = np.random.default_rng(np.random.SeedSequence([config.seed, 1]))
    t0 = time.perf_counter()
    pairs = pd.concat([sample_pairs(name, budget["pairs"], pair_rng) for name in names],
                      ignore_index=True)
    plan_s = time.perf_counter() - t0
    trials = build_trials(pairs, budget)
    if config.restart:
        for f in ("runs.jsonl", "runs.csv", "config.json"):
            (out / f).unlink(missing_ok=True)
    # the keys of this dict are the sweep's identity: earlier result folders resume with it
    record = {"experiment": "nav_montecarlo", "seed": config.seed, "quick": config.quick,
              "envs": names, "angles": list(ANGLES), "w1": W1, "w2": W2,
              "discretisation": "catalogue defaults (0.34 m cells, K = 8, Δ = 45°)",
              "pairs_per_env": budget["pairs"],
              "physics_pairs_per_env": budget["physics_pairs"],
              "gauss_sigmas_deg": list(budget["sigmas"]),
              "model_noise": {"eps_deg": "Δ = 360°/K of the environment (45° at K = 8, "
                              "the smallest non-zero ε the model allows)",
                              "r": list(budget["model_r"])},
              "reps_twin": budget["reps"], "reps_pybullet": budget["physics_reps"],
              "exact_levels_run_once": True,
              "twin_glance_deg": TWIN_GLANCE_DEG,
              "twin_glance_note": "the twin's bumper ignores contacts more than 80° from "
              "the heading, like the PyBullet body's bumper arc (as experiments.nav_fig3)",
              "executor": {"speed_m_s": 0.2, "back_off_m": 0.0},
              "pair_sampling": "uniform without replacement over reachable ordered pairs "
              "(start != goal), numpy default_rng(SeedSequence([seed, 1])), per "
              "environment in order; PyBullet runs the first physics_pairs of them",
              "success": "final position in the goal cell and heading within ±Δ/2 "
              "(docs/model.md §8)",
              "confidence_intervals": "95 % Wilson score (scipy.stats.binomtest)",
              "length_bins": [str(b) for b in LENGTH_BINS]}
    sweep = Sweep(nav_trial, trials, config.seed, out, record, name="runs")
    executor = make_executor(config)
    print(f"nav_montecarlo: {len(pairs)} pairs ({plan_s:.1f} s planning), "
          f"{len(trials)} trials")
    result = sweep.run(executor, progress=config.progress)
    ex = result.executor
    where = f" on {ex['kind']} with {ex['workers']} worker(s)" if "workers" in ex else ""
    print(f"ran {result.n_run} trials ({result.n_resumed} resumed from the journal) in "
          f"{result.wall_s:.1f} s{where}")
    _report(out, result.table)
    return out


def main(argv=None) -> int:
    """Parse the command line into a :class:`Config` and :func:`run` it (exit status)."""
    p = experiment_parser("nav_montecarlo", __doc__.splitlines()[0])
    p.add_argument("--pairs", type=int, default=None,
                   help="pairs per environment (default 300; 12 with --quick)")
    p.add_argument("--physics-pairs", type=int, default=None,
                   help="of those, pairs also run in PyBullet (default 40; 2 with --quick; "
                   "0 for none)")
    p.add_argument("--reps", type=int, default=None,
                   help="noisy repetitions per pair and level in the twin (default 10)")
    p.add_argument("--envs", default=",".join(ENVS), help="environments (default lab,complex)")
    p.add_argument("--restart", action="store_true",
                   help="delete the output folder's earlier sweep instead of resuming it")
    p.add_argument("--plot-only", action="store_true",
                   help="redraw the figure and summaries from an existing runs.csv")
    add_executor_args(p)
    args = p.parse_args(argv)
    budget = dict(QUICK if args.quick else FULL)
    for key in ("pairs", "physics_pairs", "reps"):
        if getattr(args, key) is not None:
            budget[key] = getattr(args, key)
    config = Config(**budget, envs=tuple(s.strip() for s in args.envs.split(",") if s.strip()),
                    restart=args.restart, plot_only=args.plot_only, quick=args.quick,
                    seed=args.seed, out=args.out, workers=args.workers,
                    dask_local=args.dask_local, dask=args.dask, progress=not args.no_progress)
    try:
        run(config)
    except envs.UserError as exc:
        print(f"nav_montecarlo: error: {exc}", file=sys.stderr)
        return 2
    return 0


def _report(out: Path, runs: pd.DataFrame) -> None:
    by_noise = summarise(runs, [])
    by_noise.to_csv(out / "summary_noise.csv", index=False)
    summarise(runs, ["length_bin"]).to_csv(out / "summary_length.csv", index=False)
    summarise(runs, ["angles_used"]).to_csv(out / "summary_angles.csv", index=False)
    summarise(runs, ["headings"]).to_csv(out / "summary_headings.csv", index=False)
    phys = runs.loc[runs["backend"] == "pybullet", ["env", "pair"]].drop_duplicates()
    if len(phys):                   # both backends on the same pairs
        same = runs.merge(phys, on=["env", "pair"])
        summarise(same, []).to_csv(out / "summary_paired.csv", index=False)
    draw(out / "runs.csv", out / "success.png")
    draw_by_length(out / "runs.csv", out / "success_by_length.png")
    cols = ["env", "backend", "noise", "trials", "success_rate", "ci_low", "ci_high",
            "mean_deviations"]
    print(by_noise[cols].to_string(index=False, float_format=lambda x: f"{x:.3f}"))
    print(f"wrote {out}/runs.csv, summary_*.csv, success.png, success_by_length.png, "
          f"config.json")


if __name__ == "__main__":
    sys.exit(main())
