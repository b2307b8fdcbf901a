"""Navigation Monte-Carlo: the planners compared under turn noise, in the twin and PyBullet.

    python -m experiments.nav_montecarlo [--quick] [--seed 0] [--out results/nav_montecarlo]
        [--planners step,exact] [--maps lab,fig1,...] [--pairs N] [--reps N]
        [--sigmas 0,2,5] [--pybullet-pairs N] [--workers N | --dask-local N | --dask ADDRESS]
        [--restart] [--plot-only]

Maps (:func:`world`): the catalogue (``lab``, ``fig1``, ``complex``, ``studio``), random
rectilinear rooms with blocks (``rectN``: :func:`envs.generated.random_rectilinear_room`),
the pentagon room with a hexagonal pillar (``pentagon``) and random pentagon or hexagon rooms
with a polygonal hole (``polyN``: :func:`envs.generated.random_polygon_room`), all at
h = 0.34 m, K = 8. Per map, ``pairs`` ordered (start, goal) pairs (start ≠ goal) are drawn
uniformly without replacement from the pairs the step model reaches (Φ = {45°, 90°, 135°},
w1 = 1, w2 = 100, docs/model.md §12). Every planner of
:data:`experiments.nav_planners.PLANNERS` drives every pair in the kinematic twin (all pairs)
and in PyBullet (the first ``pybullet_pairs`` of each map) under Gaussian turn noise σ
(docs/model.md §11a); success is the goal cell with the heading within ±Δ/2 (§21). A pair the
planner finds no plan for counts as a failure. Every drive is one trial of
:mod:`bouncesim.runs.sweep` (seeded, resumable, any executor).

Outputs in ``--out``: ``runs.csv`` (one row per trial), ``runs.jsonl`` (the resume journal),
``summary_noise.csv`` (per planner, backend and noise level, pooled over the maps as
env = 'all' and per map), ``summary_length.csv``, ``summary_headings.csv``,
``summary_decisions.csv`` (time per decision), ``summary_paired.csv`` (both backends on the
PyBullet pairs), all with 95 % Wilson intervals; ``config.json``; ``success.png`` (success
against noise, one curve per planner), ``success_by_map.png`` and ``success_by_length.png``,
drawn from runs.csv alone (``--plot-only`` redraws them).
"""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import pandas as pd

import envs
from bouncesim import robots
from bouncesim.robots.noise import parse_noise
from bouncesim.runs.executors import add_executor_args, make_executor
from bouncesim.runs.sweep import Sweep
from envs.motion import PYBULLET_CONTACT, ContactParams
from planners.navigation import Navigator

from .common import experiment_parser, invocation, output_dir
from .nav_fig3_physics import TWIN_GLANCE_DEG
from .nav_planners import PLANNERS, NavConfig, NoPlan, cells_of, heading_class, plan_headings, world

__all__ = ["LENGTH_BINS", "MAPS", "Config", "build_trials", "draw", "draw_by_length",
           "draw_by_map", "heading_class", "main", "nav_trial", "plan_headings", "run",
           "sample_pairs", "summarise", "summarise_decisions", "wilson", "world"]

MAPS = ("lab", "fig1", "complex", "studio", "rect1", "rect2", "pentagon", "poly1", "poly2")
ANGLES = (45.0, 90.0, 135.0)
W1, W2 = 1.0, 100.0
LENGTH_BINS = (-np.inf, 5, 10, 20, 40, np.inf)
"""Plan length bins (symbols: zeros plus angles): up to 5, (5, 10], (10, 20], ..."""
CONFIDENCE = 0.95

FULL = {"pairs": 200, "pybullet_pairs": 4, "sigmas": (0.0, 1.0, 2.0, 5.0, 10.0),
        "reps": 10, "pybullet_reps": 1}
QUICK = {"pairs": 4, "pybullet_pairs": 0, "sigmas": (0.0, 2.0, 10.0), "reps": 2,
         "pybullet_reps": 1}
QUICK_MAPS = ("lab", "rect1", "poly1")
MAPS_HELP = ("the catalogue (lab, fig1, complex, studio), rectN (random rectilinear rooms), "
             "pentagon (a pentagon room with a hexagonal pillar), polyN (random pentagon or "
             "hexagon rooms with a hole)")


