"""Which model's policy mix α delivers the target coverage: designed, then executed.

Table I's setting (the complex environment, Φ = {30°, 75°, 315°}, ε = 5°, r = 0.8, 360
orientations, uniform target over the position cells): each coverage model (``--models``,
default step, sampled and event) predicts the coverage q of every angle and designs its mix
α = argmin ‖Aα − b‖ over the simplex. Each α is then *executed* — time-shared in epochs
(docs/model.md §21) in the kinematic twin (long runs) and in PyBullet (shorter runs) — and the
simulated coverage is compared with the target:

- ``promised``: TV(Σ α_i q_i, b), what the model says its α achieves;
- ``delivered``: TV(q̂, b), what the simulated robot achieves with that α;
- ``prediction error``: TV(Σ α_i q_i, q̂).

As a yardstick, ``oracle`` is the α fitted on the twin's own per-angle histograms (what the
best mix of these three angles can do in the twin), executed the same way. Two replicates
with independent seeds give the noise floor.

Outputs (under ``--out``, default results/alpha_delivery/): ``alpha.csv`` (model, angle,
α), ``runs.csv`` (the simulations, with raw counts), ``delivery.csv`` (model, backend,
promised, delivered, prediction error, noise floor, steps), ``config.json`` and the
headline figure ``alpha_delivery.png`` (drawn from the CSV files alone).

``--horizon T`` designs every α for the first T steps of a run (docs/model.md §20: each
model's q_T from the uniform start, executed in ``--epoch`` epochs; SLSQP when epochs make the
fit non-linear) and executes it for exactly T steps without burn-in (robots =
max(twin robots, twin steps / T)); delivery.csv's ``horizon`` column says which (``limit``
without it).

``--quick``: 72 orientations, 2·10^5 twin steps per estimate, one short PyBullet run.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

import envs
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
from experiments.coverage_validation import ANGLES, EPS, R, policy_label, simulate
from planners.cells import CellSpace
from planners.coverage import TurnNoise, design_mix, model_for, solve_mix, uniform_target
from planners.metrics import tv_distance

__all__ = ["Config", "draw_figure", "main", "run"]

NAME = "alpha_delivery"
ENV = "complex"



def _counts(rows) -> np.ndarray:
    return sum(np.array(c.split(), dtype=float) for c in rows["counts"])


def _trials(label, policy, K, config, twin_steps, pb_steps, pb_runs):
    out = []
    robots, burn_in = config.twin_robots, config.twin_burn_in
    if config.horizon is not None:          # exactly the first T steps of many robots
        robots = max(robots, twin_steps // config.horizon)
        twin_steps, burn_in = robots * config.horizon, 0     # steps: over the batch
        pb_steps = min(pb_steps, config.horizon)
    for rep in (0, 1):
        base = {"label": label, "env": ENV, "orientations": K, "policy": policy,
                "robots": robots, "epoch": config.epoch, "speed": config.speed,
                "replicate": rep}
        out.append({**base, "backend": "twin", "steps": twin_steps, "run": 0,
                    "burn_in": burn_in})
        if pb_steps > 0:
            out += [{**base, "backend": "pybullet", "steps": pb_steps, "run": i, "burn_in": 0}
                    for i in range(pb_runs)]
    return out


def draw_figure(out: Path) -> Path:
    """alpha_delivery.png from delivery.csv and alpha.csv."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from bouncesim.plots import save_figure

    out = Path(out)
    d = pd.read_csv(out / "delivery.csv")
    al = pd.read_csv(out / "alpha.csv")
    labels = list(dict.fromkeys(d.label))
    backends = list(dict.fromkeys(d.backend))
    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(13, 4.6),
                                  gridspec_kw={"width_ratios": [2.2, 1]})
    xs = np.arange(len(labels))
    width = 0.8 / (1 + len(backends))
    prom = d.drop_duplicates("label").set_index("label").reindex(labels)
    ax.bar(xs, prom.promised, width, color="0.75", label="promised (model's own prediction)")
    for i, b in enumerate(backends):
        db = d[d.backend == b].set_index("label").reindex(labels)
        fl = db.noise_floor.to_numpy()
        lo = np.minimum(fl, db.delivered.to_numpy())
        ax.bar(xs + (i + 1) * width, db.delivered, width, yerr=[lo, fl], capsize=3,
               label=f"delivered in {b} (bar: ± seed-to-seed TV)")
    ax.set_xticks(xs + 0.4 - width / 2, [f"{lab}" for lab in labels])
    ax.set_ylabel("TV(coverage, uniform target)")
    ax.set_ylim(0, 1)
    ax.set_title(f"{ENV}: does the α each model designs deliver the target?")
    ax.legend(fontsize=8)
    angles = list(dict.fromkeys(al.angle))
    bottom = np.zeros(len(labels))
    for a in angles:
        v = al[al.angle == a].set_index("label").reindex(labels).alpha.to_numpy()
        ax2.bar(xs, v, 0.6, bottom=bottom, label=f"{a}°")
        bottom += v
    ax2.set_xticks(xs, labels)
    ax2.set_ylabel("α")
    ax2.set_title("the mixes")
    ax2.legend(fontsize=8)
    return save_figure(fig, out / "alpha_delivery.png", dpi=110)


