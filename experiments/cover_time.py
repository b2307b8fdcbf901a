"""Coverage-time metrics (docs/model.md §20a): the event model's prediction against the
kinematic twin, for one robot and teams of four.

On maps nobody tuned for (a two-room map of about 200 cells drawn here, a random rectilinear
room and a random room with slanted walls and pillars from :mod:`envs.generated`) at K = 360,
ε = 5°, r = 0.8 and the angles 30°, 75° and 315°: the predicted mean covered fraction C(t)
(sampled from the model's chain) against the twin's, at t = 1000, 5000 and 20000 steps, and
T_90. Writes cover_time.csv (one row per map, angle, team size and t), cover_cells.csv (per
cell, the share of runs that have visited it by each t, model and twin: where the two
disagree), config.json and cover_time.png (C(t), model against twin).

    python -m experiments.cover_time            # the full run (about five minutes)
    python -m experiments.cover_time --quick    # a small map, K = 72, short horizon
    python -m experiments.cover_time --bin-length 0.01   # the model with 1 cm contact bins
    python -m experiments.cover_time --twin-runs 2000    # T_90 of rarely covering records
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from bouncesim.runs.cover import twin_cover
from envs.generated import big_two_room, random_rectilinear_room, slanted_room
from planners.cells import CellSpace
from planners.coverage import TurnNoise, model_for
from planners.coverage.cover_time import coverage_metrics, metric_times, visited_by

from .common import experiment_parser, output_dir, recorded, write_config

NAME = "cover_time"
ANGLES = (30.0, 75.0, 315.0)
EPS, R = 5.0, 0.8


@dataclass(frozen=True)
class Config:
    """Parameters of one cover_time run.

    Attributes
    ----------
    orientations : int     K
    horizon : int          steps per robot
    times : tuple          the t compared
    rooms : int            random rectilinear rooms besides the two-room map
    slanted : int          random rooms with slanted walls and pillars off the grid
                           (:func:`envs.generated.slanted_room`, every pillar 2.2 r clear)
    model_runs : int       sampled runs (teams) of the model per record
    twin_runs : int        simulated teams per angle and team size
    bin_length : float     [m] the event model's contact bins (its default 0.03; 0.01 closes
                           the two-room door's gap, docs/readme_coverage.md)
    quick, seed, out
    """

    orientations: int = 360
    horizon: int = 20_000
    times: tuple = (1000, 5000, 20_000)
    rooms: int = 1
    slanted: int = 1
    model_runs: int = 2000
    twin_runs: int = 200
    bin_length: float = 0.03
    quick: bool = False
    seed: int = 0
    out: Path = Path("results") / NAME


def run(config: Config) -> Path:
    """Model against twin on every map, angle and team size; writes CSV, figure, config."""
    out = output_dir(config.out)
    rng = np.random.default_rng(config.seed)
    maps = [big_two_room(config.orientations)] + [
        random_rectilinear_room(rng, config.orientations, name=f"rect{i}")
        for i in range(config.rooms)] + [
        slanted_room(rng, config.orientations, name=f"slanted{i}")
        for i in range(config.slanted)]
    noise = TurnNoise(EPS, R)
    rows, curves, per_cell = [], [], []
    t0 = time.perf_counter()
    for env in maps:
        cs = CellSpace(env)
        model = model_for(cs, "event", {"bin_length": config.bin_length})
        t1 = time.perf_counter()
        times = sorted(set(metric_times(config.horizon)) | set(config.times))
        pred = coverage_metrics(model, ANGLES, noise, robots=[1, 4], horizon=config.horizon,
                                runs=config.model_runs, rng=rng, exact=False,
                                times=times)
        model_s = time.perf_counter() - t1
        for m in pred:
            sim = twin_cover(env, m.angle, noise, robots=m.robots, runs=config.twin_runs,
                             horizon=config.horizon, times=m.t, rng=rng, cells=cs)
            for t in config.times:
                i = list(m.t).index(t) if t in m.t else None
                if i is None:
                    continue
                tw_T, tw_nr = sim.T_mean(0.9)
                rows.append({"map": env.name, "P": cs.P, "angle": int(m.angle),
                             "robots": m.robots, "t": t, "model": m.covered_mean[i],
                             "model_se": m.covered_se[i], "twin": sim.covered_mean[i],
                             "twin_se": sim.covered_se[i],
                             "diff": m.covered_mean[i] - sim.covered_mean[i],
                             "T90_model": m.T["0.9"]["mean"],
                             "T90_model_not_reached": m.T["0.9"]["not_reached"],
                             "T90_twin": tw_T, "T90_twin_not_reached": tw_nr,
                             "T90_model_se": m.T["0.9"].get("mean_se"),
                             "T90_twin_se": sim.T_mean_se(0.9),
                             "model_seconds_all": model_s, "twin_seconds": sim.seconds})
            sim_cells = visited_by(sim.first, m.t)
            for t in config.times:
                if t in m.t:
                    i = list(m.t).index(t)
                    per_cell.extend({"map": env.name, "angle": int(m.angle),
                                     "robots": m.robots, "t": t, "cell": p,
                                     "x": cs.centres[p][0], "y": cs.centres[p][1],
                                     "model": m.cell_visited[i, p], "twin": sim_cells[i, p]}
                                    for p in range(cs.P))
            for ti, cm, ct in zip(m.t, m.covered_mean, sim.covered_mean):
                curves.append({"map": env.name, "angle": int(m.angle), "robots": m.robots,
                               "t": int(ti), "model": cm, "twin": ct})
        print(pd.DataFrame([r for r in rows if r["map"] == env.name]).to_string(index=False))
    pd.DataFrame(rows).to_csv(out / "cover_time.csv", index=False, float_format="%.6g")
    pd.DataFrame(curves).to_csv(out / "cover_curves.csv", index=False, float_format="%.6g")
    cells = pd.DataFrame(per_cell)
    cells.to_csv(out / "cover_cells.csv", index=False, float_format="%.4g")
    worst = cells.assign(diff=cells.model - cells.twin).sort_values("diff").head(8)
    print("cells the model visits least often against the twin:")
    print(worst.to_string(index=False))
    write_config(out, {"experiment": NAME, **recorded(config), "angles": list(ANGLES),
                       "eps": EPS, "r": R, "model": "event",
                       "seconds": time.perf_counter() - t0})
    draw_figure(out)
    print(f"wrote {out}")
    return out


def draw_figure(out: Path) -> Path:
    """cover_time.png from cover_curves.csv: C(t) per map, angle and team, model and twin."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from bouncesim.plots import save_figure

    df = pd.read_csv(Path(out) / "cover_curves.csv")
    maps = list(dict.fromkeys(df["map"]))
    fig, axes = plt.subplots(1, len(maps), figsize=(6 * len(maps), 4.2), squeeze=False)
    for ax, name in zip(axes[0], maps):
        d = df[df["map"] == name]
        for i, (key, g) in enumerate(d.groupby(["angle", "robots"])):
            c = f"C{i}"
            team = f"{key[1]} robot" + ("s" if key[1] > 1 else "")
            ax.plot(g.t, g.model, color=c, label=f"{key[0]}°, {team}: model")
            ax.plot(g.t, g.twin, "o", color=c, mfc="none", ms=4, label="twin")
        ax.set_xscale("log")
        ax.set_xlabel("t [steps per robot]")
        ax.set_ylabel("mean covered fraction C(t)")
        ax.set_title(f"{name}: model (lines) against the twin (circles)")
        ax.legend(fontsize=6, ncol=2)
    return save_figure(fig, Path(out) / "cover_time.png", dpi=110)


