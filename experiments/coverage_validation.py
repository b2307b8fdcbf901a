"""Predicted against simulated coverage (docs/model.md §16 against docs/model.md §8).

For every environment and every bouncing angle of the coverage setting (Table I:
Φ = {30°, 75°, 315°}, ε = 5°, r = 0.8, 360 orientations, 0.34 m cells), plus the policy mix α
that each model designs for the uniform target, the predicted coverage q is compared with the
step-sampled visit histogram q̂ of simulated runs:

- the kinematic twin (:class:`bouncesim.robots.kinematic.KinematicBatch`): long runs, at least 10^6
  counted steps for each estimate, from starts drawn uniformly over the N configurations,
  after a burn-in (``--twin-burn-in``) so that the histogram estimates the *limiting*
  distribution the models predict;
- PyBullet (:class:`bouncesim.robots.pybullet.PyBulletRobot` through
  :func:`bouncesim.runs.execute.execute`), or MuJoCo with ``--physics mujoco``
  (:class:`bouncesim.robots.mujoco.MuJoCoRobot`, the second engine): shorter runs
  (``--pybullet-runs`` runs of ``--pybullet-steps`` steps per estimate), each from its own
  uniform random start, so one run trapped in a small persistent group does not stand for
  the whole estimate.

The same simulation is run twice with independent seeds (replicates 0 and 1); the TV between
the two is the noise floor of the estimate at that step count. A mix is run by time-sharing
in epochs of ``--epoch`` steps (docs/model.md §21); its prediction is the model's *time-shared*
coverage (:mod:`planners.coverage.timeshare`: the model's chain followed through the epochs), and
docs/model.md §16's Σ α_i q_i is reported beside it (``tv_pooled_sum``). The two differ when an
epoch is short against an angle's mixing: in fig1 at 315° the robot leaks into a pocket at
about 1e-4 per step, which a 1000-step epoch rarely reaches.

Outputs (under ``--out``, default results/coverage_validation/):

- ``runs.csv``: one row per simulation (trial index, env, policy, backend, replicate, run,
  steps, counted, dropped, bumps, wall time, and the raw counts), written by the resumable sweep
  runner (:mod:`bouncesim.runs.sweep`; trial i's seed is spawned from ``--seed`` and i);
- ``histograms.csv``: env, policy, backend, replicate, run, p, count (the raw visit counts);
- ``predictions.csv``: env, model, policy, p, q, q_sum (Σ α_i q_i for a mix, q for an
  angle); the α of each model's mix is in ``alpha.csv``;
- ``tv.csv``: env, model, policy, backend, steps, dropped fraction, TV(q, q̂) of replicate 0,
  of the pooled replicates, TV(Σ α_i q_i, q̂) pooled (mixes only) and the noise floor
  TV(q̂₀, q̂₁);
- ``heatmaps_<env>_<model>.png``: predicted, simulated (twin, pooled) and their difference
  for every policy; ``tv_<backend>.png``: the TV table as bars;
- ``config.json``: every parameter, the seed, package versions and the git revision.

Figures are drawn from the CSV files alone (:func:`draw_figures`).

``--quick`` (what CI runs): lab and fig1 at 72 orientations (5° steps, so the same angles
and ε stay valid), 10^5 twin steps per estimate after a 2000-step burn-in, and a 60-step
PyBullet run of one angle.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

import envs
from bouncesim.robots import make_robot
from bouncesim.robots.kinematic import KinematicBatch
from bouncesim.robots.noise import noise_for_mix
from bouncesim.runs.execute import execute
from bouncesim.runs.executors import add_executor_args, make_executor
from bouncesim.runs.sweep import run_sweep
from experiments.common import (
    SweepOptions,
    add_models_arg,
    experiment_parser,
    invocation,
    output_dir,
    recorded,
)
from planners.cells import CellSpace
from planners.coverage import TurnNoise, design_mix, model_for, timeshared_coverage
from planners.metrics import tv_distance
from planners.plan import PolicyMix

__all__ = ["ANGLES", "EPS", "PHYSICS", "R", "Config", "draw_figures", "env_label", "main",
           "predict", "run", "simulate", "tv_table"]

NAME = "coverage_validation"
ANGLES = (30.0, 75.0, 315.0)
EPS, R = 5.0, 0.8
ENVS = ("lab", "fig1", "complex")


def _num(x):
    x = float(x)
    return int(round(x)) if abs(x - round(x)) < 1e-9 else x


def policy_label(angles, alpha) -> str:
    """'75' for one angle, 'mix:30=0.1,75=0.4,315=0.5' for a mix (the α in the label)."""
    nz = [(a, al) for a, al in zip(angles, alpha) if al > 0]
    if len(nz) == 1:
        return f"{_num(nz[0][0])}"
    return "mix:" + ",".join(f"{_num(a)}={al:.6f}" for a, al in nz)


def parse_policy(label: str) -> PolicyMix:
    if label.startswith("mix:"):
        pairs = [t.split("=") for t in label[4:].split(",")]
        alpha = np.array([float(v) for _, v in pairs])
        return PolicyMix(tuple(float(a) for a, _ in pairs), tuple(alpha / alpha.sum()), EPS, R)
    return PolicyMix((float(label),), (1.0,), EPS, R)


PHYSICS = ("pybullet", "mujoco")
"""The physics engines of the short runs (``--physics``)."""


# ----------------------------------------------------------------------------- one trial
def simulate(params: dict, rng: np.random.Generator) -> dict:
    """One simulated estimate of the visit histogram (a sweep trial; pure in params + rng).

    params: env, orientations, policy (label), backend ("twin", "pybullet" or "mujoco"),
    steps, robots (twin batch size), epoch, speed (physics drive speed [m/s]) and optionally
    cell_size [m] (default: the catalogue's) and burn_in (twin steps per robot run first and
    not counted, default 0). Other keys are carried along untouched.
    Returns the run's row; ``counts`` is the histogram over position cells as a
    space-separated string.
    """
    env = envs.load(params["env"], cell_size=params.get("cell_size"),
                    orientations=int(params["orientations"]))
    cs = CellSpace(env)
    mix = parse_policy(params["policy"])
    noise = noise_for_mix(mix, cs.delta_deg)
    epoch = int(params["epoch"])
    steps = int(params["steps"])
    t0 = time.perf_counter()
    if params["backend"] == "twin":
        n = int(params["robots"])
        per = math.ceil(steps / n)
        res = KinematicBatch(env, n, rng, cells=cs).run(
            mix, per, epoch=epoch, noise=noise, burn_in=int(params.get("burn_in", 0)))
        counts, dropped, bumps = res.counts, res.dropped, res.bumps
    elif params["backend"] in PHYSICS:
        with make_robot(params["backend"], env, noise=noise, rng=rng) as robot:
            run = execute(mix, robot, steps=steps, epoch=epoch, rng=rng, cells=cs,
                          speed=float(params["speed"]), record_trace=False)
        counts, dropped, bumps = run.counts, run.dropped, run.bumps
    else:
        raise ValueError(f"unknown backend {params['backend']!r}")
    return {"counted": int(counts.sum()), "dropped": int(dropped), "bumps": int(bumps),
            "wall_s": round(time.perf_counter() - t0, 3),
            "counts": " ".join(str(int(c)) for c in counts)}


# ----------------------------------------------------------------------------- predictions
def predict(cs: CellSpace, model: str = "step", epoch: int | None = None) -> dict:
    """Predicted coverage of each angle and of the model's own α mix (uniform target).

    The mix's prediction is the model's time-shared coverage with epochs of ``epoch`` steps
    (:func:`planners.coverage.timeshared_coverage`, docs/model.md §19), or docs/model.md §16's
    Σ α_i q_i when ``epoch`` is None.

    Returns {"q": {label: (P,) array}, "q_sum": {label: Σ α_i q_i for the mix, q for an
    angle}, "alpha": (m,) array, "mix": label, "seconds": float}.
    """
    t0 = time.perf_counter()
    cm = model_for(cs, model)
    res = design_mix(cm, ANGLES, TurnNoise(EPS, R))
    q = {f"{_num(a)}": ac.q for a, ac in zip(ANGLES, res.per_angle)}
    mix = policy_label(ANGLES, res.alpha)
    q_sum = {**q, mix: res.mixed_q()}
    q[mix] = q_sum[mix] if epoch is None else timeshared_coverage(cm, res.mix, epoch=epoch).q
    return {"q": q, "q_sum": q_sum, "alpha": np.asarray(res.alpha), "mix": mix,
            "seconds": time.perf_counter() - t0}


def tv_table(runs: pd.DataFrame, preds: pd.DataFrame) -> pd.DataFrame:
    """TV of each prediction against each backend's histograms (replicate 0, pooled, floor)."""
    rows = []
    for (env, model, policy), pq in preds.groupby(["env", "model", "policy"], sort=False):
        pq = pq.sort_values("p")
        q = pq["q"].to_numpy()
        q_sum = pq["q_sum"].to_numpy() if "q_sum" in pq else q
        sims = runs[(runs.env == env) & (runs.policy == policy)]
        for backend, sb in sims.groupby("backend", sort=False):
            hist = {}
            for r in sb.itertuples():
                c = np.array(r.counts.split(), dtype=float)
                hist[int(r.replicate)] = hist.get(int(r.replicate), 0) + c
            h0 = hist.get(0)
            pooled = sum(hist.values())
            floor = tv_distance(hist[0], hist[1]) if 0 in hist and 1 in hist else math.nan
            total = float(sb.counted.sum() + sb.dropped.sum())
            rows.append({"env": env, "model": model, "policy": policy, "backend": backend,
                         "steps": int(sb.counted.sum() + sb.dropped.sum()),
                         "dropped_fraction": float(sb.dropped.sum()) / total if total else 0.0,
                         "tv": tv_distance(q, h0) if h0 is not None else math.nan,
                         "tv_pooled": tv_distance(q, pooled),
                         "tv_pooled_sum": (tv_distance(q_sum, pooled)
                                           if policy.startswith("mix") else math.nan),
                         "noise_floor": floor})
    return pd.DataFrame(rows)


