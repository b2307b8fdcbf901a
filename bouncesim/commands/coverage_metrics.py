"""``bouncesim coverage --metrics``: coverage-time metrics of the angles and the mix
(docs/model.md §20a), written to metrics.json with a figure of the covered fraction.

Kept beside :mod:`bouncesim.commands.coverage`, which calls :func:`add_args`,
:func:`check_args` and :func:`run_metrics`.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from envs import UserError
from planners.coverage import MixDesign
from planners.coverage.cover_time import LEVELS, RUNS, coverage_metrics, return_times

__all__ = ["add_args", "check_args", "run_metrics", "write_metrics", "format_metrics",
           "DEFAULT_HORIZON"]

DEFAULT_HORIZON = 20_000
"""Steps per robot of the metrics without --horizon."""


def add_args(p) -> None:
    """Add --metrics, --robots, --metrics-runs, --simulate and --seed."""
    p.add_argument("--metrics", action="store_true",
                   help="coverage-time metrics per angle and for the mix executed in epochs "
                   "(--epoch, default 1000) over --horizon steps (default "
                   f"{DEFAULT_HORIZON}): the covered fraction C(t) (share of the cells visited "
                   "in the first t steps: mean, 10th and 90th percentiles), T_X for X in "
                   "0.5, 0.8, 0.9, 1.0 (mean over the runs that reach X, median, share not "
                   "reached), each cell's mean return time and the worst idleness "
                   "(docs/model.md section 20a); computed exactly on tiny maps, otherwise by "
                   "sampling the model's chain (with standard errors); writes metrics.json "
                   "and cover_time.png to --out")
    p.add_argument("--objective", choices=("tv", "cover90", "idleness"), default="tv",
                   help="what the mix alpha minimises: tv (default), the TV to the target; "
                   "cover90, the mean time for --robots robots to cover 90 %% of the cells; "
                   "idleness, the mean worst idleness; both over --horizon steps (default "
                   f"{DEFAULT_HORIZON}) with the mix in epochs of --epoch steps (default "
                   "1000), sampled from the model's chain over a simplex grid of alpha "
                   "(docs/model.md section 20b); alpha.json then reports the objective's "
                   "value and the TV design's alpha")
    p.add_argument("--robots", type=int, default=1, metavar="K",
                   help="with --metrics: also a team of K robots that ignore each other and "
                   "start independently (t counts each robot's own steps); with a time "
                   "--objective: the team size it is for")
    p.add_argument("--metrics-runs", type=int, default=RUNS, metavar="N",
                   help=f"with --metrics: sampled runs (teams) per record (default {RUNS})")
    p.add_argument("--simulate", type=int, default=0, metavar="N",
                   help="with --metrics: also simulate N runs (teams) on the kinematic twin "
                   "and draw them against the model (default 0: none)")
    p.add_argument("--seed", type=int, default=None,
                   help="with --metrics: seed of the sampled runs and the simulation "
                   "(default 0)")


def check_args(args) -> None:
    """One-sentence errors for the metrics and time-objective flags, before any heavy work."""
    timed = args.objective != "tv"
    if timed:
        if args.target is not None:
            raise UserError(f"--objective {args.objective} covers the whole room: drop "
                            "--target.")
        if args.start is not None:
            raise UserError(f"--objective {args.objective} starts from the uniform start: "
                            "drop --start.")
        if args.target_space != "positions":
            raise UserError("a time objective counts position cells only; use "
                            "--target-space positions.")
    if not args.metrics:
        for flag, value, default in (("--robots", args.robots, 1),
                                     ("--metrics-runs", args.metrics_runs, RUNS),
                                     ("--simulate", args.simulate, 0),
                                     ("--seed", args.seed, None)):
            if value != default and not (timed and flag in ("--robots", "--seed")):
                raise UserError(f"{flag} needs --metrics.")
        if not timed:
            return
    if args.seed is None:      # the metrics are random: config.json records the seed
        args.seed = 0
    if args.robots < 1:
        raise UserError(f"--robots must be at least 1, got {args.robots}.")
    if args.metrics_runs < 2:
        raise UserError(f"--metrics-runs must be at least 2, got {args.metrics_runs}.")
    if args.simulate < 0:
        raise UserError(f"--simulate must be 0 or more, got {args.simulate}.")
    if args.target_space != "positions":
        raise UserError("--metrics counts position cells only; use --target-space positions.")


def run_metrics(model, result: MixDesign, args, start, timeshared=None,
                progress=None) -> dict:
    """Metrics of every angle and of the mix (when there are two angles or more), for one
    robot and for --robots; returns the content of metrics.json. ``timeshared``: the mix's
    limit in epochs of --epoch steps when already computed, (q, counted fraction).
    """
    T = int(args.horizon or DEFAULT_HORIZON)
    epoch = int(args.epoch or 1000)
    rng = np.random.default_rng(args.seed)
    teams = sorted({1, int(args.robots)})
    kw = {"robots": teams, "horizon": T, "start": start, "runs": args.metrics_runs,
          "rng": rng}
    records = coverage_metrics(model, list(result.angles), result.noise,
                               limits=list(result.per_angle), progress=progress, **kw)
    if len(result.angles) > 1:
        if timeshared is not None and args.epoch is not None:
            lim = [timeshared]
        else:                                  # long epochs: Σ α_a s_a of the angles' limits
            s = sum(a / return_times(model, result.noise, ang, limit=cov)
                    for a, ang, cov in zip(result.alpha, result.angles, result.per_angle)
                    if a > 0)
            lim = [(s, 1.0)]
        records += coverage_metrics(model, result.mix, result.noise, epoch=epoch, limits=lim,
                                    **kw)
    out = [r.to_json() for r in records]
    if args.simulate:
        from ..runs.cover import twin_cover
        for r, rec in zip(records, out):
            policy = result.mix if r.angle is None else r.angle
            sim = twin_cover(model.cs.env, policy, result.noise, robots=r.robots,
                             runs=args.simulate, horizon=T, epoch=epoch, times=r.t, rng=rng,
                             start=start, cells=model.cs)
            rec["twin_covered_mean"] = [float(x) for x in sim.covered_mean]
            rec["twin_covered_se"] = [float(x) for x in sim.covered_se]
            rec["twin_T"] = {f"{x:.1f}": {**dict(zip(("mean", "not_reached"), sim.T_mean(x))),
                                          "mean_se": sim.T_mean_se(x)} for x in LEVELS}
            rec["twin_runs"] = int(args.simulate)
            rec["twin_seconds"] = round(sim.seconds, 3)
    cs = model.cs
    return {"env": cs.env.name, "model": model.name, "K": cs.K, "P": cs.P,
            "noise": str(result.noise), "horizon": T, "epoch": epoch,
            "start": "uniform" if start is None else int(start), "seed": int(args.seed),
            "levels": [f"{x:.1f}" for x in LEVELS], "records": out}


def write_metrics(out_dir, metrics: dict, plots: bool, figures: str) -> list[Path]:
    """metrics.json and cover_time.<figures> in ``out_dir``; returns the files written."""
    out = Path(out_dir)
    (out / "metrics.json").write_text(json.dumps(metrics, indent=1) + "\n")
    written = [out / "metrics.json"]
    if plots:
        from ..coverage_plots import save_cover_curves
        written.append(save_cover_curves(
            out / f"cover_time.{figures}", metrics["records"],
            title=f"{metrics['env']}: covered fraction, {metrics['model']} model, "
            f"{metrics['noise']}, K={metrics['K']}"))
    return written


def format_metrics(metrics: dict) -> str:
    """A short table: per record C(T), T_0.9 and T_1.0, the worst idleness, a team's first
    meeting and its meetings per 1000 steps, and the method.
    """
    T = metrics["horizon"]
    lines = [f"coverage-time metrics over {T} steps per robot (docs/model.md section 20a):",
             f"{'policy':>7} {'robots':>6} {'C(T)':>7} {'T_0.9 mean':>11} {'not':>5} "
             f"{'T_1.0 mean':>11} {'not':>5} {'idle':>7} {'meet':>6} {'/1000':>6}  method"]
    for r in metrics["records"]:
        t9, t10 = r["T"]["0.9"], r["T"]["1.0"]
        m = r.get("meeting")
        meet = (f"{_steps(m['first']['mean']):>6} {m['per_1000']:6.1f}" if m
                else f"{'':>6} {'':>6}")
        lines.append(
            f"{str(r['angle']):>7} {r['robots']:>6} {r['covered_mean'][-1]:7.3f} "
            f"{_steps(t9['mean']):>11} {t9['not_reached']:5.2f} {_steps(t10['mean']):>11} "
            f"{t10['not_reached']:5.2f} {r['idleness_worst']:7.0f} {meet}  {r['method']}")
    lines.append("not: share of runs that do not reach X within the horizon; idle: mean "
                 "worst idleness [steps]; meet: a team's mean first meeting (two robots "
                 "counted in one cell at one step) [steps], /1000: meetings per 1000 steps "
                 "of one robot")
    return "\n".join(lines)


def _steps(x) -> str:
    return "-" if x is None else f"{x:.0f}"
