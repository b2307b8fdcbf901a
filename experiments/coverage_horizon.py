"""Coverage over a horizon on a two-room office: how long until the limit means something.

The two-room map (4.08 m × 2.72 m, a partition with a door ``door`` wide, one pillar per room;
:func:`two_room`) with Φ = {30°, 75°, 315°}, ε = 5°, r = 0.8. For every angle the event model's
expected coverage of the first T steps from the uniform start (docs/model.md §20) is computed on
a geometric grid of T in one pass, with its TV to the angle's limit (docs/model.md §16, §17) and
``steps_to_limit`` (the first grid T within TV 0.05). The kinematic twin, started uniformly and
run for T steps without burn-in, gives Monte-Carlo points at a few T (two seeds each).

Outputs (``--out``, default results/coverage_horizon/): ``horizon.csv`` (angle, T, left-room
share, TV to the limit, source = model | limit | twin, seed), ``steps_to_limit.csv``,
``config.json`` and ``coverage_horizon.png`` (drawn from the CSVs alone).

``--quick``: T up to 2·10^4, twin points at T = 100 and 1000 only, smaller batches.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from bouncesim.robots.kinematic import KinematicBatch
from bouncesim.robots.noise import SteppedNoise
from envs import Environment
from experiments.common import experiment_parser, output_dir, recorded, write_config
from planners.cells import CellSpace
from planners.coverage import Horizon, TurnNoise, model_for
from planners.coverage.horizon import LIMIT_TV, grid
from planners.metrics import tv_distance

__all__ = ["Config", "draw_figure", "main", "run", "two_room", "left_cells"]

NAME = "coverage_horizon"
ANGLES = (30.0, 75.0, 315.0)
EPS, R = 5.0, 0.8
WALL_X = (2.04, 2.38)          # the partition [m]
DOOR_Y = 1.19                  # door centre [m] (the middle of cell row 3)


def two_room(door: float = 0.34, orientations: int = 360) -> Environment:
    """The two-room office with a door ``door`` [m] wide (0.34 m: exactly one robot).

    4.08 m × 2.72 m (12 × 8 cells of 0.34 m, robot radius 0.17 m), a partition at
    x = 2.04–2.38 m with the door centred at y = 1.19 m, one 0.34 m pillar per room.
    ``door = 0.34`` is ``experiments/maps/two_room.json``.
    """
    if not 0 < door < 2.72:
        raise ValueError(f"the door must be between 0 and 2.72 m wide, got {door}.")
    # rounded: 1.19 + 0.17 is 1.3599999999999999, 1e-16 narrower than the drawn door, and a
    # one-robot door is a knife edge for the C-space (docs/readme_horizon.md)
    lo, hi = round(DOOR_Y - door / 2, 9), round(DOOR_Y + door / 2, 9)
    x0, x1 = WALL_X
    obs = [[[x0, hi], [x1, hi], [x1, 2.72], [x0, 2.72]],
           [[0.68, 1.70], [1.02, 1.70], [1.02, 2.04], [0.68, 2.04]],
           [[3.06, 0.68], [3.40, 0.68], [3.40, 1.02], [3.06, 1.02]]]
    if lo > 0:
        obs.insert(0, [[x0, 0], [x1, 0], [x1, lo], [x0, lo]])
    return Environment.from_dict({
        "name": f"two_room_door_{door:g}", "boundary": [[0, 0], [4.08, 0], [4.08, 2.72],
                                                         [0, 2.72]],
        "obstacles": obs, "robot_radius": 0.17,
        "discretization": {"cell_size": 0.34, "orientations": int(orientations)}})


def left_cells(cs: CellSpace) -> np.ndarray:
    """Boolean mask of the position cells of the left room (centre west of the partition)."""
    return cs.centres[:, 0] < WALL_X[0]


@dataclass(frozen=True)
class Config:
    """Parameters of one coverage_horizon run.

    Attributes
    ----------
    door : float             door width [m]
    orientations : int       K
    cap : int                largest horizon of the grid [steps]
    twin_horizons : tuple    T of the twin's Monte-Carlo points
    twin_steps : int         robot-steps per twin point and seed (robots = twin_steps // T)
    quick, seed, out
    """

    door: float = 0.34
    orientations: int = 72
    cap: int = 200_000
    twin_horizons: tuple = (100, 1000, 10_000)
    twin_steps: int = 400_000
    quick: bool = False
    seed: int = 0
    out: Path = Path("results") / NAME


def run(config: Config) -> Path:
    """Horizon coverage per angle (model), limits, twin points; writes CSVs, figure, config."""
    out = output_dir(config.out)
    env = two_room(config.door, config.orientations)
    cs = CellSpace(env)
    left = left_cells(cs)
    noise = TurnNoise(EPS, R)
    model = model_for(cs, "event")
    t0 = time.perf_counter()
    hz = Horizon(model)
    rows, stl = [], []
    for a in ANGLES:
        lim = model.analyse(a, noise).q
        rows.append({"angle": int(a), "T": np.nan, "left_share": float(lim[left].sum()),
                     "tv_to_limit": 0.0, "source": "limit", "seed": -1})
        first = None
        t1 = time.perf_counter()
        for T, counts, _ in hz.run([a], grid(config.cap), noise=noise):
            q = counts / counts.sum()
            tv = tv_distance(q, lim)
            if first is None and tv <= LIMIT_TV:
                first = T
            rows.append({"angle": int(a), "T": T, "left_share": float(q[left].sum()),
                         "tv_to_limit": tv, "source": "model", "seed": -1})
        stl.append({"angle": int(a), "steps_to_limit": first, "cap": config.cap,
                    "seconds": time.perf_counter() - t1})
        for T in config.twin_horizons:
            for s in (0, 1):
                rng = np.random.default_rng([config.seed, int(a), T, s])
                batch = KinematicBatch(env, max(1, config.twin_steps // T), rng, cells=cs)
                res = batch.run(a, T, noise=SteppedNoise(EPS, R, cs.delta_deg))
                qh = res.counts / res.counts.sum()
                rows.append({"angle": int(a), "T": T, "left_share": float(qh[left].sum()),
                             "tv_to_limit": tv_distance(qh, lim), "source": "twin", "seed": s})
    df = pd.DataFrame(rows)
    df.to_csv(out / "horizon.csv", index=False, float_format="%.6g")
    pd.DataFrame(stl).to_csv(out / "steps_to_limit.csv", index=False)
    write_config(out, {"experiment": NAME, **recorded(config), "angles": list(ANGLES),
                       "eps": EPS, "r": R, "model": "event",
                       "seconds": time.perf_counter() - t0})
    draw_figure(out)
    print(pd.DataFrame(stl).to_string(index=False))
    print(f"wrote {out}")
    return out


def draw_figure(out: Path) -> Path:
    """coverage_horizon.png from horizon.csv and steps_to_limit.csv."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from bouncesim.plots import save_figure

    out = Path(out)
    df = pd.read_csv(out / "horizon.csv")
    stl = pd.read_csv(out / "steps_to_limit.csv").set_index("angle")
    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(12, 4.4))
    for i, a in enumerate(dict.fromkeys(df.angle)):
        c = f"C{i}"
        d = df[df.angle == a]
        mod, lim, tw = (d[d.source == s] for s in ("model", "limit", "twin"))
        ax.plot(mod["T"], mod.left_share, color=c, label=f"{a}°: model, first T steps")
        ax.axhline(float(lim.left_share.iloc[0]), color=c, ls="--", lw=1.2,
                   label=f"{a}°: limit")
        ax.plot(tw["T"], tw.left_share, "o", color=c, mfc="none", ms=6,
                label=f"{a}°: twin (2 seeds)")
        ax2.loglog(mod["T"], mod.tv_to_limit.clip(lower=1e-4), color=c, label=f"{a}°: model")
        ax2.loglog(tw["T"], tw.tv_to_limit.clip(lower=1e-4), "o", color=c, mfc="none", ms=6)
        s = stl.loc[a, "steps_to_limit"]
        if pd.notna(s):
            ax2.axvline(float(s), color=c, ls=":", lw=1)
    ax.set_xscale("log")
    ax.set_xlabel("horizon T [steps] (1 step ≈ 1 s at 0.34 m/s)")
    ax.set_ylabel("share of the first T steps in the left room")
    ax.set_ylim(-0.02, 1.05)
    ax.set_title("two-room office, door one robot wide: coverage against T")
    ax.legend(fontsize=7, ncol=3, loc="lower center")
    ax2.axhline(LIMIT_TV, color="k", ls="--", lw=1, label=f"TV {LIMIT_TV} (steps_to_limit)")
    ax2.set_xlabel("horizon T [steps]")
    ax2.set_ylabel("TV(q_T, limit)")
    ax2.set_title("distance to the limit (dotted: steps_to_limit)")
    ax2.legend(fontsize=7)
    return save_figure(fig, out / "coverage_horizon.png", dpi=110)


def main(argv=None) -> int:
    """Parse the command line into a :class:`Config` and :func:`run` it (exit status)."""
    p = experiment_parser(NAME, __doc__.split("\n\n")[0])
    p.add_argument("--door", type=float, default=0.34, help="door width [m] (default 0.34)")
    p.add_argument("--orientations", type=int, default=None,
                   help="K (default 72; a multiple of 72: the angles and eps need 5°)")
    p.add_argument("--cap", type=int, default=None,
                   help="largest horizon [steps] (default 2e5; quick 2e4)")
    args = p.parse_args(argv)
    q = args.quick
    config = Config(door=args.door, orientations=args.orientations or 72,
                    cap=args.cap or (20_000 if q else 200_000),
                    twin_horizons=(100, 1000) if q else (100, 1000, 10_000),
                    twin_steps=100_000 if q else 400_000, quick=q, seed=args.seed,
                    out=args.out)
    run(config)
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
