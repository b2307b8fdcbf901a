"""Navigation a real robot can trust: every planner on several bodies, under biased turns,
sensor faults and an unknown start, on maps nobody tuned on (docs/model.md §15).

    python -m experiments.nav_robustness [--quick] [--seed 0] [--out results/nav_robustness]
        [--maps lab,lroom,...] [--pairs N] [--bodies twin,nearest,...]
        [--conditions sigma0,sigma2,...] [--workers N | --dask-local N | --dask ADDRESS]
        [--restart] [--plot-only]

Bodies (the robot that runs; the navigator is never told which):

- ``twin``: the kinematic twin with the front-half bumper (docs/model.md §21);
- ``twin-rule``: the twin with PyBullet's fitted contact rule (glancing contacts slide, §9);
- ``nearest``: the twin whose bumper side comes from the wall point nearest its centre;
- ``pybullet``: the PyBullet Create 2 (needs the ``sim`` extra; slow);
- ``mujoco``: the MuJoCo Create 2 (needs the ``mujoco`` extra), a second engine built by
  another team, which declares no contact rule (the navigator plans with the front-half
  bumper);
- ``create3``: the Create 3 adapter on its emulator of the twin.

Conditions (``CONDITIONS``): Gaussian turn noise σ = 0, 2, 5°; a body that turns 8 % short or
long while the navigator knows only 1 ± 10 % (``gauss:2,scale=0.1``); 5 % of bumper sides
misread; 2 % of bumps missed (:class:`bouncesim.robots.faulty.FaultyRobot`); an unknown start
(σ = 2°: the body at a random pose, the navigator told nothing). Planners: ``feedback`` in
every condition; the open-loop ``exact`` and ``reliable`` plans under the noise conditions
(the headline figure).

Maps: the catalogue (``lab``, ``fig1``, ``studio``) and held-out ones generated without
tuning: ``lroom`` (an L-shaped room with an octagonal pillar off the grid), ``office40`` (two
rooms and a 0.40 m door), ``pentahex`` (a pentagon with a hexagonal pillar) and ``slantedN``
(random rooms with slanted walls and pillars), all at h = 0.34 m, K = 8, Φ = {45°, 90°, 135°}.
Pairs: drawn uniformly from the (start, goal) pairs the exact planner reaches. Under
PyBullet's contact rule (the bodies ``twin-rule`` and ``pybullet``) some of them have no
plan at all; each run records whether its pair is ``reachable`` for its body, and the
summary gives the success over those pairs too (``success_reachable``).

Outputs in ``--out``: ``runs.csv`` (one row per run: success, bumps, bumps to localize, the
turn estimate, decision CPU times, reachable, the belief's mass in the goal cell at the
final drive ``stop_mass``), ``summary.csv`` (per planner, body and
condition, pooled over the maps and per map: Wilson 95 % intervals, median bumps, median
bumps to localize, decision CPU p50/p95/max), ``outcomes.csv`` (runs per way of ending:
reached, stopped outside the cell, heading off, bump budget spent, no bump; pooled and per
map), ``config.json``, ``success_vs_sigma.png`` (success against σ for the open-loop exact
and reliable plans and feedback) and ``maps.png`` (every map with feedback's success at σ =
2° per body), drawn from runs.csv alone.
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
from bouncesim.robots.kinematic import KinematicRobot
from bouncesim.robots.noise import parse_noise
from bouncesim.runs.drivers import NavConfig, declared_noise
from bouncesim.runs.execute import execute
from bouncesim.runs.executors import add_executor_args, make_executor
from bouncesim.runs.options import with_options
from bouncesim.runs.sweep import Sweep
from envs.motion import PYBULLET_CONTACT
from planners.cells import CellSpace
from planners.navigation import make_planner, planner_class
from planners.navigation.feedback import DEFAULT_MAX_BUMPS, FeedbackConfig, FeedbackNavigator

from .common import experiment_parser, invocation, name_list, output_dir, run_main
from .nav_montecarlo import wilson
from .nav_planners import world

__all__ = ["BODIES", "CONDITIONS", "Config", "build_trials", "draw", "draw_maps",
           "feedback_config", "main", "maps_of", "run", "sample_pairs", "summarise", "trial"]

ANGLES = (45.0, 90.0, 135.0)
BODIES = ("twin", "twin-rule", "nearest", "pybullet", "mujoco", "create3")
CONDITIONS = {
    # name: (body's turn noise, the navigator's declared noise, p_side, p_miss, unknown start)
    "sigma0": ("gauss:0", "gauss:0", 0.0, 0.0, False),
    "sigma1": ("gauss:1", "gauss:1", 0.0, 0.0, False),
    "sigma2": ("gauss:2", "gauss:2", 0.0, 0.0, False),
    "sigma5": ("gauss:5", "gauss:5", 0.0, 0.0, False),
    "scale0.92": ("gauss:2,factor=0.92", "gauss:2,scale=0.1", 0.0, 0.0, False),
    "scale1.08": ("gauss:2,factor=1.08", "gauss:2,scale=0.1", 0.0, 0.0, False),
    "side5": ("gauss:2", "gauss:2", 0.05, 0.0, False),
    "miss2": ("gauss:2", "gauss:2", 0.0, 0.02, False),
    "unknown": ("gauss:2", "gauss:2", 0.0, 0.0, True),
}
NOISE_ONLY = ("sigma0", "sigma1", "sigma2", "sigma5")
"""Conditions the open-loop planners run in (they know neither faults nor unknown starts)."""
MAPS = ("lab", "fig1", "studio", "lroom", "office40", "pentahex", "slanted1", "slanted2")
QUICK_MAPS = ("lab", "lroom")
TUNED = ("lab", "fig1", "studio")
"""The catalogue maps the feedback navigator's settings were chosen on; the rest are held
out."""
CONFIDENCE = 0.95


@lru_cache(maxsize=32)
def maps_of(name: str, seed: int = 0) -> envs.Environment:
    """A map by name: :func:`experiments.nav_planners.world`'s names, and the held-out
    generated rooms of :mod:`envs.generated` (``lroom``, ``office40``, ``pentahex``,
    ``slantedN``), all at K = 8.
    """
    from envs import generated
    if name == "lroom":
        return generated.l_room_octagon(orientations=8)
    if name == "office40":
        return generated.office(door=0.40, orientations=8)
    if name == "pentahex":
        return envs.Environment.from_dict(generated.PENTAGON)
    if name.startswith("slanted") and name[7:].isdigit():
        rng = np.random.default_rng(np.random.SeedSequence([seed, 27, int(name[7:])]))
        return generated.slanted_room(rng, orientations=8)
    return world(name, seed)


@lru_cache(maxsize=32)
def _cells(name: str, seed: int) -> CellSpace:
    return CellSpace(maps_of(name, seed))


# ============================================================================ the trial
def _body(kind: str, env, noise, rng, p_side: float, p_miss: float):
    if kind == "twin":
        body = KinematicRobot(env, noise, rng)
    elif kind == "twin-rule":
        body = KinematicRobot(env, noise, rng, contact=PYBULLET_CONTACT)
    elif kind == "nearest":
        body = KinematicRobot(env, noise, rng, side_rule="nearest")
    elif kind in ("pybullet", "mujoco"):
        from bouncesim.robots import make_robot
        body = make_robot(kind, env, noise=noise, rng=rng)
    elif kind == "create3":             # the Create 3 adapter on its emulator of the twin
        from bouncesim.robots import make_robot
        body = make_robot("create3-emulator", env, noise=noise, rng=rng, glance_deg=None)
    else:
        raise envs.UserError(f"unknown body {kind!r}; choose from {', '.join(BODIES)}.")
    if p_side or p_miss:
        from bouncesim.robots.faulty import FaultyRobot
        body = FaultyRobot(body, p_side=p_side, p_miss=p_miss, rng=rng)
    return body


@lru_cache(maxsize=8)
def _rule_navigator(name: str, seed: int):
    return make_planner("exact", _cells(name, seed), ANGLES, contact=PYBULLET_CONTACT)


def reachable(params: dict) -> bool:
    """Whether the exact planner reaches the pair's goal noise-free under the body's contact
    rule (the pairs are drawn reachable without one; PyBullet's rule slides glancing flights
    on, and makes some of them unreachable for any angle sequence the planner knows).
    """
    if params["body"] not in ("twin-rule", "pybullet"):
        return True
    nav = _rule_navigator(params["env"], int(params["map_seed"]))
    return nav.plan(int(params["start"]), int(params["goal"])) is not None


def trial(params: dict, rng: np.random.Generator) -> dict:
    """Drive one pair once: the sweep's trial function (pure in ``params`` and ``rng``).

    ``params``: env, map_seed, start, goal, planner, body, condition (a :data:`CONDITIONS`
    name), feedback (``FeedbackConfig`` fields as "key=value,..."; "" for the defaults),
    max_bumps (the feedback run's budget). The rng drives the body's noise and faults, its
    random start and the navigator.
    """
    env = maps_of(params["env"], int(params["map_seed"]))
    cs = _cells(params["env"], int(params["map_seed"]))
    body_spec, declared, p_side, p_miss, unknown = CONDITIONS[params["condition"]]
    body_rng, nav_rng, start_rng = rng.spawn(3)
    noise = parse_noise(body_spec, cs.delta_deg)
    body = _body(params["body"], env, noise, body_rng, p_side, p_miss)
    s, g, name = int(params["start"]), int(params["goal"]), params["planner"]
    rule = PYBULLET_CONTACT if params["body"] in ("twin-rule", "pybullet") else None
    t0 = time.perf_counter()
    try:
        if planner_class(name).closed_loop:
            budget = int(params.get("max_bumps", DEFAULT_MAX_BUMPS))
            planner = make_planner(name, cs, ANGLES, noise=declared, rng=nav_rng,
                                   contact="auto",
                                   config=feedback_config(params.get("feedback", "")))
            start = None
            if unknown:
                body.place(*env.random_pose(start_rng))
            else:
                start = s
            run = execute(planner.policy(start, g, max_bumps=budget), body, cells=cs)
        else:
            spec = declared_noise(NavConfig(noise=declared, contact=rule))
            kw = {"noise": spec, "rng": nav_rng} if "rng" in planner_class(name).needs else {}
            if "contact" in planner_class(name).needs:
                kw["contact"] = rule
            route = make_planner(name, cs, ANGLES, **kw).plan(s, g)
            run = None if route is None else execute(route.plan, body, start=s, goal=g,
                                                     cells=cs)
    finally:
        body.close()
    wall = time.perf_counter() - t0
    if run is None:
        return {"success": False, "reason": "no plan", "bumps": 0, "bumps_to_localize": -1,
                "turn_factor": np.nan, "decisions": 0, "decision_cpu_ms": "",
                "position_error_m": np.nan, "wall_s": wall, "reachable": reachable(params),
                "stop_mass": np.nan}
    cpu = getattr(run, "decision_cpu_ms", ())
    loc = getattr(run, "bumps_to_localize", 0)
    return {"success": bool(run.success), "reason": run.reason, "bumps": int(run.bumps),
            "bumps_to_localize": -1 if loc is None else int(loc),
            "turn_factor": float(getattr(run, "turn_estimate", (np.nan,))[0]),
            "decisions": len(cpu), "decision_cpu_ms": " ".join(f"{v:.2f}" for v in cpu),
            "position_error_m": np.nan if run.position_error is None
            else float(run.position_error), "wall_s": wall, "reachable": reachable(params),
            "stop_mass": float(getattr(run, "stop_mass", np.nan))}


def feedback_config(text: str) -> FeedbackConfig:
    """A :class:`FeedbackConfig` from "key=value,..." (numbers, or true/false; "" for the
    defaults).
    """
    items = [t for t in (t.strip() for t in str(text).split(",")) if t]
    return with_options(FeedbackConfig(), items, "--feedback", " (FeedbackConfig's fields)")


# ============================================================================ pairs and trials
def sample_pairs(name: str, seed: int, n: int, rng: np.random.Generator) -> pd.DataFrame:
    """``n`` ordered pairs (start ≠ goal) the exact planner reaches noise-free, drawn
    uniformly (rejection over random pairs; all reachable pairs are not enumerated).
    """
    cs = _cells(name, seed)
    nav = make_planner("exact", cs, ANGLES)
    rows, tries = [], 0
    while len(rows) < n and tries < 50 * n:
        tries += 1
        s, g = (int(v) for v in rng.choice(cs.N, 2, replace=False))
        if (s, g) not in {(r[0], r[1]) for r in rows} and nav.plan(s, g) is not None:
            rows.append((s, g))
    return pd.DataFrame({"env": name, "pair": np.arange(len(rows)),
                         "start": [r[0] for r in rows], "goal": [r[1] for r in rows]})


def build_trials(pairs: pd.DataFrame, planners, bodies, conditions, map_seed: int,
                 reps: int, feedback: str = "",
                 max_bumps: int = DEFAULT_MAX_BUMPS) -> list[dict]:
    """Every (pair, planner, body, condition, repetition) as sweep parameters; the
    open-loop planners only under the noise conditions, and σ = 0 runs once.
    """
    out = []
    for _, p in pairs.iterrows():
        for name in planners:
            closed = planner_class(name).closed_loop
            for body in bodies:
                for cond in conditions:
                    if not closed and cond not in NOISE_ONLY:
                        continue
                    for rep in range(1 if cond == "sigma0" else reps):
                        out.append({"env": p["env"], "map_seed": int(map_seed),
                                    "pair": int(p["pair"]), "start": int(p["start"]),
                                    "goal": int(p["goal"]), "planner": name, "body": body,
                                    "condition": cond, "rep": rep, "feedback": feedback,
                                    "max_bumps": int(max_bumps)})
    return out


# ============================================================================ statistics
def _p(values: pd.Series, q: float) -> float:
    v = np.concatenate([np.array(s.split(), dtype=float) for s in values.fillna("") if s]
                       or [np.array([])])
    return float(np.percentile(v, q)) if v.size else np.nan


OUTCOMES = (("reached", "reached the goal"), ("stopped outside the cell", "ended "),
            ("heading off", "heading off"), ("bump budget spent", "gave up"),
            ("no bump", "no bump"))
"""How a run ended, by the start of its reason (``bouncesim.runs.runners.plan_result`` and
the feedback runner write them): (class, reason prefix); anything else is "other"."""


def outcome_class(reason: str) -> str:
    """The :data:`OUTCOMES` class of a run's reason.

    >>> outcome_class("gave up after 40 bumps"), outcome_class("reached the goal")
    ('bump budget spent', 'reached')
    """
    return next((name for name, prefix in OUTCOMES if str(reason).startswith(prefix)),
                "other")


def outcomes(runs: pd.DataFrame) -> pd.DataFrame:
    """Runs per outcome class (:func:`outcome_class`) per (planner, body, condition), pooled
    over the maps (env = 'all') and per map: where the failures come from.
    """
    runs = runs.assign(outcome=runs.reason.map(outcome_class))
    names = [n for n, _ in OUTCOMES] + ["other"]
    parts = []
    for by, pooled in ((["planner", "body", "condition"], "all"),
                       (["planner", "body", "condition", "env"], None)):
        t = runs.pivot_table(index=by, columns="outcome", values="trial", aggfunc="size",
                             fill_value=0).reindex(columns=names, fill_value=0).reset_index()
        if pooled is not None:
            t.insert(3, "env", pooled)
        parts.append(t)
    out = pd.concat(parts, ignore_index=True)
    out.columns.name = None
    return out


def summarise(runs: pd.DataFrame) -> pd.DataFrame:
    """Per (planner, body, condition), pooled over the maps (env = 'all'), over the held-out
    maps (env = 'held-out': those not in :data:`TUNED`, when the run has any) and per map:
    runs, successes, success rate with its Wilson interval, the success rate over the pairs
    the body's contact rule leaves reachable (:func:`reachable`), median bumps, median bumps
    to localize (unknown starts that localized), the share that never localized, and the
    decision CPU p50, p95 and maximum [ms] over every decision.
    """
    if "reachable" not in runs:                 # a table from before the column
        runs = runs.assign(reachable=True)
    runs = runs.assign(reach_ok=runs.success.astype(bool) & runs.reachable.astype(bool))
    parts = []
    held = runs[~runs.env.isin(TUNED)]
    for by, rows, pooled in ((["planner", "body", "condition"], runs, "all"),
                             (["planner", "body", "condition"], held, "held-out"),
                             (["planner", "body", "condition", "env"], runs, None)):
        if rows.empty or (pooled == "held-out" and held.env.nunique() == runs.env.nunique()):
            continue
        g = rows.groupby(by, sort=True)
        out = g.agg(runs=("success", "size"), successes=("success", "sum"),
                    reachable_runs=("reachable", "sum"), reachable_ok=("reach_ok", "sum"),
                    median_bumps=("bumps", "median")).reset_index()
        loc = g["bumps_to_localize"].agg(
            lambda s: float(np.median(s[s >= 0])) if (s >= 0).any() else np.nan)
        out["median_bumps_to_localize"] = loc.to_numpy()
        out["never_localized"] = g["bumps_to_localize"].agg(
            lambda s: float((s < 0).mean())).to_numpy()
        for q, col in ((50, "cpu_p50_ms"), (95, "cpu_p95_ms"), (100, "cpu_max_ms")):
            out[col] = g["decision_cpu_ms"].agg(lambda s, q=q: _p(s, q)).to_numpy()
        if pooled is not None:
            out.insert(3, "env", pooled)
        parts.append(out)
    out = pd.concat(parts, ignore_index=True)
    out["successes"] = out["successes"].astype(int)
    out["success_rate"] = out["successes"] / out["runs"]
    out["success_reachable"] = out.pop("reachable_ok") / out["reachable_runs"].replace(0, np.nan)
    out["ci_low"], out["ci_high"] = wilson(out["successes"].to_numpy(), out["runs"].to_numpy())
    return out


def value_bound(runs: pd.DataFrame) -> pd.DataFrame:
    """What a robot that knew its contact state after every bump would reach: per feedback
    run from a known start under turn noise σ (the sigma conditions), the closed-loop value
    (docs/model.md §15, "Deciding by value"; γ = 1, the bump budget's flights, stops from a
    known state: ``stop_extra`` 0) of the bump
    that ends the first flight from the pair's start, beside the run's success; pooled
    (env = 'all') and per map, per body and condition. A ceiling for the value decision
    under its own model of the robot (bins and 7 flights per state, not an exact bound).
    """
    from planners.navigation.feedback.observe import landings
    rows, seen = [], {}
    keep = runs[(runs.planner == "feedback") & runs.condition.isin(NOISE_ONLY)
                & (runs.condition != "sigma0")]
    for (env, seed, cond, body), grp in keep.groupby(["env", "map_seed", "condition", "body"]):
        cs = _cells(env, int(seed))
        sigma = float(cond.removeprefix("sigma"))
        rule = PYBULLET_CONTACT if body in ("twin-rule", "pybullet") else None
        budget = int(grp["max_bumps"].iloc[0]) if "max_bumps" in grp else DEFAULT_MAX_BUMPS
        for (s, g), pair in grp.groupby(["start", "goal"]):
            key = (env, seed, cond, rule is None, s, g)     # bodies with one rule share it
            if key not in seen:
                cfg = FeedbackConfig(turn_sigma_deg=sigma, gamma=1.0, contact=rule,
                                     value_horizon=budget, stop_extra=0.0)
                fnav = FeedbackNavigator(cs, ANGLES, int(g), cfg)
                x, y, th = cs.pose(int(s))
                _, end, _, _, _, th_end = landings(fnav.nav.caster, np.array([[x, y]]),
                                                   np.array([th]), rule, bearings=False)
                seen[key] = float(fnav.value.values(end, th_end, budget - 1)[0])
            v = seen[key]
            rows.extend((env, body, cond, v, bool(ok)) for ok in pair.success)
    t = pd.DataFrame(rows, columns=["env", "body", "condition", "bound", "success"])
    parts = [t.groupby(["body", "condition"]).agg(runs=("success", "size"),
             bound=("bound", "mean"), success=("success", "mean")).reset_index()
             .assign(env="all"),
             t.groupby(["body", "condition", "env"]).agg(runs=("success", "size"),
             bound=("bound", "mean"), success=("success", "mean")).reset_index()]
    return pd.concat(parts, ignore_index=True)[["body", "condition", "env", "runs", "bound",
                                                "success"]]


def draw(summary: pd.DataFrame, path: Path) -> Path:
    """Success against σ (pooled over the maps, the twin body): open-loop exact and reliable
    plans and feedback, with 95 % Wilson intervals.
    """
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from bouncesim.plots import save_figure
    s = summary[(summary.env == "all") & summary.condition.isin(NOISE_ONLY)].copy()
    s["sigma"] = s.condition.str.removeprefix("sigma").astype(float)
    fig, ax = plt.subplots(figsize=(6.8, 4.4), layout="constrained")
    colours = {"exact": "C0", "reliable": "C1", "feedback": "C2"}
    styles = {"twin": "-", "nearest": "--", "twin-rule": ":", "pybullet": "-.",
              "mujoco": (0, (5, 1)), "create3": (0, (1, 1))}
    bodies = sorted(s.body.unique(), key=lambda b: list(styles).index(b) if b in styles else 9)
    for (planner, body), d in s.groupby(["planner", "body"], sort=True):
        d = d.sort_values("sigma")
        dx = 0.06 * (bodies.index(body) - (len(bodies) - 1) / 2)    # error bars side by side
        ax.errorbar(d.sigma + dx, d.success_rate, yerr=[d.success_rate - d.ci_low,
                                                         d.ci_high - d.success_rate],
                    marker="o", ms=4, capsize=2, color=colours.get(planner),
                    ls=styles.get(body, "-"), label=f"{planner}, {body}")
    ax.set_xlabel("Gaussian turn noise σ [deg]")
    ax.set_ylabel("success rate (95 % Wilson interval)")
    ax.set_ylim(0, 1.02)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="lower left", ncol=len(colours))
    ax.set_title("reaching the goal cell and heading, pooled over the maps")
    return save_figure(fig, path, dpi=130)


def draw_maps(summary: pd.DataFrame, names, seed: int, path: Path,
              condition: str = "sigma2") -> Path:
    """Every map of the run with its free cells, titled with feedback's success there under
    ``condition`` per body (the held-out maps are the ones nobody tuned on).
    """
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from bouncesim.plots import draw_env, save_figure
    names = list(names)
    cols = min(4, len(names))
    rows = -(-len(names) // cols)
    fig, axes = plt.subplots(rows, cols, figsize=(3.2 * cols, 2.7 * rows), layout="constrained",
                             squeeze=False)
    s = summary[(summary.planner == "feedback") & (summary.condition == condition)]
    for ax, name in zip(axes.flat, names):
        draw_env(ax, maps_of(name, seed), _cells(name, seed), lw=1.2)
        rates = s[s.env == name]
        text = ", ".join(f"{b} {r:.2f}" for b, r in zip(rates.body, rates.success_rate))
        tag = "" if name in TUNED else " (held out)"
        ax.set_title(f"{name}{tag}" + (f"\n{condition}: {text}" if text else ""), fontsize=8)
        ax.set_xticks([])
        ax.set_yticks([])
        ax.set_xlabel("")
        ax.set_ylabel("")
    for ax in list(axes.flat)[len(names):]:
        ax.set_visible(False)
    return save_figure(fig, path, dpi=110)


# ============================================================================ the sweep
@dataclass(frozen=True)
class Config:
    """One run of the experiment (see the module; ``main`` builds it from the command line).

    Attributes
    ----------
    maps, bodies, conditions, planners : tuple of str
    pairs : int          pairs per map
    reps : int           noisy repetitions per pair (σ = 0 runs once)
    feedback : str       the feedback navigator's settings, "key=value,..." of
                         :class:`FeedbackConfig` ("" for the defaults)
    max_bumps : int      a feedback run's bump budget
    seed : int           root seed (random maps, pairs and the sweep)
    out : Path           output folder
    restart, plot_only, quick : bool
    bound : bool         only write bound.csv from runs.csv (:func:`value_bound`)
    workers, dask_local, dask : the executor (``add_executor_args``)
    progress : bool
    """

    maps: tuple = MAPS
    bodies: tuple = ("twin", "nearest", "twin-rule")
    conditions: tuple = tuple(CONDITIONS)
    planners: tuple = ("feedback", "exact", "reliable")
    pairs: int = 30
    reps: int = 1
    feedback: str = ""
    max_bumps: int = DEFAULT_MAX_BUMPS
    seed: int = 0
    out: Path = Path("results") / "nav_robustness"
    restart: bool = False
    plot_only: bool = False
    quick: bool = False
    bound: bool = False
    workers: int | None = None
    dask_local: int | None = None
    dask: str | None = None
    progress: bool = True


def run(config: Config) -> Path:
    """Sample the pairs, run (or resume) the sweep, write the summary and the figure."""
    out = output_dir(config.out)
    if config.plot_only or config.bound:
        runs = pd.read_csv(out / "runs.csv")
        if config.bound:
            table = value_bound(runs)
            table.to_csv(out / "bound.csv", index=False)
            print(table[table.env == "all"].drop(columns="env").to_string(
                index=False, float_format=lambda v: f"{v:.3f}"))
            print(f"wrote {out}/bound.csv")
        else:
            _report(out, runs)
        return out
    for what, names, known in (("body", config.bodies, BODIES),
                               ("condition", config.conditions, tuple(CONDITIONS))):
        bad = [n for n in names if n not in known]
        if bad or not names:
            raise envs.UserError(f"unknown {what} {', '.join(bad) or '(none)'}; choose from "
                                 f"{', '.join(known)}.")
    for name in config.planners:
        planner_class(name)
    feedback_config(config.feedback)
    if config.max_bumps < 1:
        raise envs.UserError(f"--max-bumps must be at least 1, got {config.max_bumps}.")
    pair_rng = np.random.default_rng(np.random.SeedSequence([config.seed, 27]))
    pairs = pd.concat([sample_pairs(m, config.seed, config.pairs, pair_rng)
                       for m in config.maps], ignore_index=True)
    trials = build_trials(pairs, config.planners, config.bodies, config.conditions,
                          config.seed, config.reps, config.feedback, config.max_bumps)
    if config.restart:
        for f in ("runs.jsonl", "runs.csv", "config.json"):
            (out / f).unlink(missing_ok=True)
    record = {"experiment": "nav_robustness", "seed": config.seed, "quick": config.quick,
              "maps": list(config.maps), "bodies": list(config.bodies),
              "conditions": {c: list(CONDITIONS[c]) for c in config.conditions},
              "planners": list(config.planners), "angles": list(ANGLES),
              "pairs_per_map": config.pairs, "reps": config.reps,
              "feedback": config.feedback, "max_bumps": config.max_bumps,
              "discretisation": "0.34 m cells, K = 8 on every map"}
    sweep = Sweep(trial, trials, config.seed, out, record, provenance=invocation(config.seed))
    runs = sweep.run(make_executor(config), progress=config.progress).table
    _report(out, runs)
    return out


def _report(out: Path, runs: pd.DataFrame) -> None:
    summary = summarise(runs)
    summary.to_csv(out / "summary.csv", index=False)
    draw(summary, out / "success_vs_sigma.png")
    draw_maps(summary, list(dict.fromkeys(runs.env)), int(runs.map_seed.iloc[0]),
              out / "maps.png")
    pooled = summary[summary.env == "all"]
    cols = ["planner", "body", "condition", "runs", "success_rate", "ci_low", "ci_high",
            "success_reachable",
            "median_bumps", "median_bumps_to_localize", "cpu_p95_ms"]
    print(pooled[cols].to_string(index=False, float_format=lambda v: f"{v:.3g}"))
    ends = outcomes(runs)
    ends.to_csv(out / "outcomes.csv", index=False)
    print("how the runs ended (all maps):")
    print(ends[ends.env == "all"].drop(columns="env").to_string(index=False))
    print(f"wrote {out}/summary.csv, {out}/outcomes.csv, {out}/success_vs_sigma.png, "
          f"{out}/maps.png")


def main(argv: list[str] | None = None) -> int:
    """Command line: ``python -m experiments.nav_robustness --help``."""
    p = experiment_parser("nav_robustness", __doc__.split("\n\n")[0])
    p.add_argument("--maps", type=name_list, default=None, metavar="M1,M2,...")
    p.add_argument("--bodies", type=name_list, default=None, metavar="B1,B2,...",
                   help=f"bodies ({', '.join(BODIES)})")
    p.add_argument("--conditions", type=name_list, default=None, metavar="C1,C2,...",
                   help=f"conditions ({', '.join(CONDITIONS)})")
    p.add_argument("--planners", type=name_list, default=None, metavar="P1,P2,...")
    p.add_argument("--pairs", type=int, default=None, help="pairs per map (default 30)")
    p.add_argument("--reps", type=int, default=None, help="noisy repetitions (default 1)")
    p.add_argument("--feedback", default=None, metavar="KEY=VAL,...",
                   help="the feedback navigator's FeedbackConfig settings (default: its own)")
    p.add_argument("--max-bumps", type=int, default=None, metavar="N",
                   help=f"a feedback run gives up after N bumps (default {DEFAULT_MAX_BUMPS})")
    p.add_argument("--restart", action="store_true", help="start the sweep again")
    p.add_argument("--plot-only", action="store_true", help="redraw from runs.csv")
    p.add_argument("--bound", action="store_true",
                   help="only write bound.csv from runs.csv: the success a robot that knew its "
                   "contact state after every bump would reach, per body, condition and map, "
                   "beside feedback's")
    add_executor_args(p)
    args = p.parse_args(argv)
    base = Config(maps=QUICK_MAPS, pairs=3, bodies=("twin", "nearest"),
                  conditions=("sigma0", "sigma2", "side5", "unknown")) if args.quick \
        else Config()
    config = replace(base, **{k: v for k, v in {
        "maps": args.maps, "bodies": args.bodies, "conditions": args.conditions,
        "planners": args.planners, "pairs": args.pairs, "reps": args.reps,
        "feedback": args.feedback, "max_bumps": args.max_bumps}.items()
        if v is not None}, seed=args.seed, out=args.out, restart=args.restart,
        plot_only=args.plot_only, bound=args.bound, quick=args.quick, workers=args.workers,
        dask_local=args.dask_local, dask=args.dask, progress=not args.no_progress)
    return run_main("nav_robustness", lambda: config, run)


if __name__ == "__main__":
    sys.exit(main())
