"""``bouncesim coverage ENV``: persistent groups, limiting distributions and the best policy mix.

The paper's Algorithm 3 (docs/model.md §16): for every bouncing angle, the Markov chain of the
noisy bouncing robot, its persistent groups, its limiting distribution π and coverage q;
then the mix α over the angles whose mixed coverage best matches a target.
"""

from __future__ import annotations

import csv
import json
import sys
from dataclasses import asdict, fields, is_dataclass, replace
from pathlib import Path

import numpy as np

from envs import UserError
from planners.cells import CellSpace
from planners.coverage import (
    MODELS,
    SPACES,
    TARGET_FORMATS,
    MixDesign,
    TurnNoise,
    check_angles,
    default_settings,
    design_mix,
    group_cells,
    horizon_of,
    load_target,
    model_for,
    steps_to_limit,
    steps_to_limit_each,
    timeshared_coverage,
)
from planners.coverage.horizon import CAP, LIMIT_TV
from planners.metrics import tv_distance

from ..runs.options import with_options
from . import coverage_metrics as metrics_cli
from .common import (
    add_angle_noise_args,
    add_contact_arg,
    add_env_args,
    add_figures_arg,
    add_output,
    check_fits,
    contact_rule,
    flush_warnings,
    load_env,
    make_cells,
    parse_angles,
    report_written,
    writable_path,
    write_config,
)

__all__ = ["register", "run", "write_outputs", "format_table"]

DESCRIPTION = """\
For every bouncing angle: the Markov chain of the bouncing robot with rotation noise (turn by
exactly the angle with probability r, otherwise by the angle plus a uniform non-zero multiple
of 360/K up to +-eps), its persistent groups (closed classes), its limiting distribution from
a uniform start and the coverage q (probability of each position cell). Then the policy mix
alpha (alpha >= 0, sum 1) minimising the 2-norm ||A alpha - b|| between the mixed coverage and
the target b.

Writes to --out: coverage.csv (columns angle,p,i,j,x,y,q; angle = each bouncing angle, "mix"
for A alpha and "target" for b, over position cells), alpha.json (angles, alpha, residual =
||A alpha - b||_2 not squared, tv = 0.5 ||A alpha - b||_1, and per angle the persistent
groups, their sizes in the model's states (see "states") and in position cells
("group_cells", comparable across models) and the transient fraction of the states),
heatmap_angle_<A>.png per angle and heatmap_mix_vs_target.png (.svg or .pdf with
--figures). With --target-space
configurations also
coverage_configurations.csv (angle,z,p,k,pi).

A x alpha assumes every epoch of the executed mix reaches its angle's limiting distribution.
With --epoch STEPS the mix is also predicted as docs/model.md section 21 runs it (epochs of STEPS
steps, each with one angle drawn with probabilities alpha; the robot carries its state from
epoch to epoch): alpha.json gains "timeshared" (its TV to the target and to A alpha),
coverage.csv the series "mix_epochs" and the plots heatmap_mix_epochs_vs_target.png. Where
an angle mixes slowly (a pocket the robot leaks into rarely) the two differ a lot.

Every run reports per angle and for the mix "steps_to_limit" (alpha.json and the table): the
first T on a 2^(1/8) grid from 100 at which the coverage from the uniform start is within TV
0.05 of the limit (docs/model.md section 20). It is exact when the model's own run gets there;
otherwise "estimate" extrapolates the run's slowest mode, once two doublings of T agree on it
("method": "extrapolated", with "relaxation_steps"), or only "more than last" is known
("bound": not up to --limit-cap steps or within --limit-seconds per policy).

With --horizon T everything is for the first T steps of a run instead of the limit
(docs/model.md section 20): coverage.csv's q and the heatmaps are the expected share of the
first T steps in each cell (from the uniform start, or --start), alpha is fitted to that (with
--epoch: as executed in epochs, by SLSQP; alpha.json reports its convergence), and a warning
says when T is far below a policy's steps_to_limit. Once a run's per-step share is steady and
within TV 1e-4 of its limit, its remaining steps count at the limit, so T may be far beyond
what can be stepped; a T the run would not settle for within 10^6 steps is refused at once.

With --metrics: how fast each angle and the mix (executed in epochs of --epoch steps, default
1000) cover the map over --horizon steps per robot (default 20000), for one robot and for a
team of --robots K robots that ignore each other (docs/model.md section 20a): the covered
fraction C(t), T_X for X = 0.5, 0.8, 0.9, 1.0, each cell's mean return time and the worst
idleness, from the model's own chain (exactly on tiny maps, else from --metrics-runs sampled
runs, with standard errors). Writes metrics.json (one record per policy and team size) and
cover_time.png (with --simulate N, against N runs of the kinematic twin).

With --objective cover90 or idleness, alpha is the mix that covers 90 % of the room fastest
(for --robots robots) or keeps the worst idleness lowest (docs/model.md section 20b) instead
of the one nearest the target; alpha.json's "objective" gives its value in steps and the TV
design's alpha, and its tv and residual are this mix's against the target.
"""

