"""Fig. 3 of the paper in the `lab` environment: two shortest bouncing plans, drawn on the map,
then (when the physics backends are installed) executed in PyBullet and in the kinematic twin.

    python -m experiments.nav_fig3 [--quick] [--seed 0] [--out results/nav_fig3]

Paper ids are 1-based (id = z + 1): plan 1 goes from id 9 to id 1, plan 2 from id 104 to id 9.
"""

from __future__ import annotations

import sys

import pandas as pd

import envs
from bouncesim.runs.options import parse_angles
from planners.cells import CellSpace
from planners.navigation import Navigator
from planners.plan import Plan

from .common import experiment_parser, output_dir, write_config

__all__ = ["PAPER_PLANS", "QUERIES", "main"]

QUERIES = [("plan 1", 9, 1), ("plan 2", 104, 9)]     # (label, paper start id, paper goal id)
PAPER_PLANS = {"plan 1": None,   # the paper prints no string for plan 1: it "uses only 90°"
               "plan 2": "000000 135° 135° 000000 135° 135° 00000 90°"}
PAPER_ANGLES = {"plan 1": {90}, "plan 2": {90, 135}}


def plan_routes(angles, w1=1.0, w2=100.0):
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


def main(argv=None) -> int:
    p = experiment_parser("nav_fig3", __doc__.splitlines()[0])
    p.add_argument("--angles", default="90,135",
                   help="bouncing angles [deg] (default 90,135: the angles of the paper's plans)")
    p.add_argument("--no-physics", action="store_true", help="plan only, skip execution")
    args = p.parse_args(argv)
    try:
        angles = parse_angles(args.angles)
        env, cells, nav, routes, table = plan_routes(angles)
    except envs.UserError as exc:
        print(f"nav_fig3: error: {exc}", file=sys.stderr)
        return 2
    out = output_dir(args.out)
    table.to_csv(out / "plans.csv", index=False)
    print(f"lab: P = {cells.P}, N = {cells.N}, Φ = {', '.join(f'{a:g}°' for a in angles)}")
    for _, r in table.iterrows():
        print(f"{r['plan']} (id {r['start_id']} → id {r['goal_id']}):")
        print(f"   ours : {r['ours']}   (cost {r['cost']:g}, angles {r['angles_used']})")
        paper = r["paper"] if isinstance(r["paper"], str) else "(not printed)"
        print(f"   paper: {paper}   (angles {r['paper_angles']})"
              f"  -> same angle set: {'yes' if r['same_angles_as_paper'] else 'no'}")
    config = {"experiment": "nav_fig3", "env": "lab", "angles": angles, "w1": 1.0,
              "w2": 100.0, "seed": args.seed, "quick": args.quick}
    executed = None
    if not args.no_physics:
        try:
            from .nav_fig3_physics import execute_fig3
        except ImportError:
            execute_fig3 = None
        if execute_fig3 is not None:
            executed, runs_config = execute_fig3(env, cells, routes, table, args, out)
            config.update(runs_config)
    draw(env, cells, routes, table, out / "fig3_paths.png", executed)
    write_config(out, config)
    print(f"wrote {out}/plans.csv, fig3_paths.png, config.json")
    return 0


if __name__ == "__main__":
    sys.exit(main())