# ============================================================================ the trial
def nav_trial(params: dict, rng: np.random.Generator) -> dict:
    """Drive one pair once with one planner: the sweep's trial function (pure in ``params``
    and ``rng``; an open-loop plan is computed once per process and pair, and cached).

    ``params``: env, map_seed, start, goal (configuration indices), planner (a
    :data:`PLANNERS` name), backend ('kinematic' or 'pybullet'), noise (``parse_noise`` spec),
    glance (the twin's bumper arc [deg]; 0 for the front-half bumper of docs/model.md §21).
    The rng drives the noise (and any randomness of the planner).
    """
    env = world(params["env"], int(params["map_seed"]))
    cells = cells_of(env)
    spec = params["noise"]
    t0 = time.perf_counter()
    glance = float(params["glance"])
    options = ({"glance_deg": glance} if params["backend"] == "kinematic" and glance > 0
               else {})
    # the exact planner plans for the body's contact rule: the twin's glance_deg, or
    # PyBullet's fitted rule (docs/model.md Appendix B, §9)
    contact = (ContactParams(90.0 - glance, 0.0) if options else
               PYBULLET_CONTACT if params["backend"] == "pybullet" else None)
    config = NavConfig(angles=ANGLES, w1=W1, w2=W2, noise=spec, contact=contact)
    driver = PLANNERS[params["planner"]](env, int(params["start"]), int(params["goal"]),
                                         config, rng)
    robot = robots.make_robot(params["backend"], env, noise=parse_noise(spec, cells.delta_deg),
                              rng=rng, **options)
    try:
        run = driver(robot)
    except NoPlan:
        run = None
    finally:
        robot.close()
    wall = time.perf_counter() - t0
    plan = getattr(driver, "plan", None)
    decisions = int(driver.decisions)
    out = {"has_plan": run is not None,
           "plan": "" if plan is None else plan.exact_text(),
           "length": -1 if plan is None else len(plan.labels),
           "plan_bumps": -1 if plan is None else plan.bumps,
           "angles_used": -1 if plan is None else plan.angles_used,
           "headings": "" if plan is None else heading_class(
               cells.pose(int(params["start"]))[2], plan),
           "decisions": decisions, "decision_s": float(driver.decision_s),
           "decision_ms": 1e3 * float(driver.decision_s) / max(decisions, 1),
           "wall_s": wall}
    if run is None:
        return {"success": False, "completed": False, "reason": "no plan",
                "bumps_executed": 0, "deviations": 0, "early": 0, "late": 0,
                "position_error_m": np.nan, "heading_error_deg": np.nan,
                "final_x": np.nan, "final_y": np.nan, "final_heading": np.nan,
                "sim_time_s": 0.0, **out}
    fx, fy, fh = run.final_pose
    return {"success": bool(run.success), "completed": bool(run.completed),
            "reason": run.reason, "bumps_executed": int(run.bumps),
            "deviations": len(run.deviations),
            "early": sum(d.kind == "early" for d in run.deviations),
            "late": sum(d.kind == "late" for d in run.deviations),
            "position_error_m": float(run.position_error),
            "heading_error_deg": float(run.heading_error),
            "final_x": float(fx), "final_y": float(fy), "final_heading": float(fh),
            "sim_time_s": float(run.elapsed), **out}


# ============================================================================ pairs and trials
def sample_pairs(name: str, seed: int, n: int, rng: np.random.Generator) -> pd.DataFrame:
    """``n`` ordered pairs (start ≠ goal) the step model reaches, drawn uniformly without
    replacement (all of them when there are fewer).
    """
    ap = Navigator(cells_of(world(name, seed)), ANGLES, W1, W2).all_pairs()
    W = ap.weights.copy()
    np.fill_diagonal(W, -1.0)
    ii, jj = np.nonzero(W > 0)
    pick = np.sort(rng.choice(len(ii), size=min(n, len(ii)), replace=False))
    return pd.DataFrame({"env": name, "pair": np.arange(len(pick)),
                         "start": ii[pick].astype(int), "goal": jj[pick].astype(int)})


