"""Convergence of the coverage models: TV to simulation against resolution and compute time.

For each environment (``--envs``, default lab and complex) at Table I's noise (Φ = {30°, 75°,
315°}, ε = 5°, r = 0.8), every coverage model is evaluated over a ladder of resolutions:

- ``step`` (the paper's model): orientations K ∈ {72, 360, 720} at the catalogue cell size;
- ``sampled`` (generalized cell mapping): the m × m lattice of sample points per position
  cell (``grid``) and the sample headings per orientation cell (``theta_samples``);
- ``event`` (bump-to-bump): contact-bin length along the C-space boundary, and flight start
  points per bin (the recommended default is 0.03 m with 2 points);
- every model also at a finer cell size (0.17 m) where it is cheap enough.

Each prediction is timed and compared, angle by angle, with the kinematic twin's
step-sampled histogram (docs/model.md §22) at the same cell size and K, from a long run (``--steps``
per angle, default 2·10^6) plus a second seed for the noise floor. The twin runs go through
the resumable sweep runner.

Outputs (under ``--out``, default results/model_convergence/): ``convergence.csv`` (env,
model, knob, value, K, cell size, seconds, TV per angle, max and mean TV, noise floor),
``twin/`` (the reference runs), ``config.json`` and ``convergence.png`` (TV against the
knob and against compute time, drawn from the CSV alone).

``--quick``: lab only, K = 72, a short ladder and 2·10^5 twin steps.
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
    experiment_parser,
    invocation,
    output_dir,
    recorded,
    write_config,
)
from experiments.coverage_validation import ANGLES, EPS, R, simulate
from planners.cells import CellSpace
from planners.coverage import TurnNoise, model_for
from planners.metrics import tv_distance

__all__ = ["LADDER", "QUICK_LADDER", "Config", "draw_figure", "main", "predict_q", "run"]

NAME = "model_convergence"

# (model, knob, values, fixed settings); knob "orientations" and "cell_size" change the cell
# space (and so the twin reference), the others are model settings.
LADDER = [
    ("step", "orientations", (72, 360, 720), {}),
    ("step", "cell_size", (0.34, 0.17), {}),
    ("sampled", "grid", (1, 2, 3), {}),
    ("sampled", "theta_samples", (1, 4), {"grid": 2}),
    ("event", "bin_length", (0.2, 0.1, 0.05, 0.03, 0.02), {"samples": 2}),
    ("event", "samples", (1, 2, 3), {"bin_length": 0.03}),
    ("event", "orientations", (72, 360, 720), {}),
    ("event", "cell_size", (0.34, 0.17), {}),
]
QUICK_LADDER = [
    ("step", "orientations", (72,), {}),
    ("sampled", "grid", (1, 3), {}),
    ("event", "bin_length", (0.1, 0.03), {}),
]
CELL_KNOBS = ("orientations", "cell_size")


def predict_q(cs: CellSpace, angle: float, model: str, settings: dict, rng) -> np.ndarray:
    """Coverage q (P,) of one angle under a model with the given settings."""
    return model_for(cs, model, settings or None).analyse(angle, TurnNoise(EPS, R)).q



def draw_figure(out: Path) -> Path:
    """Draw convergence.png (TV against resolution and time) from the CSVs in ``out``."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from bouncesim.plots import save_figure

    out = Path(out)
    d = pd.read_csv(out / "convergence.csv")
    envs_ = list(dict.fromkeys(d.env))
    knobs = list(dict.fromkeys(zip(d.model, d.knob)))
    fig, axes = plt.subplots(len(envs_), 2, figsize=(13, 4.2 * len(envs_)), squeeze=False)
    colors = {"step": "tab:red", "sampled": "tab:orange", "event": "tab:blue"}
    styles = ["-", "--", ":", "-."]
    for row, env_name in zip(axes, envs_):
        de = d[d.env == env_name]
        for model, knob in knobs:
            dk = de[(de.model == model) & (de.knob == knob)]        # ladder order
            if dk.empty:
                continue
            ls = styles[[k for m, k in knobs if m == model].index(knob) % len(styles)]
            bt = dk.sort_values("seconds")
            row[1].plot(bt.seconds, bt.tv_max, ls, marker="o", color=colors.get(model),
                        label=f"{model}: {knob}")
            for x, y, v in zip(dk.seconds, dk.tv_max, dk.value):
                row[1].annotate(f"{v:g}", (x, y), fontsize=7, xytext=(3, 3),
                                textcoords="offset points")
            pos = np.arange(len(dk))
            row[0].plot(pos, dk.tv_max, ls, marker="o", color=colors.get(model),
                        label=f"{model}: {knob} ({', '.join(f'{v:g}' for v in dk.value)})")
        floor = de.noise_floor.max()
        for ax in row:
            ax.axhline(0.05, color="k", lw=0.8, ls="--")
            ax.axhline(floor, color="0.5", lw=0.8, ls=":")
            ax.set_ylabel("max over angles of TV(model, twin)")
            ax.set_ylim(0, max(0.7, float(de.tv_max.max()) * 1.05))
        row[0].set_xlabel("rung of the ladder (coarse → fine; values in the legend)")
        row[1].set_xscale("log")
        row[1].set_xlabel("compute time for the three angles [s]")
        row[0].set_title(f"{env_name}: TV to the twin along each resolution ladder")
        row[1].set_title(f"{env_name}: TV against compute time\n(dashed: the 0.05 goal, "
                         f"dotted: twin noise floor)", fontsize=10)
        row[0].legend(fontsize=7)
    return save_figure(fig, out / "convergence.png", dpi=100)