def main(argv=None) -> int:
    """Parse the command line into a :class:`Config` and :func:`run` it (exit status)."""
    p = experiment_parser(NAME, __doc__.split("\n\n")[0])
    p.add_argument("--bin-length", type=float, default=0.03, metavar="M",
                   help="the event model's contact bin length [m] (default 0.03)")
    p.add_argument("--twin-runs", type=int, default=Config.twin_runs, metavar="N",
                   help=f"simulated teams per angle and team size (default "
                        f"{Config.twin_runs}); T_90 of a record that rarely reaches 90 %% "
                        "rests on the few runs that do")
    args = p.parse_args(argv)
    if not 0 < args.bin_length <= 0.2:
        p.error(f"--bin-length must lie in (0, 0.2] m, got {args.bin_length:g}")
    if args.twin_runs < 2:
        p.error(f"--twin-runs must be at least 2, got {args.twin_runs}")
    if args.quick:
        config = Config(orientations=72, horizon=2000, times=(100, 1000, 2000), rooms=0,
                        slanted=0, model_runs=300, twin_runs=30, quick=True, seed=args.seed,
                        out=args.out, bin_length=args.bin_length)
    else:
        config = Config(seed=args.seed, out=args.out, bin_length=args.bin_length,
                        twin_runs=args.twin_runs)
    run(config)
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