def build_trials(pairs: pd.DataFrame, planners, budget: dict, map_seed: int,
                 glance: float = TWIN_GLANCE_DEG) -> list[dict]:
    """Every (pair, planner, backend, noise level, repetition) as sweep parameters.

    The noise-free level runs once: the open-loop plans and both simulators are then
    deterministic.
    """
    trials = []
    for _, p in pairs.iterrows():
        backends = [("kinematic", budget["reps"])]
        if p["pair"] < budget["pybullet_pairs"]:
            backends.append(("pybullet", budget["pybullet_reps"]))
        for planner in planners:
            for backend, reps in backends:
                for sigma in budget["sigmas"]:
                    for rep in range(1 if sigma == 0 else reps):
                        trials.append({"env": p["env"], "map_seed": int(map_seed),
                                       "pair": int(p["pair"]), "start": int(p["start"]),
                                       "goal": int(p["goal"]), "planner": planner,
                                       "backend": backend, "noise": f"gauss:{sigma:g}",
                                       "noise_kind": "gauss", "noise_level": float(sigma),
                                       "rep": rep, "glance": float(glance)})
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


LENGTH_LABELS = ["0-5", "6-10", "11-20", "21-40", "41+"]
"""Labels of LENGTH_BINS, in order."""


def length_bin(length) -> pd.Series:
    """Plan length [symbols] binned into LENGTH_BINS, labelled by LENGTH_LABELS."""
    return pd.cut(pd.Series(length), bins=list(LENGTH_BINS), labels=LENGTH_LABELS).astype(str)


def summarise(runs: pd.DataFrame, by: list[str]) -> pd.DataFrame:
    """Success rate with a 95 % Wilson interval per (planner, backend, noise level, *by*),
    plus mean deviations and the median final position error [m].
    """
    runs = runs.copy()
    if "length_bin" in by:
        runs["length_bin"] = pd.Categorical(length_bin(runs["length"]).values,
                                            categories=LENGTH_LABELS, ordered=True)
        runs = runs[runs["length"] >= 0]                   # no plan: no length
    keys = ["planner", "backend", "noise_kind", "noise_level", "noise", *by]
    g = runs.groupby(keys, sort=True, dropna=False, observed=True)
    out = g.agg(trials=("success", "size"), successes=("success", "sum"),
                pairs=("pair", "nunique"), mean_deviations=("deviations", "mean"),
                median_position_error_m=("position_error_m", "median")).reset_index()
    out["successes"] = out["successes"].astype(int)
    out["success_rate"] = out["successes"] / out["trials"]
    out["ci_low"], out["ci_high"] = wilson(out["successes"].to_numpy(),
                                           out["trials"].to_numpy())
    return out


def summarise_noise(runs: pd.DataFrame) -> pd.DataFrame:
    """:func:`summarise` pooled over the maps (env = 'all'; ``pairs`` then counts pairs
    summed over the maps) and per map.
    """
    runs = runs.assign(pair=runs["env"] + ":" + runs["pair"].astype(str))
    pooled = summarise(runs, []).assign(env="all")
    per_map = summarise(runs, ["env"])
    return pd.concat([pooled, per_map], ignore_index=True)


def summarise_decisions(runs: pd.DataFrame) -> pd.DataFrame:
    """Time per decision [ms] per (planner, map) in the twin: the mean (total decision time
    over total decisions), the median and the maximum over the trials.
    """
    twin = runs[runs["backend"] == "kinematic"]
    g = twin.groupby(["planner", "env"], sort=True)
    out = g.agg(trials=("decision_s", "size"), decisions=("decisions", "sum"),
                decision_s=("decision_s", "sum"), median_ms=("decision_ms", "median"),
                max_ms=("decision_ms", "max")).reset_index()
    out["mean_ms"] = 1e3 * out["decision_s"] / out["decisions"].clip(lower=1)
    return out.drop(columns="decision_s")