@dataclass(frozen=True)
class Config(SweepOptions):
    """Parameters of one model_convergence run (``config.json`` minus the execution fields).

    Attributes
    ----------
    envs : tuple of str       environments
    twin_steps : int          twin steps per angle and seed (``--steps``)
    twin_burn_in : int        twin steps per robot before counting (``--burn-in``)
    quick : bool              the short ladder (QUICK_LADDER) at K = 72
    seed : int                root seed of the twin sweep and of the sampled predictions
    out : Path                output folder
    workers, dask_local, dask : the executor (see ``add_executor_args``)
    progress : bool           show progress bars
    """

    envs: tuple[str, ...] = ("lab", "complex")
    twin_steps: int = 2_000_000
    twin_burn_in: int = 20_000
    quick: bool = False
    seed: int = 0
    out: Path = Path("results") / NAME


def run(config: Config) -> Path:
    """Every rung of the ladder against the twin; writes convergence.csv/.png, config.json.

    Returns the output folder.
    """
    q = config.quick
    env_names = config.envs
    ladder = QUICK_LADDER if q else LADDER
    base_K = 72 if q else 360
    steps, burn_in = config.twin_steps, config.twin_burn_in
    out = output_dir(config.out)

    # every (env, K, h) the ladder needs, and the twin reference runs for it
    rungs = []
    for env_name in env_names:
        h0 = envs.load(env_name).cell_size
        for model, knob, values, fixed in ladder:
            for v in values:
                K = int(v) if knob == "orientations" else base_K
                h = float(v) if knob == "cell_size" else h0
                settings = dict(fixed)
                if knob not in CELL_KNOBS:
                    settings[knob] = v
                rungs.append((env_name, model, knob, v, K, h, settings))
    spaces = sorted({(r[0], r[4], r[5]) for r in rungs})
    trials = [{"env": e, "orientations": K, "cell_size": h, "policy": f"{int(a)}",
               "backend": "twin", "steps": steps, "robots": 200, "epoch": 1, "speed": 0.3,
               "replicate": rep, "burn_in": burn_in}
              for e, K, h in spaces for a in ANGLES for rep in (0, 1)]
    record = {"experiment": NAME, **recorded(config), "angles": list(ANGLES), "eps": EPS,
              "r": R, "ladder": [[m, k, list(v), f] for m, k, v, f in ladder]}
    runs = run_sweep(simulate, trials, config.seed, out / "twin", record,
                     make_executor(config), progress=config.progress, name="runs",
                     provenance=invocation(config.seed))
    hist = {}
    for r in runs.itertuples():
        hist[(r.env, int(r.orientations), float(r.cell_size), r.policy, int(r.replicate))] = \
            np.array(r.counts.split(), dtype=float)

    rows = []
    rng_root = np.random.SeedSequence(config.seed)
    from tqdm import tqdm
    for i, (env_name, model, knob, v, K, h, settings) in enumerate(
            tqdm(rungs, desc="predictions", disable=not config.progress)):
        cs = CellSpace(envs.load(env_name, cell_size=h, orientations=K))
        rng = np.random.default_rng(np.random.SeedSequence(rng_root.entropy, spawn_key=(i,)))
        t0 = time.perf_counter()
        qs = {f"{int(a)}": predict_q(cs, a, model, settings, rng) for a in ANGLES}
        secs = time.perf_counter() - t0
        row = {"env": env_name, "model": model, "knob": knob, "value": v, "orientations": K,
               "cell_size": h, "settings": str(settings), "seconds": secs}
        floors = []
        for a, qa in qs.items():
            h0, h1 = hist[(env_name, K, h, a, 0)], hist[(env_name, K, h, a, 1)]
            row[f"tv_{a}"] = tv_distance(qa, h0 + h1)
            floors.append(tv_distance(h0, h1))
        tvs = [row[f"tv_{a}"] for a in qs]
        row.update(tv_max=max(tvs), tv_mean=float(np.mean(tvs)), noise_floor=max(floors))
        rows.append(row)
    table = pd.DataFrame(rows)
    table.to_csv(out / "convergence.csv", index=False, float_format="%.5g")
    write_config(out, record)
    draw_figure(out)
    print(table.drop(columns=["settings"]).to_string(index=False,
                                                     float_format=lambda x: f"{x:.3g}"))
    print(f"wrote {out}")
    return out


def main(argv=None) -> int:
    """Parse the command line into a :class:`Config` and :func:`run` it (exit status)."""
    p = experiment_parser(NAME, __doc__.split("\n\n")[0])
    p.add_argument("--envs", default=None, help="comma-separated (default lab,complex)")
    p.add_argument("--steps", type=int, default=None,
                   help="twin steps per angle and seed (default 2e6; quick 2e5)")
    p.add_argument("--burn-in", type=int, default=None,
                   help="twin steps per robot before counting (default 20000; quick 2000)")
    add_executor_args(p)
    args = p.parse_args(argv)
    q = args.quick
    config = Config(
        envs=tuple((args.envs or ("lab" if q else "lab,complex")).split(",")),
        twin_steps=args.steps or (200_000 if q else 2_000_000),
        twin_burn_in=args.burn_in if args.burn_in is not None else (2000 if q else 20_000),
        quick=q, seed=args.seed, out=args.out, workers=args.workers,
        dask_local=args.dask_local, dask=args.dask, progress=not args.no_progress)
    run(config)
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
