"""Feedback navigation against open-loop exact plans under Gaussian turn noise (§15).

For each map, (start, goal) pairs are drawn uniformly from the ordered pairs (start ≠ goal)
the exact planner reaches (Φ = {45°, 90°, 135°}, K = 8, w1 = 1, w2 = 100). Every pair is run
once per σ in the kinematic twin (front-half bumper, 0.2 m/s) with Gaussian turn noise σ:
by feedback (:func:`bouncesim.runs.execute.navigate_feedback`, the filter told σ), by feedback
with heading correction (§15's extension, off by default elsewhere) and, with the same robot
noise seed, by the open-loop exact plan (:func:`bouncesim.runs.execute.execute`).
Maps: ``lab`` and one random polygon room with a hole (``experiments.nav_exact``).
With ``--contact pybullet`` the twin has PyBullet's contact rule (§9: glancing contacts
slide), the exact plans are planned for it and the feedback navigator learns it from the
body (§15); ``--filter-contact off`` keeps the navigator's front-half bumper model on that
body (the rule before).

    python -m experiments.nav_feedback [--quick] [--seed S] [--pairs N] [--sigmas 0,2,5]
                                       [--contact off|pybullet] [--filter-contact auto|off]
                                       [--out DIR]

Writes ``runs.csv`` (one row per run), ``decisions.csv`` (one row per feedback decision, its
wall time [ms]), ``summary.csv`` (success with 95 % Wilson intervals, decision times),
``config.json`` and ``success.png`` (drawn from summary.csv).
"""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import pandas as pd

import envs
from bouncesim.plots import save_figure
from bouncesim.robots import make_robot
from bouncesim.robots.noise import GaussianNoise
from bouncesim.runs.execute import execute, navigate_feedback
from envs.motion import PYBULLET_CONTACT
from planners.cells import CellSpace
from planners.navigation.exact import ExactNavigator
from planners.navigation.feedback import FeedbackConfig

from .common import experiment_parser, name_list, output_dir, run_main, write_config
from .nav_exact import map_named
from .nav_montecarlo import wilson

__all__ = ["Config", "run", "run_map", "summarise", "draw", "main"]

ANGLES = (45.0, 90.0, 135.0)
W1, W2 = 1.0, 100.0


@dataclass(frozen=True)
class Config:
    """Parameters of one nav_feedback run.

    Attributes
    ----------
    pairs : int            pairs per map
    sigmas : tuple         Gaussian turn noise σ [deg]
    maps : tuple of str    catalogue names or 'randomN' (random polygon room N)
    particles : int        particles of the filter
    corrected : bool       also run feedback with heading correction (§15's extension)
    guided : bool          the guided plan search of §15 (off by default, as in
                           :class:`planners.navigation.feedback.FeedbackConfig`)
    contact : str          the twin's contact rule: 'off' (front-half bumper) or 'pybullet'
                           (§9's PYBULLET_CONTACT; exact plans are planned for it)
    filter_contact : str   'auto': the feedback navigator takes the body's rule (§15);
                           'off': it keeps the front-half bumper model
    quick : bool           recorded; ``main`` turns it into a small budget
    seed : int             root seed (rooms, pairs, noise, filter)
    out : Path             output folder
    """

    pairs: int = 60
    sigmas: tuple = (0.0, 2.0, 5.0)
    maps: tuple = ("lab", "random1")
    particles: int = FeedbackConfig.particles
    corrected: bool = True
    guided: bool = False
    contact: str = "off"
    filter_contact: str = "auto"
    quick: bool = False
    seed: int = 0
    out: Path = Path("results") / "nav_feedback"


def _pairs(exact: ExactNavigator, n: int, rng: np.random.Generator) -> list[tuple]:
    """``n`` ordered pairs (start ≠ goal) with an exact plan, uniform by rejection."""
    N, out, tries = exact.cells.N, [], 0
    while len(out) < n and tries < 200 * n:
        tries += 1
        s, g = (int(v) for v in rng.integers(0, N, 2))
        if s != g and (route := exact.plan(s, g)) is not None:
            out.append((s, g, route))
    return out


def feedback_config(config: Config) -> FeedbackConfig:
    """The feedback navigator's settings of a run."""
    return FeedbackConfig(particles=config.particles, guided=config.guided)