# ============================================================================ figures
def _errorbar(ax, part, label, dodge=0.0, **style) -> None:
    part = part.sort_values("noise_level")
    x = part["noise_level"].to_numpy() + dodge
    y = part["success_rate"].to_numpy()
    err = np.vstack([y - part["ci_low"].to_numpy(), part["ci_high"].to_numpy() - y])
    ax.errorbar(x, y, yerr=err, capsize=3, ms=4, label=label, **style)


def _planner_style(planners) -> dict:
    colours = {"step": "#888888", "exact": "#3b75af", "reliable": "#e08214",
               "feedback": "#2ca02c"}
    markers = {"step": "o", "exact": "s", "reliable": "^", "feedback": "D"}
    return {p: {"color": colours.get(p, f"C{i + 4}"), "marker": markers.get(p, "v")}
            for i, p in enumerate(planners)}


def draw(runs_csv: Path, path: Path) -> None:
    """Success against Gaussian turn noise σ, one curve per planner, pooled over the maps
    (the twin solid, the PyBullet subset dashed), from runs.csv.
    """
    from bouncesim.plots import plt, save_figure

    runs = pd.read_csv(runs_csv)
    s = summarise_noise(runs)
    s = s[(s["env"] == "all") & (s["noise_kind"] == "gauss")]
    planners = list(dict.fromkeys(runs["planner"]))
    style = _planner_style(planners)
    n_maps = runs["env"].nunique()
    span = max(float(s["noise_level"].max()), 1.0)
    fig, ax = plt.subplots(figsize=(6.8, 4.3))
    for i, planner in enumerate(planners):
        for backend, ls, fill in (("kinematic", "-", None), ("pybullet", "--", "none")):
            part = s[(s["planner"] == planner) & (s["backend"] == backend)]
            if part.empty:
                continue
            where = "twin" if backend == "kinematic" else "PyBullet"
            dodge = (i - (len(planners) - 1) / 2) * 0.012 * span + (
                0.006 * span if backend == "pybullet" else 0.0)
            _errorbar(ax, part, f"{planner}, {where} ({int(part['pairs'].max())} pairs)",
                      dodge, ls=ls, mfc=fill, lw=1.6 if backend == "kinematic" else 1.0,
                      **style[planner])
    ax.set_xlabel("Gaussian turn noise σ [deg]")
    ax.set_ylabel("success rate (95 % Wilson interval)")
    ax.set_ylim(-0.02, 1.02)
    ax.set_xticks(sorted(s["noise_level"].unique()))
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7.5, loc="upper right")
    glance = float(runs["glance"].iloc[0]) if "glance" in runs else 0.0
    arc = f"±{glance:g}°" if glance > 0 else "front half"
    ax.set_title(f"Navigation success under turn noise: {n_maps} maps pooled\n"
                 f"(Φ = {{45°, 90°, 135°}}, K = 8, pairs the step model reaches; twin bumper "
                 f"{arc})", fontsize=9)
    save_figure(fig, path, dpi=130)