@dataclass(frozen=True)
class Config(SweepOptions):
    """Parameters of one alpha_delivery run (``config.json`` minus the execution fields).

    Attributes
    ----------
    models : tuple of str     coverage models, each designs its own mix
    orientations : int        K
    twin_steps : int          twin steps per estimate
    twin_robots : int         robots per twin batch
    pybullet_steps : int      steps per PyBullet run, 0 to skip
    pybullet_runs : int       PyBullet runs per estimate from random starts
    twin_burn_in : int        twin steps per robot before counting
    epoch : int               steps per epoch
    speed : float             PyBullet speed [m/s]
    horizon : int or None     design and execute for the first T steps (None: the limit)
    quick : bool              recorded; ``main`` turns it into the smaller budget
    seed : int                root seed (the oracle's sweep uses seed + 1)
    out : Path                output folder
    workers, dask_local, dask : the executor (see ``add_executor_args``)
    progress : bool           show a progress bar
    """

    models: tuple[str, ...] = ("step", "sampled", "event")
    orientations: int = 360
    twin_steps: int = 2_000_000
    twin_robots: int = 200
    pybullet_steps: int = 2000
    pybullet_runs: int = 4
    twin_burn_in: int = 20_000
    epoch: int = 1000
    speed: float = 0.3
    horizon: int | None = None
    quick: bool = False
    seed: int = 0
    out: Path = Path("results") / NAME