EXAMPLES = """\
examples:
  bouncesim coverage complex --orientations 360 --angles 30,75,315 --eps 5 --r 0.8 --out out/
  bouncesim coverage lab --angles 90,135 --target my_target.csv --out out/
  bouncesim coverage complex --orientations 360 --angles 30,75,315 --eps 5 --r 0.8 --model event
  bouncesim coverage lab --orientations 72 --angles 30,75,315 --eps 5 --r 0.8 --model event \
      --model-option bin_length=0.01
  bouncesim coverage fig1 --orientations 72 --angles 30,75,315 --eps 5 --r 0.8 --model event \
      --epoch 1000
  bouncesim coverage two_room.json --orientations 72 --angles 30,75,315 --eps 5 --r 0.8 \
      --model event --horizon 2000 --start 0.51,1.19,0
  bouncesim coverage two_room.json --angles 30,75,315 --eps 5 --r 0.8 --model event \
      --metrics --robots 4 --horizon 20000 --out out/
  bouncesim coverage two_room.json --angles 30,75,315 --eps 5 --r 0.8 --model event \
      --objective cover90 --robots 2 --metrics --out out/

""" + TARGET_FORMATS


def register(sub) -> None:
    """Add the ``coverage`` sub-command to the CLI's sub-parsers."""
    import argparse
    p = sub.add_parser("coverage", help="coverage of bouncing policies and the best policy mix",
                       description=DESCRIPTION, epilog=EXAMPLES,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    add_env_args(p)
    add_angle_noise_args(p)
    p.add_argument("--noise", default=None, metavar="SPEC",
                   help="rotation noise instead of --eps/--r: gauss:SIGMA, a Gaussian turn "
                   "error of SIGMA deg (docs/model.md section 11a), or model:eps=E,r=R")
    p.add_argument("--target", type=Path, default=None, metavar="FILE",
                   help="target distribution file (formats below; default uniform)")
    p.add_argument("--target-space", choices=SPACES,
                   default="positions",
                   help="match the target over position cells (coverage q, default) or over "
                   "configuration cells (limiting distribution pi)")
    p.add_argument("--model", choices=list(MODELS), default="step",
                   help="coverage model (default step, the paper's, whose Table 1 this "
                   "reproduces; event is the one to use when you compare with physics, and "
                   "validate's default): "
                   + "; ".join(f"{name}: {cls.summary}" for name, cls in MODELS.items())
                   + " (see docs/model_continuous.md)")
    p.add_argument("--model-option", action="append", default=[], metavar="KEY=VALUE",
                   help="a setting of the chosen model, repeatable: event: bin_length [m] "
                   "(default 0.03), samples (flight starts per bin, default 2); sampled: grid "
                   "(m x m points per cell, default 3), theta_samples (default 2)")
    add_contact_arg(p, what=" of the event model")
    p.add_argument("--epoch", type=int, default=None, metavar="STEPS",
                   help="also predict the mix as it is executed: epochs of STEPS steps, each "
                   "with one angle drawn with probabilities alpha (docs/model.md section 21); "
                   "positions only")
    p.add_argument("--horizon", type=int, default=None, metavar="STEPS",
                   help="coverage of the first STEPS steps instead of the limit, and alpha "
                   "fitted to it (docs/model.md section 20)")
    p.add_argument("--start", default=None, metavar="S",
                   help="with --horizon or --metrics: start configuration z or pose X,Y,DEG "
                   "(default: uniform over the configurations)")
    metrics_cli.add_args(p)
    p.add_argument("--limit-cap", type=int, default=CAP, metavar="STEPS",
                   help=f"largest T steps_to_limit tries (default {CAP:.0e})")
    p.add_argument("--limit-seconds", type=float, default=5.0, metavar="S",
                   help="time budget of the exact steps_to_limit pass per policy [s] "
                   "(default 5); beyond it the answer is extrapolated from the run's slow "
                   "mode, or only bounded")
    add_output(p, "--out", folder=True, default=None, metavar="DIR",
               help="output folder (CSV, JSON, config.json and heatmaps in the --figures "
               "format); without it only the table is printed")
    p.add_argument("--no-plots", action="store_true", help="skip the heatmaps")
    add_figures_arg(p)
    p.add_argument("--json", action="store_true",
                   help="print alpha.json's content instead of the table")
    p.set_defaults(func=run)


def _progress(total: int | None, desc: str = "chains", unit: str = "angle"):
    try:
        from tqdm import tqdm
    except ImportError:                          # pragma: no cover - tqdm is a dependency
        return None

    def wrap(it):
        # delay: nothing is shown for short runs; disable=None: only on a terminal.
        return tqdm(it, total=total, desc=desc, unit=unit, file=sys.stderr,
                    delay=1.0, disable=None, leave=False)
    return wrap


def run(args) -> int:
    """Run ``bouncesim coverage``: per-angle coverage, the mix α and output files; exit status."""
    env = load_env(args)
    cs = make_cells(args, env)
    noise = TurnNoise(args.eps, args.r)
    if getattr(args, "noise", None) is not None:
        if not noise.exact:
            raise UserError("give the rotation noise either as --noise or as --eps/--r.")
        noise = TurnNoise.from_spec(args.noise)
    angles = check_angles(cs.K, parse_angles(args.angles), noise)   # before any heavy work
    target, target_desc = None, f"uniform over {args.target_space}"
    if args.target is not None:
        target = load_target(args.target, cs, args.target_space)
        target_desc = str(args.target)
    settings = parse_model_options(args.model, args.model_option)
    contact = contact_rule(args)
    if contact is not None:
        settings = replace(settings or default_settings(args.model), contact=contact)
    if args.target_space not in MODELS[args.model].spaces:
        raise UserError(f"the {args.model} model predicts coverage over position cells only; "
                        "use --target-space positions.")
    if args.epoch is not None:
        if args.epoch < 1:
            raise UserError(f"--epoch must be at least one step, got {args.epoch}.")
        if args.target_space != "positions":
            raise UserError("--epoch predicts coverage over position cells only; use "
                            "--target-space positions.")
    metrics_cli.check_args(args)
    start = None
    if args.horizon is not None or args.metrics:
        if args.horizon is not None and args.horizon < 1:
            raise UserError(f"--horizon must be at least one step, got {args.horizon}.")
        if args.horizon is not None and args.target_space != "positions":
            raise UserError("--horizon predicts coverage over position cells only; use "
                            "--target-space positions.")
        if args.start is not None:
            from .plan import parse_config
            start = parse_config(args.start, cs, "start")
    elif args.start is not None:
        raise UserError("--start needs --horizon or --metrics (the limit does not depend on "
                        "the start).")
    spread = float(noise.support(cs.K)[0].max()) * cs.delta_deg    # ε, or the Gaussian's ±M·Δ
    check_fits(args, cs, MODELS[args.model].memory_estimate(cs, angles, spread, settings),
               what="coverage")
    if args.out is not None:
        writable_path(args.out, "--out", folder=True)
    flush_warnings()
    model = model_for(cs, args.model, settings)
    result = design_mix(model, angles, noise, target=target, space=args.target_space,
                        progress=_progress(len(angles)), horizon=args.horizon,
                        epoch=args.epoch, start=None if args.horizon is None else start)
    summary = summarise(result, cs, env.name, target_desc)
    summary["model"] = args.model
    summary["states"] = {"kind": MODELS[args.model].state_kind,
                         "count": int(result.per_angle[0].pi.size) if result.per_angle else 0}
    for pa, cov in zip(summary["per_angle"], result.per_angle):   # positions, every model
        pa["group_cells"] = group_cells(model, cov).tolist()
    summary["noise"] = str(noise)
    if settings is not None:
        summary["model_settings"] = {
            k: asdict(v) if is_dataclass(v) else v
            for k, v in ((f.name, getattr(settings, f.name)) for f in fields(settings))}
    timeshared = ts_limit = None
    if args.epoch is not None:
        ts = timeshared_coverage(model, result.mix, epoch=args.epoch, noise=noise,
                                 progress=_progress(None, "epochs", "epoch"))
        timeshared, ts_limit = ts.q, (ts.q, ts.counted_fraction)
        summary["timeshared"] = {
            "epoch": ts.epoch, "tv": tv_distance(ts.q, result.target),
            "tv_to_A_alpha": tv_distance(ts.q, result.mixed_q()),
            "epoch_iterations": ts.epochs, "converged": ts.converged,
            "error_estimate": ts.error_estimate, "counted_fraction": ts.counted_fraction}
    summary["steps_to_limit"], mix_limit = limit_report(model, result, args, timeshared)
    if args.horizon is not None:
        summary["horizon"] = horizon_report(result, args, start, summary["steps_to_limit"],
                                            mix_limit)
    if args.objective != "tv":
        result, summary["objective"] = design_for_time_cli(model, result, args)
        summary.update(alpha=[float(a) for a in result.alpha], residual=result.residual,
                       tv=result.tv, solver=result.method)
    metrics = None
    if args.metrics:
        metrics = metrics_cli.run_metrics(model, result, args, start, ts_limit,
                                          progress=_progress(None, "metrics", "record"))
    if args.out is not None:
        written = write_outputs(result, cs, args.out, summary, plots=not args.no_plots,
                                timeshared=timeshared, figures=args.figures)
        if metrics is not None:
            written += metrics_cli.write_metrics(args.out, metrics, not args.no_plots,
                                                 args.figures)
        written.append(write_config(Path(args.out), args, cs.env))
    if args.json:
        print(json.dumps(summary if metrics is None else {**summary, "metrics": metrics}))
    else:
        print(format_table(summary))
        if metrics is not None:
            print(metrics_cli.format_metrics(metrics))
    if args.out is not None:
        report_written(written, args)
    return 0


def design_for_time_cli(model, result: MixDesign, args) -> tuple[MixDesign, dict]:
    """``--objective cover90|idleness``: the α that minimises the time objective
    (:func:`planners.coverage.design_mix`, docs/model.md §20b) in place of the TV design's,
    with its coverage, TV and residual against the target; and alpha.json's "objective".
    """
    td = design_mix(model, result.angles, result.noise, objective=args.objective,
                    horizon=args.horizon, epoch=args.epoch, robots=args.robots, rng=args.seed,
                    progress=_progress(None, "candidates", "mix"))
    A = result.columns if result.columns is not None else \
        np.column_stack([a.q for a in result.per_angle])
    mixed = A @ td.alpha
    design = replace(result, alpha=np.asarray(td.alpha, dtype=float), mixed=mixed,
                     residual=float(np.linalg.norm(mixed - result.target)),
                     tv=tv_distance(mixed, result.target),
                     method=f"{args.objective}: simplex grid, sampled")
    return design, {
        "name": args.objective, "value_steps": td.value, "value_se": td.value_se,
        "horizon": td.horizon, "epoch": td.epoch, "robots": td.robots, "runs": td.runs,
        "seed": td.seed, "candidates": int(len(td.candidates)),
        "tv_design_alpha": [float(a) for a in result.alpha]}


def limit_report(model, result: MixDesign, args, timeshared_q) -> tuple[dict, np.ndarray]:
    """alpha.json's "steps_to_limit": per angle and for the mix, the first T on a 2^(1/8) grid
    at which the coverage from the uniform start is within TV 0.05 of the limit, exact or
    extrapolated from the run's slow mode once that extrapolation is stable (docs/model.md
    section 20), within --limit-seconds per policy; and the mix's limit it was measured
    against.
    """
    hz = horizon_of(model)
    kw = {"noise": result.noise, "cap": args.limit_cap, "max_seconds": args.limit_seconds,
          "settle": True}
    limits = [a.q for a in result.per_angle]
    mix_limit = limits[0] if len(result.angles) == 1 else (
        timeshared_q if timeshared_q is not None else np.column_stack(limits) @ result.alpha)
    # one pass for the angles, and for the mix too when each of its runs keeps one angle
    epochs = args.epoch is not None and len(result.angles) > 1
    each, mix = steps_to_limit_each(hz, result.angles, limits, alpha=result.alpha,
                                    mix_limit=None if epochs else mix_limit, **kw)
    if epochs:
        mix = steps_to_limit(hz, result.angles, mix_limit, alpha=result.alpha,
                             epoch=args.epoch, **kw)
    return {"tol": LIMIT_TV, "start": "uniform", "limit_seconds": args.limit_seconds,
            "per_angle": [{"angle": _num(a), **r} for a, r in zip(result.angles, each)],
            "mix": mix}, mix_limit


def horizon_report(result: MixDesign, args, start, limit: dict, mix_limit) -> dict:
    """alpha.json's "horizon": T, start, per-angle and mix TV to the limit (docs/model.md
    section 20); warns on stderr when T is far below a policy's steps_to_limit.
    """
    T = int(args.horizon)
    per = [{"angle": r["angle"], "tv_to_limit": tv_distance(col, a.q), **r}
           for col, a, r in zip(result.A.T, result.per_angle, limit["per_angle"])]
    mix = {"tv_to_limit": tv_distance(result.mixed, mix_limit), **limit["mix"]}
    for name, r in [*((f"{p['angle']}°", p) for p in per), ("the mix", mix)]:
        need = r["estimate"] if r["estimate"] is not None else r["last"]
        if r["estimate"] is None or T < need / 4:
            print(f"warning: --horizon {T} is far below the {stl_text(r)} steps {name} needs "
                  f"to come within TV {r['tol']} of its limit (TV at T: "
                  f"{r['tv_to_limit']:.3f}); the limit does not describe this horizon.",
                  file=sys.stderr)
    return {"T": T, "start": "uniform" if start is None else int(start), "epoch": args.epoch,
            "convergence": result.convergence, "per_angle": per, "mix": mix}


def stl_text(r: dict) -> str:
    """A steps_to_limit record in words: "1234", "about 6.1e+06 (extrapolated from 1600)" or
    "more than 7611".
    """
    if r["steps"] is not None:                           # exact
        return str(r["steps"])
    est = r["estimate"]
    if est is not None:                                  # extrapolated
        return f"about {est if est < 100_000 else format(est, '.2g')} (extrapolated from " \
               f"{r['last']})"
    return f"more than {r['last']}"


def parse_model_options(model: str, options) -> object | None:
    """The model's settings record from ``KEY=VALUE`` strings (None: the defaults)."""
    if not options:
        return None
    return with_options(default_settings(model), options, "--model-option",
                        f" (the {model} model's settings)")


def summarise(result: MixDesign, cs: CellSpace, env_name: str, target_desc: str) -> dict:
    """The content of alpha.json."""
    return {
        "env": env_name, "K": cs.K, "P": cs.P, "N": cs.N, "cell_size": cs.h,
        "eps": _num(result.eps), "r": result.r,
        "target": target_desc, "target_space": result.space,
        "angles": [_num(a) for a in result.angles],
        "alpha": [float(a) for a in result.alpha],
        "residual": result.residual,
        "residual_norm": "Euclidean 2-norm ||A alpha - b||_2 (not squared)",
        "tv": result.tv,
        "solver": result.method,
        "per_angle": [a.summary() for a in result.per_angle],
    }


def format_table(summary: dict) -> str:
    """A short human-readable table of alpha.json's content."""
    model = f" model={summary['model']}" if summary.get("model") else ""
    lines = [f"{summary['env']}: K={summary['K']} P={summary['P']} N={summary['N']}{model} "
             f"noise={summary['noise']} target={summary['target']}",
             f"{'angle':>7} {'alpha':>10} {'groups':>7} {'largest':>8} {'transient':>10}"]
    for a, pa in zip(summary["alpha"], summary["per_angle"]):
        sizes = pa.get("group_cells", pa["group_sizes"])
        largest = max(sizes) if sizes else 0
        lines.append(f"{str(pa['angle']) + '°':>7} {a:10.6f} {pa['persistent_groups']:7d} "
                     f"{largest:8d} {100 * pa['transient_fraction']:9.1f}%")
    states = summary.get("states")
    if states and summary["per_angle"] and "group_cells" in summary["per_angle"][0]:
        lines.append(f"largest: position cells of the largest persistent group; transient: "
                     f"share of the {states['count']} {states['kind']} in no group")
    lines.append(f"residual ||A alpha - b||_2 = {summary['residual']:.6g}, "
                 f"TV = {summary['tv']:.6g}")
    hz, stl = summary.get("horizon"), summary.get("steps_to_limit")
    if hz:
        lines.append(f"over the first {hz['T']} steps (start {hz['start']}); steps to the "
                     f"limit (TV <= {stl['tol']}, from the uniform start):")
        for r in [*hz["per_angle"], {**hz["mix"], "angle": "mix"}]:
            lines.append(f"{str(r['angle']):>7}  TV(q_T, limit) = {r['tv_to_limit']:.4f}  "
                         f"steps_to_limit = {stl_text(r)}")
    elif stl:
        lines.append(f"steps to the limit (TV <= {stl['tol']}, from the uniform start):")
        for r in [*stl["per_angle"], {**stl["mix"], "angle": "mix"}]:
            lines.append(f"{str(r['angle']):>7}  steps_to_limit = {stl_text(r)}")
    ts = summary.get("timeshared")
    if ts:
        note = "" if ts["converged"] else \
            f" (not converged: estimated error {ts['error_estimate']:.2g})"
        lines.append(f"executed in {ts['epoch']}-step epochs: TV to target = {ts['tv']:.6g}, "
                     f"TV to A alpha = {ts['tv_to_A_alpha']:.6g}{note}")
    return "\n".join(lines)


def write_outputs(result: MixDesign, cs: CellSpace, out_dir, summary: dict,
                  plots: bool = True, timeshared=None, figures: str = "png") -> list[Path]:
    """Write coverage.csv, alpha.json (and the heatmaps) into out_dir; ``timeshared`` is the
    mix's predicted coverage when executed in epochs (series "mix_epochs"). Returns the
    files written. Figure titles name ``summary["model"]`` when it is there; ``figures`` is
    their format (png, svg or pdf).
    """
    out = writable_path(out_dir, "the output folder", folder=True)
    ij, xy = cs.cells_ij, cs.centres
    mixed = result.mixed_q()
    target_q = result.target if result.space == "positions" else \
        result.target.reshape(cs.K, cs.P).sum(axis=0)
    qs = [a.q for a in result.per_angle] if result.horizon is None else list(result.columns.T)
    series = [(_num(a.angle), q) for a, q in zip(result.per_angle, qs)]
    series += [("mix", mixed), ("target", target_q)]
    if timeshared is not None:
        series.append(("mix_epochs", timeshared))
    with open(out / "coverage.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["angle", "p", "i", "j", "x", "y", "q"])
        for name, q in series:
            for p in range(cs.P):
                w.writerow([name, p, int(ij[p, 0]), int(ij[p, 1]), f"{xy[p, 0]:.6g}",
                            f"{xy[p, 1]:.6g}", repr(float(q[p]))])
    if result.space == "configurations":
        z = np.arange(cs.N)
        cols = [(_num(a.angle), a.pi) for a in result.per_angle]
        cols += [("mix", result.A @ result.alpha), ("target", result.target)]
        with open(out / "coverage_configurations.csv", "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(["angle", "z", "p", "k", "pi"])
            for name, v in cols:
                for zz, val in zip(z.tolist(), v.tolist()):
                    w.writerow([name, zz, zz % cs.P, zz // cs.P, repr(val)])
    (out / "alpha.json").write_text(json.dumps(summary, indent=2) + "\n")
    written = [out / "coverage.csv"] + (
        [out / "coverage_configurations.csv"] if result.space == "configurations" else []) + [
        out / "alpha.json"]
    model = f"{summary['model']} model, " if summary.get("model") else ""    # for titles
    if plots:
        from bouncesim.coverage_plots import save_heatmap, save_mix_vs_target
        over = "" if result.horizon is None else f" over {result.horizon} steps"
        for a, q in zip(result.per_angle, qs):
            written.append(save_heatmap(
                out / f"heatmap_angle_{_num(a.angle)}.{figures}", cs, q,
                title=f"{cs.env.name}: coverage of {_num(a.angle)}°{over} "
                f"({model}{_noise_label(result.noise)})"))
        alpha_title = f"{cs.env.name}, {model}alpha = " + ", ".join(
            f"{_num(a)}°: {al:.3f}" for a, al in zip(result.angles, result.alpha))
        written.append(save_mix_vs_target(out / f"heatmap_mix_vs_target.{figures}", cs, mixed,
                                          target_q, title=alpha_title))
        if timeshared is not None:
            epoch = summary["timeshared"]["epoch"]
            written.append(save_mix_vs_target(
                out / f"heatmap_mix_epochs_vs_target.{figures}", cs, timeshared, target_q,
                label="executed", title=f"{alpha_title}, executed in {epoch}-step epochs"))
    return written


def _noise_label(noise: TurnNoise) -> str:
    """The rotation noise for a figure title."""
    base = (f"Gaussian σ {_num(noise.sigma_deg)}°" if noise.sigma_deg > 0
            else f"eps {_num(noise.eps_deg)}°, r {noise.r:g}")
    if noise.has_body:
        base += (f", body {_num(noise.body_offset_deg)}° ± {_num(noise.body_sigma_deg)}°")
    return base


def _num(x):
    x = float(x)
    return int(round(x)) if abs(x - round(x)) < 1e-9 else x