def draw_by_map(runs_csv: Path, path: Path) -> None:
    """Success against σ per map (twin), one curve per planner, from runs.csv."""
    from bouncesim.plots import plt, save_figure

    runs = pd.read_csv(runs_csv)
    s = summarise_noise(runs)
    s = s[(s["env"] != "all") & (s["backend"] == "kinematic")]
    names = list(dict.fromkeys(runs["env"]))
    planners = list(dict.fromkeys(runs["planner"]))
    style = _planner_style(planners)
    cols = min(len(names), 3)
    rows = -(-len(names) // cols)
    fig, axes = plt.subplots(rows, cols, figsize=(3.4 * cols, 2.6 * rows), sharex=True,
                             sharey=True, squeeze=False)
    for ax, name in zip(axes.flat, names):
        for planner in planners:
            part = s[(s["env"] == name) & (s["planner"] == planner)]
            if not part.empty:
                _errorbar(ax, part, planner, lw=1.3, **style[planner])
        n = int(s.loc[s["env"] == name, "pairs"].max())
        ax.set_title(f"{name} ({n} pairs)", fontsize=9)
        ax.set_ylim(-0.02, 1.02)
        ax.grid(alpha=0.3)
    for ax in axes.flat[len(names):]:
        ax.set_visible(False)
    for ax in axes[-1]:
        ax.set_xlabel("σ [deg]")
    for ax in axes[:, 0]:
        ax.set_ylabel("success (twin)")
    axes.flat[0].legend(fontsize=7)
    save_figure(fig, path, dpi=130)


def draw_by_length(runs_csv: Path, path: Path) -> None:
    """Success against plan length (binned) in the twin, one panel per planner, one curve
    per noise level, pooled over the maps, from runs.csv.
    """
    from bouncesim.plots import plt, save_figure

    runs = pd.read_csv(runs_csv)
    runs = runs[(runs["backend"] == "kinematic") & (runs["length"] >= 0)]
    if runs.empty:
        return
    runs = runs.assign(pair=runs["env"] + ":" + runs["pair"].astype(str))
    s = summarise(runs, ["length_bin"])
    planners = list(dict.fromkeys(runs["planner"]))
    fig, axes = plt.subplots(1, len(planners), figsize=(5.0 * len(planners), 3.8),
                             sharey=True, squeeze=False)
    for ax, planner in zip(axes[0], planners):
        sub = s[s["planner"] == planner]
        levels = sorted(sub["noise_level"].unique())
        for i, level in enumerate(levels):
            part = sub[sub["noise_level"] == level]
            x = np.array([LENGTH_LABELS.index(b) for b in part["length_bin"]]) + 0.05 * (
                i - (len(levels) - 1) / 2)
            y = part["success_rate"].to_numpy()
            err = np.vstack([y - part["ci_low"].to_numpy(), part["ci_high"].to_numpy() - y])
            ax.errorbar(x, y, yerr=err, marker="o", ms=3.5, capsize=2, lw=1.2,
                        label=f"σ = {level:g}°")
        mine = runs[runs["planner"] == planner].drop_duplicates("pair")
        n_by_bin = mine.assign(b=length_bin(mine["length"]).values).groupby("b").size()
        ax.set_xticks(range(len(LENGTH_LABELS)))
        ax.set_xticklabels([f"{b}\n({int(n_by_bin.get(b, 0))} pairs)" for b in LENGTH_LABELS],
                           fontsize=8)
        ax.set_xlabel("plan length [symbols]")
        ax.set_title(f"{planner} planner, twin, all maps", fontsize=10)
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
    pairs : int               pairs per map
    pybullet_pairs : int      of those, pairs also driven in PyBullet (0 for none)
    reps : int                noisy repetitions per pair, planner and level in the twin
    pybullet_reps : int       noisy repetitions per pair, planner and level in PyBullet
    sigmas : tuple of float   Gaussian turn noise σ [deg] (docs/model.md §11a)
    twin_glance : float       the twin's bumper arc [deg] (80: like the PyBullet body;
                              0: the front-half bumper the planners model, §21)
    planners : tuple of str   names in :data:`experiments.nav_planners.PLANNERS`
    maps : tuple of str       map names (:func:`world`)
    restart : bool            delete the output folder's earlier sweep instead of resuming it
    plot_only : bool          redraw the figures and summaries from an existing runs.csv
    quick : bool              recorded; ``main`` turns it into the QUICK budget
    seed : int                root seed (random maps, pair sampling and the sweep)
    out : Path                output folder
    workers, dask_local, dask : the executor (see ``add_executor_args``)
    progress : bool           show a progress bar
    """

    pairs: int = FULL["pairs"]
    pybullet_pairs: int = FULL["pybullet_pairs"]
    reps: int = FULL["reps"]
    pybullet_reps: int = FULL["pybullet_reps"]
    sigmas: tuple[float, ...] = FULL["sigmas"]
    twin_glance: float = TWIN_GLANCE_DEG
    planners: tuple[str, ...] = ("step", "exact")
    maps: tuple[str, ...] = MAPS
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
    a bad budget, an unknown planner or map, a missing runs.csv or a different earlier
    sweep; returns the output folder.
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
    if not config.sigmas or not all(np.isfinite(v) and v >= 0 for v in config.sigmas):
        raise envs.UserError(f"--sigmas must be non-negative numbers [deg], got "
                             f"{', '.join(f'{v:g}' for v in config.sigmas) or '(none)'}.")
    unknown = [p for p in config.planners if p not in PLANNERS]
    if unknown or not config.planners:
        raise envs.UserError(f"unknown planner {', '.join(unknown) or '(none)'}; choose from "
                             f"{', '.join(PLANNERS)}.")
    if config.pybullet_pairs > 0:
        try:
            import pybullet  # noqa: F401
        except ImportError:
            print("nav_montecarlo: pybullet is not installed; running the twin only.")
            config = replace(config, pybullet_pairs=0)
    budget = {key: getattr(config, key) for key in FULL}
    pair_rng = np.random.default_rng(np.random.SeedSequence([config.seed, 1]))
    t0 = time.perf_counter()
    pairs = pd.concat([sample_pairs(name, config.seed, budget["pairs"], pair_rng)
                       for name in config.maps], ignore_index=True)
    sample_s = time.perf_counter() - t0
    trials = build_trials(pairs, config.planners, budget, config.seed, config.twin_glance)
    if config.restart:
        for f in ("runs.jsonl", "runs.csv", "config.json"):
            (out / f).unlink(missing_ok=True)
    # the keys of this dict are the sweep's identity: earlier result folders resume with it
    record = {"experiment": "nav_montecarlo", "seed": config.seed, "quick": config.quick,
              "maps": list(config.maps), "planners": list(config.planners),
              "angles": list(ANGLES), "w1": W1, "w2": W2,
              "discretisation": "0.34 m cells, K = 8, Δ = 45° on every map",
              "pairs_per_map": budget["pairs"],
              "pybullet_pairs_per_map": budget["pybullet_pairs"],
              "gauss_sigmas_deg": list(budget["sigmas"]),
              "reps_twin": budget["reps"], "reps_pybullet": budget["pybullet_reps"],
              "noise_free_level_run_once": True,
              "twin_glance_deg": config.twin_glance,
              "twin_glance_note": "the twin's bumper ignores contacts more than this from "
              "the heading (80: the PyBullet body's bumper arc, as experiments.nav_fig3; "
              "0: the front-half bumper of docs/model.md §21 that the planners model)",
              "executor": {"speed_m_s": 0.2, "back_off_m": 0.0},
              "pair_sampling": "uniform without replacement over the ordered pairs "
              "(start != goal) the step model reaches, numpy default_rng(SeedSequence([seed, "
              "1])), per map in order; PyBullet drives the first pybullet_pairs of them",
              "random_maps": "rectN: envs.generated.random_rectilinear_room, polyN: "
              "envs.generated.random_polygon_room(sides=(5, 7)), each with "
              "default_rng(SeedSequence([seed, 3, 0 or 1, N]))",
              "success": "final position in the goal cell and heading within ±Δ/2 "
              "(docs/model.md §21); a pair without a plan is a failure",
              "decision_time": "open-loop planners: one decision per drive, the wall time "
              "of the plan query (computed once per worker process and pair, then cached)",
              "confidence_intervals": "95 % Wilson score (scipy.stats.binomtest)",
              "length_bins": LENGTH_LABELS}
    sweep = Sweep(nav_trial, trials, config.seed, out, record, name="runs",
                  provenance=invocation(config.seed))
    executor = make_executor(config)
    print(f"nav_montecarlo: {len(pairs)} pairs on {len(config.maps)} maps "
          f"({sample_s:.1f} s sampling), {len(trials)} trials")
    result = sweep.run(executor, progress=config.progress)
    ex = result.executor
    where = f" on {ex['kind']} with {ex['workers']} worker(s)" if "workers" in ex else ""
    print(f"ran {result.n_run} trials ({result.n_resumed} resumed from the journal) in "
          f"{result.wall_s:.1f} s{where}")
    _report(out, result.table)
    return out


def _csv_list(text: str) -> tuple[str, ...]:
    return tuple(s.strip() for s in str(text).split(",") if s.strip())


def main(argv=None) -> int:
    """Parse the command line into a :class:`Config` and :func:`run` it (exit status)."""
    p = experiment_parser("nav_montecarlo", __doc__.splitlines()[0])
    p.add_argument("--pairs", type=int, default=None,
                   help=f"pairs per map (default {FULL['pairs']}; {QUICK['pairs']} with "
                   "--quick)")
    p.add_argument("--pybullet-pairs", "--physics-pairs", dest="pybullet_pairs", type=int,
                   default=None, help=f"of those, pairs also driven in PyBullet (default "
                   f"{FULL['pybullet_pairs']}; {QUICK['pybullet_pairs']} with --quick)")
    p.add_argument("--reps", type=int, default=None,
                   help=f"noisy repetitions per pair, planner and level in the twin (default "
                   f"{FULL['reps']}; {QUICK['reps']} with --quick)")
    p.add_argument("--sigmas", default=None,
                   help="Gaussian turn noise levels σ [deg], comma-separated (default "
                   f"{','.join(f'{v:g}' for v in FULL['sigmas'])}; "
                   f"{','.join(f'{v:g}' for v in QUICK['sigmas'])} with --quick)")
    p.add_argument("--planners", default="step,exact",
                   help=f"planners to compare (registered: {', '.join(PLANNERS)})")
    p.add_argument("--maps", default=None, help=f"maps: {MAPS_HELP} (default {','.join(MAPS)}; "
                   f"{','.join(QUICK_MAPS)} with --quick)")
    p.add_argument("--twin-glance", type=float, default=TWIN_GLANCE_DEG,
                   help="the twin's bumper arc [deg] (default 80, the PyBullet body's; 0 for "
                   "the front-half bumper the planners model)")
    p.add_argument("--restart", action="store_true",
                   help="delete the output folder's earlier sweep instead of resuming it")
    p.add_argument("--plot-only", action="store_true",
                   help="redraw the figures and summaries from an existing runs.csv")
    add_executor_args(p)
    args = p.parse_args(argv)
    import matplotlib
    matplotlib.use("Agg")                      # this script writes files only
    budget = dict(QUICK if args.quick else FULL)
    for key in ("pairs", "pybullet_pairs", "reps"):
        if getattr(args, key) is not None:
            budget[key] = getattr(args, key)
    if args.sigmas is not None:
        try:
            budget["sigmas"] = tuple(float(v) for v in _csv_list(args.sigmas))
        except ValueError:
            p.error(f"--sigmas takes comma-separated numbers [deg], got {args.sigmas!r}")
    maps = _csv_list(args.maps) if args.maps else (QUICK_MAPS if args.quick else MAPS)
    config = Config(**budget, planners=_csv_list(args.planners), maps=maps,
                    twin_glance=args.twin_glance,
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
    by_noise = summarise_noise(runs)
    by_noise.to_csv(out / "summary_noise.csv", index=False)
    pooled = runs.assign(pair=runs["env"] + ":" + runs["pair"].astype(str))
    summarise(pooled, ["length_bin"]).to_csv(out / "summary_length.csv", index=False)
    summarise(pooled[pooled["headings"].notna()], ["env", "headings"]).to_csv(
        out / "summary_headings.csv", index=False)
    decisions = summarise_decisions(runs)
    decisions.to_csv(out / "summary_decisions.csv", index=False)
    phys = runs.loc[runs["backend"] == "pybullet", ["env", "pair"]].drop_duplicates()
    if len(phys):                   # both backends on the same pairs
        same = runs.merge(phys, on=["env", "pair"])
        summarise_noise(same).to_csv(out / "summary_paired.csv", index=False)
    draw(out / "runs.csv", out / "success.png")
    draw_by_map(out / "runs.csv", out / "success_by_map.png")
    draw_by_length(out / "runs.csv", out / "success_by_length.png")
    cols = ["planner", "backend", "noise", "trials", "success_rate", "ci_low", "ci_high"]
    print(by_noise.loc[by_noise["env"] == "all", cols].to_string(
        index=False, float_format=lambda x: f"{x:.3f}"))
    print(decisions.to_string(index=False, float_format=lambda x: f"{x:.2f}"))
    print(f"wrote {out}/runs.csv, summary_*.csv, success.png, success_by_map.png, "
          f"success_by_length.png, config.json")


if __name__ == "__main__":
    sys.exit(main())