def run(config: Config) -> Path:
    """Design each model's α and execute it, and the oracle's; writes CSVs, figure, config.

    Returns the output folder.
    """
    models = config.models
    K, twin_steps = config.orientations, config.twin_steps
    pb_steps, pb_runs = config.pybullet_steps, config.pybullet_runs
    out = output_dir(config.out)
    cs = CellSpace(envs.load(ENV, orientations=K))
    b = uniform_target(cs)

    alpha_rows, promised, trials, mixes = [], {}, [], {}
    for m in models:
        t0 = time.perf_counter()
        res = design_mix(model_for(cs, m), ANGLES, TurnNoise(EPS, R), horizon=config.horizon,
                         epoch=None if config.horizon is None else config.epoch)
        secs = time.perf_counter() - t0
        mixes[m] = res.mixed_q()
        promised[m] = tv_distance(mixes[m], b)
        alpha_rows += [{"label": m, "angle": int(a), "alpha": float(x), "seconds": secs}
                       for a, x in zip(ANGLES, res.alpha)]
        trials += _trials(m, policy_label(ANGLES, res.alpha), K, config, twin_steps, pb_steps,
                          pb_runs)
    # per-angle twin histograms, for the oracle α
    for a in ANGLES:
        trials += [t for t in _trials(f"angle {int(a)}", f"{int(a)}", K, config, twin_steps, 0, 0)]
    record = {"experiment": NAME, **recorded(config), "env": ENV, "angles": list(ANGLES),
              "eps": EPS, "r": R, "target": "uniform over position cells"}
    runs = run_sweep(simulate, trials, config.seed, out, record, make_executor(config),
                     progress=config.progress, name="runs",
                     provenance=invocation(config.seed))
    twin = runs[runs.backend == "twin"]
    A_twin = np.column_stack([_counts(twin[twin.label == f"angle {int(a)}"]) for a in ANGLES])
    A_twin = A_twin / A_twin.sum(axis=0)
    oracle = solve_mix(A_twin, b)
    alpha_rows += [{"label": "oracle", "angle": int(a), "alpha": float(x), "seconds": 0.0}
                   for a, x in zip(ANGLES, oracle.alpha)]
    promised["oracle"] = tv_distance(A_twin @ oracle.alpha, b)
    mixes["oracle"] = A_twin @ oracle.alpha
    oracle_trials = _trials("oracle", policy_label(ANGLES, oracle.alpha), K, config, twin_steps,
                            pb_steps, pb_runs)
    runs2 = run_sweep(simulate, oracle_trials, config.seed + 1, out / "oracle",
                      {**record, "oracle_alpha": oracle.alpha.tolist()},
                      make_executor(config), progress=config.progress, name="runs",
                      provenance=invocation(config.seed))
    allruns = pd.concat([runs, runs2], ignore_index=True)
    pd.DataFrame(alpha_rows).to_csv(out / "alpha.csv", index=False)
    rows = []
    for label in [*models, "oracle"]:
        for backend in ("twin", "pybullet"):
            sel = allruns[(allruns.label == label) & (allruns.backend == backend)]
            if sel.empty:
                continue
            h = {rep: _counts(sel[sel.replicate == rep]) for rep in (0, 1)}
            pooled = h[0] + h[1]
            rows.append({"label": label, "backend": backend,
                         "horizon": "limit" if config.horizon is None else config.horizon,
                         "promised": promised[label],
                         "delivered": tv_distance(pooled, b),
                         "prediction_error": tv_distance(mixes[label], pooled),
                         "noise_floor": tv_distance(h[0], h[1]),
                         "steps": int(sel.counted.sum() + sel.dropped.sum())})
    delivery = pd.DataFrame(rows)
    delivery.to_csv(out / "delivery.csv", index=False, float_format="%.4f")
    draw_figure(out)
    print(pd.DataFrame(alpha_rows).pivot(index="label", columns="angle", values="alpha")
          .to_string(float_format=lambda x: f"{x:.3f}"))
    print(delivery.to_string(index=False, float_format=lambda x: f"{x:.3f}"))
    print(f"wrote {out}")
    return out


def main(argv=None) -> int:
    """Parse the command line into a :class:`Config` and :func:`run` it (exit status)."""
    p = experiment_parser(NAME, __doc__.split("\n\n")[0])
    add_models_arg(p, "step,sampled,event", "each designs its own mix")
    p.add_argument("--orientations", type=int, default=None, help="K (default 360; quick 72)")
    p.add_argument("--twin-steps", type=int, default=None,
                   help="twin steps per estimate (default 2e6; quick 2e5)")
    p.add_argument("--twin-robots", type=int, default=200, help="robots per twin batch")
    p.add_argument("--pybullet-steps", type=int, default=None,
                   help="steps per PyBullet run, 0 to skip (default 2000; quick 60)")
    p.add_argument("--pybullet-runs", type=int, default=None,
                   help="PyBullet runs per estimate from random starts (default 4; quick 1)")
    p.add_argument("--twin-burn-in", type=int, default=None,
                   help="twin steps per robot before counting (default 20000; quick 2000)")
    p.add_argument("--epoch", type=int, default=1000, help="steps per epoch (default 1000)")
    p.add_argument("--speed", type=float, default=0.3, help="PyBullet speed [m/s]")
    p.add_argument("--horizon", type=int, default=None, metavar="T",
                   help="design and execute every mix for the first T steps (default: limit)")
    add_executor_args(p)
    args = p.parse_args(argv)
    q = args.quick
    config = Config(
        models=tuple(args.models), orientations=args.orientations or (72 if q else 360),
        twin_steps=args.twin_steps or (200_000 if q else 2_000_000),
        twin_robots=args.twin_robots,
        pybullet_steps=(args.pybullet_steps if args.pybullet_steps is not None
                        else (60 if q else 2000)),
        pybullet_runs=args.pybullet_runs or (1 if q else 4),
        twin_burn_in=(args.twin_burn_in if args.twin_burn_in is not None
                      else (2000 if q else 20_000)),
        epoch=args.epoch, speed=args.speed, horizon=args.horizon, quick=q, seed=args.seed,
        out=args.out,
        workers=args.workers, dask_local=args.dask_local, dask=args.dask,
        progress=not args.no_progress)
    run(config)
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
