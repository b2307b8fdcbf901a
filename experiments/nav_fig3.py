"""Fig. 3 of the paper in the `lab` environment: two shortest bouncing plans, drawn on the map,
then (when the physics backends are installed) executed in PyBullet and in the kinematic twin.

    python -m experiments.nav_fig3 [--quick] [--seed 0] [--out results/nav_fig3]

Paper ids are 1-based (id = z + 1): plan 1 goes from id 9 to id 1, plan 2 from id 104 to id 9.
"""

from __future__ import annotations

import sys
from dataclasses import asdict, dataclass
from pathlib import Path

import pandas as pd

import envs
from bouncesim.runs.options import parse_angles
from planners.cells import CellSpace
from planners.navigation import Navigator
from planners.plan import Plan

from .common import experiment_parser, output_dir, write_config

__all__ = ["PAPER_PLANS", "QUERIES", "Config", "main", "plan_routes", "run"]

QUERIES = [("plan 1", 9, 1), ("plan 2", 104, 9)]     # (label, paper start id, paper goal id)
PAPER_PLANS = {"plan 1": None,   # the paper prints no string for plan 1: it "uses only 90°"
               "plan 2": "000000 135° 135° 000000 135° 135° 00000 90°"}
PAPER_ANGLES = {"plan 1": {90}, "plan 2": {90, 135}}


@dataclass(frozen=True)
class Config:
    """Parameters of one nav_fig3 run (written to ``config.json``).

    Attributes
    ----------
    angles : tuple of float   bouncing angles Φ [deg]
    w1, w2 : float            roadmap weights: step or same-angle bump, angle change
    physics : bool            execute the plans (PyBullet when installed, and the twin)
    quick : bool              small execution budget (3 noisy runs at σ = 2° only)
    seed : int                root seed of the noisy executions
    out : Path                output folder
    """

    angles: tuple[float, ...] = (90.0, 135.0)
    w1: float = 1.0
    w2: float = 100.0
    physics: bool = True
    quick: bool = False
    seed: int = 0
    out: Path = Path("results") / "nav_fig3"


def plan_routes(angles, w1=1.0, w2=100.0):
    """Plan the paper's two Fig. 3 queries in ``lab``; returns (env, cells, nav, routes, table)."""
    env = envs.load("lab")
    cells = CellSpace(env)
    nav = Navigator(cells, angles, w1, w2)
    rows, routes = [], []
    for label, sid, gid in QUERIES:
        route = nav.plan(sid - 1, gid - 1)
        routes.append(route)
        ours = set(route.plan.angles) if route else None
        paper = PAPER_PLANS[label]
        rows.append({
            "plan": label, "start_id": sid, "goal_id": gid, "start_z": sid - 1,
            "goal_z": gid - 1, "start_pose": cells.pose(sid - 1),
            "goal_pose": cells.pose(gid - 1),
            "ours": str(route.plan) if route else None,
            "cost": route.cost if route else None,
            "steps": route.plan.steps if route else None,
            "bumps": route.plan.bumps if route else None,
            "angles_used": sorted(ours) if route else None,
            "paper": paper,
            "paper_angles": sorted(PAPER_ANGLES[label]),
            "paper_cost": _cost(Plan.parse(paper), w1, w2) if paper else None,
            "same_angles_as_paper": ours == PAPER_ANGLES[label] if route else False,
        })
    return env, cells, nav, routes, pd.DataFrame(rows)


def _cost(plan: Plan, w1: float, w2: float) -> float:
    cost, cur = 0.0, None
    for v in plan.labels:
        if v == 0:
            cost += w1
        else:
            cost += w1 if cur in (None, v) else w2
            cur = v
    return cost


def draw(env, cells, routes, table, path, executed=None) -> None:
    """Write the planned routes (and the noise-free executed paths) on the map to ``path``."""
    from bouncesim.plots import draw_env, draw_route, plt, save_figure
    fig, axes = plt.subplots(1, len(routes), figsize=(5.2 * len(routes), 4))
    for ax, route, (_, row) in zip(axes, routes, table.iterrows()):
        draw_env(ax, env, cells)
        if route is not None:
            draw_route(ax, cells, route.path, label="planned (cell centres)")
        if executed is not None:
            for (plan_label, backend), tr in executed.items():
                if plan_label == row["plan"]:
                    ax.plot(tr["x"], tr["y"], "--", lw=1.2,
                            label=f"executed ({backend})")
        ax.set_title(f"{row['plan']}: id {row['start_id']} → id {row['goal_id']}\n"
                     f"{row['ours']}", fontsize=9)
        ax.legend(fontsize=7, loc="upper right")
    save_figure(fig, path, dpi=130)


def run(config: Config) -> Path:
    """Plan (and execute) Fig. 3 and write plans.csv, runs, fig3_paths.png and config.json.

    Raises :class:`envs.UserError` for bad angles; returns the output folder.
    """
    env, cells, nav, routes, table = plan_routes(config.angles, config.w1, config.w2)
    out = output_dir(config.out)
    table.to_csv(out / "plans.csv", index=False)
    print(f"lab: P = {cells.P}, N = {cells.N}, "
          f"Φ = {', '.join(f'{a:g}°' for a in config.angles)}")
    for _, r in table.iterrows():
        print(f"{r['plan']} (id {r['start_id']} → id {r['goal_id']}):")
        print(f"   ours : {r['ours']}   (cost {r['cost']:g}, angles {r['angles_used']})")
        paper = r["paper"] if isinstance(r["paper"], str) else "(not printed)"
        print(f"   paper: {paper}   (angles {r['paper_angles']})"
              f"  -> same angle set: {'yes' if r['same_angles_as_paper'] else 'no'}")
    record = {"experiment": "nav_fig3", "env": "lab", **asdict(config)}
    executed = None
    if config.physics:
        try:
            from .nav_fig3_physics import execute_fig3
        except ImportError:
            execute_fig3 = None
        if execute_fig3 is not None:
            executed, runs_config = execute_fig3(env, cells, routes, table, config, out)
            record.update(runs_config)
    draw(env, cells, routes, table, out / "fig3_paths.png", executed)
    write_config(out, record)
    print(f"wrote {out}/plans.csv, fig3_paths.png, config.json")
    return out


def main(argv=None) -> int:
    """Parse the command line into a :class:`Config` and :func:`run` it (exit status)."""
    p = experiment_parser("nav_fig3", __doc__.splitlines()[0])
    p.add_argument("--angles", default="90,135",
                   help="bouncing angles [deg] (default 90,135: the angles of the paper's plans)")
    p.add_argument("--no-physics", action="store_true", help="plan only, skip execution")
    args = p.parse_args(argv)
    import matplotlib
    matplotlib.use("Agg")                      # this script writes files only
    try:
        config = Config(angles=tuple(parse_angles(args.angles)), physics=not args.no_physics,
                        quick=args.quick, seed=args.seed, out=args.out)
        run(config)
    except envs.UserError as exc:
        print(f"nav_fig3: error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