def run_map(name: str, config: Config) -> tuple[pd.DataFrame, pd.DataFrame]:
    """(runs, decisions) of one map: every pair × σ × {feedback, exact}."""
    env = map_named(name, config.seed)
    cells = CellSpace(env)
    contact = PYBULLET_CONTACT if config.contact == "pybullet" else None
    body = {} if contact is None else {"contact": contact}
    exact = ExactNavigator(cells, ANGLES, W1, W2, contact=contact)
    rng = np.random.default_rng(np.random.SeedSequence([config.seed, 3, len(name)]))
    pairs = _pairs(exact, config.pairs, rng)
    fcfg = feedback_config(config)
    planners = ("feedback", "feedback_corrected", "exact") if config.corrected else \
        ("feedback", "exact")
    rows, decisions = [], []
    for i, (s, g, route) in enumerate(pairs):
        for sigma in config.sigmas:
            noise = GaussianNoise(sigma)
            key = [config.seed, 4, len(name), i, int(round(sigma * 1000))]
            for planner in planners:
                bot_rng = np.random.default_rng(np.random.SeedSequence(key + [0]))
                bot = make_robot("kinematic", env, noise=noise, rng=bot_rng, **body)
                t0 = time.perf_counter()
                if planner.startswith("feedback"):
                    frng = np.random.default_rng(np.random.SeedSequence(key + [1]))
                    cfg = replace(fcfg, correct_heading=planner == "feedback_corrected")
                    run = navigate_feedback(bot, env, s, g, noise, frng, angles=ANGLES,
                                            cells=cells, config=cfg, w1=W1, w2=W2,
                                            contact="auto" if config.filter_contact == "auto"
                                            else None)
                    ms = np.asarray(run.decision_ms)
                    decisions += [{"map": name, "sigma": sigma, "pair": i,
                                   "planner": planner, "ms": v,
                                   "cpu_ms": c} for v, c in zip(ms, run.decision_cpu_ms)]
                    extra = {"reinits": run.reinits, "no_plan": run.no_plan,
                             "decisions": len(ms),
                             "decision_ms_max": float(ms.max()) if len(ms) else np.nan}
                else:
                    run = execute(route.plan, bot, start=s, goal=g, cells=cells)
                    extra = {}
                rows.append({"map": name, "sigma": sigma, "pair": i, "start": s, "goal": g,
                             "planner": planner, "success": bool(run.success),
                             "reason": run.reason, "bumps": run.bumps,
                             "plan_bumps": route.plan.bumps,
                             "position_error": run.position_error,
                             "wall_s": time.perf_counter() - t0, **extra})
    return pd.DataFrame(rows), pd.DataFrame(decisions)


def summarise(runs: pd.DataFrame, decisions: pd.DataFrame) -> pd.DataFrame:
    """Per map × σ × planner: runs, successes, rate with its 95 % Wilson interval; for
    feedback the median, 95th percentile and maximum decision time [ms] (wall), and the
    median and 95th percentile in CPU time.
    """
    g = runs.groupby(["map", "sigma", "planner"], sort=False)
    s = g.success.agg(["size", "sum"]).reset_index().rename(
        columns={"size": "runs", "sum": "successes"})
    s["success"] = s.successes / s.runs
    s["wilson_low"], s["wilson_high"] = wilson(s.successes.to_numpy(), s.runs.to_numpy())
    g = decisions.groupby(["map", "sigma", "planner"])
    d = g.ms.agg(decision_ms_median="median", decision_ms_p95=lambda v: np.percentile(v, 95),
                 decision_ms_max="max").join(
        g.cpu_ms.agg(decision_cpu_ms_median="median",
                     decision_cpu_ms_p95=lambda v: np.percentile(v, 95))).reset_index()
    return s.merge(d, on=["map", "sigma", "planner"], how="left")


def draw(summary_csv: Path, path: Path) -> None:
    """Success against σ, one panel per map, feedback and open-loop exact with Wilson bars."""
    import matplotlib.pyplot as plt
    d = pd.read_csv(summary_csv)
    maps = list(dict.fromkeys(d["map"]))
    fig, axes = plt.subplots(1, len(maps), figsize=(3.6 * len(maps), 3.7), squeeze=False)
    style = {"feedback": ("#3b75af", "o", "feedback (particle filter)"),
             "feedback_corrected": ("#e07b39", "^", "feedback + heading correction"),
             "exact": ("#999999", "s", "open-loop exact plan")}
    for ax, m in zip(axes[0], maps):
        for planner, (color, marker, label) in style.items():
            e = d[(d["map"] == m) & (d.planner == planner)].sort_values("sigma")
            if e.empty:
                continue
            ax.errorbar(e.sigma, e.success, yerr=[e.success - e.wilson_low,
                                                   e.wilson_high - e.success],
                        color=color, marker=marker, capsize=3, label=label)
        n = int(d[d["map"] == m].runs.max())
        ax.set_title(f"{m} ({n} pairs)", fontsize=9)
        ax.set_xlabel("Gaussian turn noise σ [deg]")
        ax.set_ylim(0, 1.05)
        ax.grid(alpha=0.3)
    axes[0][0].set_ylabel("success in the twin (95 % Wilson)")
    handles, labels = axes[0][0].get_legend_handles_labels()
    fig.legend(handles, labels, fontsize=7, loc="lower center", ncol=3)
    fig.tight_layout(rect=(0, 0.08, 1, 1))
    save_figure(fig, path, dpi=130)