# ----------------------------------------------------------------------------- figures
def env_label(name: str) -> str:
    """A catalogue name as it is; an env file path by its file stem (for file names)."""
    p = Path(name)
    return p.stem if p.suffix or len(p.parts) > 1 else name


def draw_figures(out: Path) -> list[Path]:
    """heatmaps_<env>_<model>.png and tv_<backend>.png from the CSV files alone."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from bouncesim.coverage_plots import diff_heatmap, heatmap
    from bouncesim.plots import save_figure

    out = Path(out)
    preds = pd.read_csv(out / "predictions.csv", dtype={"policy": str})
    hists = pd.read_csv(out / "histograms.csv", dtype={"policy": str})
    tv = pd.read_csv(out / "tv.csv", dtype={"policy": str})
    cfg = pd.read_json(out / "config.json", typ="series")
    paths = []
    for (env_name, model), pe in preds.groupby(["env", "model"], sort=False):
        cs = CellSpace(envs.load(env_name, orientations=int(cfg["orientations"])))
        policies = list(dict.fromkeys(pe.policy))
        fig, axes = plt.subplots(len(policies), 3, figsize=(13, 3.6 * len(policies)),
                                 squeeze=False)
        for row, pol in zip(axes, policies):
            q = pe[pe.policy == pol].sort_values("p")["q"].to_numpy()
            hb = hists[(hists.env == env_name) & (hists.policy == pol)
                       & (hists.backend == "twin")]
            sim = hb.groupby("p")["count"].sum().reindex(range(cs.P), fill_value=0)
            sim = sim.to_numpy(float)
            sim = sim / sim.sum() if sim.sum() > 0 else sim
            vmax = float(max(q.max(), sim.max()))
            name = (f"{pol}°" if not pol.startswith("mix")      # a policy is an angle [deg]
                    else f"mix α, {cfg['epoch']}-step epochs")
            heatmap(row[0], cs, q, title=f"{name}: predicted ({model})", vmax=vmax)
            heatmap(row[1], cs, sim, title=f"{name}: twin ({int(hb['count'].sum())} steps)",
                    vmax=vmax)
            t = tv[(tv.env == env_name) & (tv.model == model) & (tv.policy == pol)
                   & (tv.backend == "twin")]
            tvs = f"TV {float(t.tv_pooled.iloc[0]):.3f}" if len(t) else ""
            diff_heatmap(row[2], cs, sim - q, title=f"twin − predicted  {tvs}")
        fig.suptitle(f"{env_name}: predicted ({model} model) vs simulated coverage")
        paths.append(save_figure(fig, out / f"heatmaps_{env_label(env_name)}_{model}.png",
                                 dpi=90))
    for backend, tb in tv.groupby("backend", sort=False):
        tb = tb.assign(label=tb.env.map(env_label) + " "
                       + tb.policy.str.replace(r"mix:.*", "mix", regex=True))
        models = list(dict.fromkeys(tb.model))
        labels = list(dict.fromkeys(tb.label))
        fig, ax = plt.subplots(figsize=(max(6, 0.8 * len(labels)), 4))
        width = 0.8 / (len(models) + 1)
        xs = np.arange(len(labels))
        for i, m in enumerate(models):
            tm = tb[tb.model == m].set_index("label").reindex(labels)
            ax.bar(xs + i * width, tm.tv_pooled, width, label=f"{m} model")
        fl = tb.drop_duplicates("label").set_index("label").reindex(labels)
        ax.bar(xs + len(models) * width, fl.noise_floor, width, color="0.6",
               label="noise floor (seed vs seed)")
        ax.axhline(0.05, color="k", lw=0.8, ls="--")
        ax.set_xticks(xs + 0.4 - width / 2, labels, rotation=45, ha="right")
        ax.set_ylabel("TV(predicted, simulated)")
        ax.set_title(f"predicted vs {backend} coverage")
        ax.legend(fontsize=8)
        paths.append(save_figure(fig, out / f"tv_{backend}.png", dpi=110))
    return paths


# ----------------------------------------------------------------------------- main
@dataclass(frozen=True)
class Config(SweepOptions):
    """Parameters of one coverage_validation run (``config.json`` minus the execution fields).

    Attributes
    ----------
    envs : tuple of str       environments
    models : tuple of str     coverage models to predict with
    orientations : int        K
    twin_steps : int          twin steps per estimate
    twin_robots : int         robots in one twin batch
    physics : str             the physics engine of the short runs: "pybullet" or "mujoco"
                              (the ``pybullet_*`` settings apply to either)
    pybullet_steps : int      steps of one physics run, 0 to skip
    pybullet_runs : int       physics runs per estimate, each from its own random start
    twin_burn_in : int        twin steps per robot run before counting starts
    pybullet_envs : tuple     environments run in physics
    epoch : int               steps per epoch when a mix is time-shared
    speed : float             PyBullet drive speed [m/s]
    quick : bool              CI budget; ``run`` then sends only 75° to PyBullet
    seed : int                root seed of the sweep
    out : Path                output folder
    workers, dask_local, dask : the executor (see ``add_executor_args``)
    progress : bool           show a progress bar
    """

    envs: tuple[str, ...] = ENVS
    models: tuple[str, ...] = ("step",)
    orientations: int = 360
    twin_steps: int = 2_000_000
    twin_robots: int = 200
    physics: str = "pybullet"
    pybullet_steps: int = 1000
    pybullet_runs: int = 4
    twin_burn_in: int = 40_000
    pybullet_envs: tuple[str, ...] = ENVS
    epoch: int = 1000
    speed: float = 0.3
    quick: bool = False
    seed: int = 0
    out: Path = Path("results") / NAME


def run(config: Config) -> Path:
    """Predict, simulate and compare; writes the CSVs, figures and config.json.

    Returns the output folder.
    """
    q = config.quick
    K = config.orientations
    out = output_dir(config.out)

    pred_rows, alpha_rows, trials = [], [], []
    for name in config.envs:
        cs = CellSpace(envs.load(name, orientations=K))
        policies = []
        for model in config.models:
            pr = predict(cs, model, config.epoch)
            alpha_rows += [{"env": name, "model": model, "angle": _num(a), "alpha": float(al),
                            "seconds": pr["seconds"]} for a, al in zip(ANGLES, pr["alpha"])]
            for label, qv in pr["q"].items():
                pred_rows.append(pd.DataFrame({"env": name, "model": model, "policy": label,
                                               "p": np.arange(cs.P), "q": qv,
                                               "q_sum": pr["q_sum"][label]}))
                policies.append(label)
        for label in dict.fromkeys(policies):
            for rep in (0, 1):
                trials.append({"env": name, "orientations": K, "policy": label,
                               "backend": "twin", "steps": config.twin_steps,
                               "robots": config.twin_robots, "epoch": config.epoch,
                               "speed": config.speed, "replicate": rep, "run": 0,
                               "burn_in": config.twin_burn_in})
                if (config.pybullet_steps > 0 and name in config.pybullet_envs
                        and (not q or label == "75")):
                    trials += [{**trials[-1], "backend": config.physics,
                                "steps": config.pybullet_steps, "run": i, "burn_in": 0}
                               for i in range(config.pybullet_runs)]
    preds = pd.concat(pred_rows, ignore_index=True)
    preds.to_csv(out / "predictions.csv", index=False, float_format="%.12g")
    pd.DataFrame(alpha_rows).to_csv(out / "alpha.csv", index=False)
    record = {"experiment": NAME, **recorded(config), "angles": list(ANGLES), "eps": EPS,
              "r": R, "cell_size": "catalogue default"}
    runs = run_sweep(simulate, trials, config.seed, out, record, make_executor(config),
                     progress=config.progress, name="runs",
                     provenance=invocation(config.seed))
    hist = []
    for r in runs.itertuples():
        c = np.array(r.counts.split(), dtype=np.int64)
        hist.append(pd.DataFrame({"env": r.env, "policy": r.policy, "backend": r.backend,
                                  "replicate": r.replicate, "run": r.run,
                                  "p": np.arange(c.size), "count": c}))
    pd.concat(hist, ignore_index=True).to_csv(out / "histograms.csv", index=False)
    tv = tv_table(runs, preds)
    tv.to_csv(out / "tv.csv", index=False, float_format="%.4f")
    draw_figures(out)
    with pd.option_context("display.width", 160, "display.max_columns", 20):
        print(tv.assign(policy=tv.policy.str.replace(r"mix:.*", "mix", regex=True))
              .to_string(index=False, float_format=lambda x: f"{x:.3f}"))
    print(f"wrote {out}")
    return out


def main(argv=None) -> int:
    """Parse the command line into a :class:`Config` and :func:`run` it (exit status)."""
    p = experiment_parser(NAME, __doc__.split("\n\n")[0])
    p.add_argument("--envs", default=None,
                   help=f"comma-separated catalogue names or env file paths (default "
                   f"{','.join(ENVS)}; quick: lab,fig1)")
    add_models_arg(p, "step", "the models to predict with")
    p.add_argument("--orientations", type=int, default=None,
                   help="K (default 360; quick 72)")
    p.add_argument("--twin-steps", type=int, default=None,
                   help="twin steps per estimate (default 2e6; quick 1e5)")
    p.add_argument("--twin-robots", type=int, default=200,
                   help="robots in one twin batch (default 200)")
    p.add_argument("--physics", choices=PHYSICS, default="pybullet",
                   help="the physics engine of the short runs (default pybullet; mujoco "
                   "needs the mujoco extra); the --pybullet-* options apply to either")
    p.add_argument("--pybullet-steps", type=int, default=None,
                   help="steps of one PyBullet run, 0 to skip (default 1000; quick 60)")
    p.add_argument("--pybullet-runs", type=int, default=None,
                   help="PyBullet runs per estimate, each from its own random start "
                   "(default 4; quick 1)")
    p.add_argument("--pybullet-envs", default=None,
                   help="environments run in PyBullet (default: all; quick: lab)")
    p.add_argument("--twin-burn-in", type=int, default=None,
                   help="twin steps per robot run before counting starts (default 40000; "
                   "quick 2000): the prediction is the *limiting* distribution, and in fig1 "
                   "at 315° the robots leak into an absorbing pocket at about 1e-4 per step")
    p.add_argument("--epoch", type=int, default=1000,
                   help="steps per epoch when a mix is time-shared (default 1000); the "
                   "mix's prediction follows the same epochs")
    p.add_argument("--speed", type=float, default=0.3,
                   help="PyBullet drive speed [m/s] (default 0.3)")
    add_executor_args(p)
    args = p.parse_args(argv)
    q = args.quick
    env_names = [e.strip() for e in (args.envs or ("lab,fig1" if q else ",".join(ENVS)))
                 .split(",") if e.strip()]
    for e in env_names:           # a bad name or file is one sentence before any work
        envs.load(e)
    config = Config(
        envs=tuple(env_names), models=tuple(args.models),
        orientations=args.orientations or (72 if q else 360),
        twin_steps=args.twin_steps or (100_000 if q else 2_000_000),
        twin_robots=args.twin_robots,
        physics=args.physics,
        pybullet_steps=(args.pybullet_steps if args.pybullet_steps is not None
                        else (60 if q else 1000)),
        pybullet_runs=args.pybullet_runs or (1 if q else 4),
        twin_burn_in=(args.twin_burn_in if args.twin_burn_in is not None
                      else (2000 if q else 40_000)),
        pybullet_envs=tuple((args.pybullet_envs or (env_names[0] if q else ",".join(env_names)))
                            .split(",")),
        epoch=args.epoch, speed=args.speed, quick=q, seed=args.seed, out=args.out,
        workers=args.workers, dask_local=args.dask_local, dask=args.dask,
        progress=not args.no_progress)
    run(config)
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