def run(config: Config) -> Path:
    """Run every map; write runs.csv, decisions.csv, summary.csv, config.json, success.png."""
    if config.pairs < 1:
        raise envs.UserError(f"--pairs must be at least 1, got {config.pairs}.")
    if config.contact not in ("off", "pybullet") or config.filter_contact not in ("auto", "off"):
        raise envs.UserError("--contact must be off or pybullet and --filter-contact auto or "
                             "off.")
    out = output_dir(config.out)
    write_config(out, {"experiment": "nav_feedback", "seed": config.seed,
                       "quick": config.quick, "pairs_per_map": config.pairs,
                       "sigmas": list(config.sigmas), "maps": list(config.maps),
                       "angles": list(ANGLES), "w1": W1, "w2": W2,
                       "feedback": feedback_config(config).__dict__,
                       "robot": "kinematic twin, " + ("front-half bumper" if config.contact
                                                      == "off" else "PyBullet's contact rule "
                                                      "(docs/model.md section 9)") +
                       ", Gaussian turn noise, 0.2 m/s",
                       "contact": config.contact, "filter_contact": config.filter_contact,
                       "pair_sampling": "uniform over ordered pairs (start != goal) with an "
                       "exact plan, by rejection"})
    parts = [run_map(m, config) for m in config.maps]
    runs = pd.concat([p[0] for p in parts], ignore_index=True)
    decisions = pd.concat([p[1] for p in parts], ignore_index=True)
    runs.to_csv(out / "runs.csv", index=False)
    decisions.to_csv(out / "decisions.csv", index=False)
    summary = summarise(runs, decisions)
    summary.to_csv(out / "summary.csv", index=False)
    draw(out / "summary.csv", out / "success.png")
    print(summary.to_string(index=False, float_format=lambda v: f"{v:.3f}"))
    return out


def _sigmas(text: str | None) -> tuple:
    """--sigmas as a tuple of non-negative floats [deg] (None: the default)."""
    if text is None:
        return Config.sigmas
    try:
        out = tuple(float(v) for v in name_list(text))
    except ValueError:
        out = ()
    if not out or not all(np.isfinite(v) and v >= 0 for v in out):
        raise envs.UserError(f"--sigmas must be non-negative numbers [deg], got {text!r}.")
    return out


def main(argv=None) -> int:
    """Parse the command line into a :class:`Config` and :func:`run` it (exit status)."""
    p = experiment_parser("nav_feedback", __doc__.splitlines()[0])
    p.add_argument("--pairs", type=int, default=None,
                   help="pairs per map (default 60; 4 with --quick)")
    p.add_argument("--maps", default=",".join(Config.maps), help="maps: names or randomN")
    p.add_argument("--guided", action="store_true",
                   help="the guided plan search (docs/model.md section 15; off by default)")
    p.add_argument("--sigmas", default=None,
                   help="Gaussian turn noise levels [deg], comma-separated (default 0,2,5)")
    p.add_argument("--contact", choices=("off", "pybullet"), default="off",
                   help="the twin's contact rule (docs/model.md section 9; default off)")
    p.add_argument("--filter-contact", choices=("auto", "off"), default="auto",
                   help="auto (default): the feedback navigator takes the body's contact "
                   "rule; off: it keeps the front-half bumper model")
    args = p.parse_args(argv)
    pairs = args.pairs if args.pairs is not None else (4 if args.quick else Config.pairs)
    return run_main("nav_feedback", lambda: Config(
        pairs=pairs, sigmas=_sigmas(args.sigmas), maps=name_list(args.maps), guided=args.guided,
        contact=args.contact, filter_contact=args.filter_contact, quick=args.quick,
        seed=args.seed, out=args.out), run)


if __name__ == "__main__":
    sys.exit(main())
