"""Fig. 3 of the paper in the `lab` environment: two shortest bouncing plans, drawn on the map,
then (when the physics backends are installed) executed in PyBullet and in the kinematic twin.

    python -m experiments.nav_fig3 [--quick] [--seed 0] [--out results/nav_fig3]

Paper ids are 1-based (id = z + 1): plan 1 goes from id 9 to id 1, plan 2 from id 104 to id 9.
Writes ``plans.csv`` (the step plans, the paper's, and the exact planner's for the same
queries, docs/model.md §13), ``fig3_paths.png`` (the step plans and their noise-free
executions) and ``fig3_step_vs_exact.png`` (the paper's step plans beside the exact ones,
each replayed noise-free in the twin, plus one contrasting query on ``studio``).
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
from planners.navigation.exact import ExactNavigator
from planners.plan import Plan

from .common import experiment_parser, output_dir, run_main, write_config
from .compare import add_compare_arg

__all__ = ["CONTRAST", "PAPER_PLANS", "QUERIES", "Config", "draw_step_vs_exact",
           "exact_routes", "main", "plan_routes", "run", "step_vs_exact_rows"]

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


def exact_routes(cells, table, angles, w1=1.0, w2=100.0) -> list:
    """The exact planner's routes (docs/model.md §13) for the queries of ``table`` (None where
    it finds none); adds the columns ``exact`` (the plan with its flights), ``exact_cost``
    and ``exact_bumps`` to ``table``.
    """
    nav = ExactNavigator(cells, angles, w1, w2)
    routes = [nav.plan(int(r["start_z"]), int(r["goal_z"])) for _, r in table.iterrows()]
    table["exact"] = [r.plan.exact_text() if r else None for r in routes]
    table["exact_cost"] = [r.cost if r else None for r in routes]
    table["exact_bumps"] = [r.plan.bumps if r else None for r in routes]
    return routes


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
    """Write the planned routes (and the noise-free executed paths) on the map to ``path``.

    The plan is a wide pale band; PyBullet's path a solid line and the twin's a thin dashed
    one over it, so both show where they coincide with the plan and with each other; bumps
    are drawn above the start and goal markers (these runs bump where they start or end).
    The start and goal markers are the query's configurations at their cell centres.
    """
    from bouncesim.plots import draw_env, draw_pose, draw_route, map_legend, plt, save_figure
    fig, axes = plt.subplots(1, len(routes), figsize=(5.2 * len(routes), 4.3),
                             layout="constrained")
    styles = {"pybullet": ("#1f4e9c", "-", 3.0, "o"), "kinematic": ("#ff7f0e", "--", 1.3, "x")}
    for ax, route, (_, row) in zip(axes, routes, table.iterrows()):
        draw_env(ax, env, cells)
        if route is not None:       # wide and pale: the runs drawn over it stay visible
            draw_route(ax, cells, route.path, label="planned (cell centres)", color="#9ecae1",
                       lw=9, alpha=0.6, markers=False)
        draw_pose(ax, cells.pose(int(row["start_z"])), "start", label="start (cell centre)",
                  length=0.4 * cells.h)
        draw_pose(ax, cells.pose(int(row["goal_z"])), "goal", label="goal (cell centre)",
                  length=0.4 * cells.h)
        if executed is not None:
            for (plan_label, backend), tr in executed.items():
                if plan_label == row["plan"]:
                    colour, ls, lw, mark = styles.get(backend, ("#2ca02c", ":", 1.3, "+"))
                    bumps = tr[tr["event"] == "bump"] if "event" in tr else tr.iloc[:0]
                    ax.plot(tr["x"], tr["y"], ls=ls, color=colour, lw=lw, zorder=5,
                            label=f"executed ({backend})")
                    ax.plot(bumps["x"], bumps["y"], mark, color=colour, ms=8, mew=1.6,
                            mfc="none", ls="none", zorder=9, label=f"bumps ({backend})")
        ax.set_title(f"{row['plan']}: id {row['start_id']} → id {row['goal_id']}\n"
                     f"{row['ours']}", fontsize=9)
        map_legend(ax, ncol=3)
    save_figure(fig, path, dpi=130)


CONTRAST = ("studio", 670, 603)
"""A query on the non-rectilinear ``studio`` map (configurations z) where the two planners
differ: the first short one (2-3 bumps) of a seeded random search whose step plan misses
its goal in the noise-free twin (it ends outside the goal cell, 0.24 m from its centre)
and whose exact plan reaches it."""


def _replay(env, cells, route):
    """The noise-free twin's (success, trace frame) for a route (front-half bumper, §21)."""
    from bouncesim.robots import make_robot
    from bouncesim.runs.execute import execute
    run = execute(route.plan, make_robot("kinematic", env), start=route.start,
                  goal=route.goal, cells=cells)
    return bool(run.success), run.trace.to_frame()


def step_vs_exact_rows(env, cells, routes, exact, table, angles, w1=1.0, w2=100.0) -> list:
    """The rows of :func:`draw_step_vs_exact`: the Fig. 3 queries, then :data:`CONTRAST`."""
    rows = [(env, cells, f"{r['plan']} (id {r['start_id']} → id {r['goal_id']})", st, ex)
            for (_, r), st, ex in zip(table.iterrows(), routes, exact)]
    name, s, g = CONTRAST
    env2 = envs.load(name)
    cells2 = CellSpace(env2)
    rows.append((env2, cells2, f"{name}: {s} → {g}",
                 Navigator(cells2, angles, w1, w2).plan(s, g),
                 ExactNavigator(cells2, angles, w1, w2).plan(s, g)))
    return rows


def draw_step_vs_exact(rows, path) -> None:
    """Step plans (left: bumps at cell centres, the paper's model) beside exact plans (right:
    the exact bump poses), each with its noise-free twin run dashed; one row per
    (env, cells, title, step route, exact route) of ``rows``, to ``path``.
    """
    import textwrap

    from bouncesim.plots import draw_env, draw_pose, draw_route, map_legend, plt, save_figure
    fig, axes = plt.subplots(len(rows), 2, figsize=(10.4, 4.4 * len(rows)), squeeze=False,
                             layout="constrained")
    for row_axes, (env, cells, title, step, exact) in zip(axes, rows):
        for ax, r, what, colour in ((row_axes[0], step, "step model (paper)", "#777777"),
                                    (row_axes[1], exact, "exact planner", "#3b75af")):
            draw_env(ax, env, cells)
            if r is None:
                ax.set_title(f"{title}, {what}: no plan", fontsize=8)
                continue
            is_step = what.startswith("step")
            draw_route(ax, cells, r.path if is_step else r.poses, color=colour,
                       label="planned", markers=False, lw=5, alpha=0.45)
            ok, tr = _replay(env, cells, r)
            ax.plot(tr["x"], tr["y"], "--", color="#d62728", lw=1.1,
                    label=f"twin, noise-free: {'reached' if ok else 'missed'}")
            # the same start and goal configurations (their cell centres) in both panels
            draw_pose(ax, cells.pose(r.start), "start", label="start (cell centre)",
                      length=0.4 * cells.h)
            draw_pose(ax, cells.pose(r.goal), "goal", label="goal (cell centre)",
                      length=0.4 * cells.h)
            text = str(r.plan) if is_step else r.plan.exact_text(decimals=2)
            lines = [f"{title}, {what}, cost {r.cost:.4g}", *textwrap.wrap(text, 72)]
            ax.set_title("\n".join(lines), fontsize=8)
            map_legend(ax, fontsize=7)
    save_figure(fig, path, dpi=130)


def run(config: Config) -> Path:
    """Plan (and execute) Fig. 3 and write plans.csv, runs, fig3_paths.png and config.json.

    Raises :class:`envs.UserError` for bad angles; returns the output folder.
    """
    env, cells, nav, routes, table = plan_routes(config.angles, config.w1, config.w2)
    exact = exact_routes(cells, table, config.angles, config.w1, config.w2)
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
        print(f"   exact: {r['exact'] or '(none)'}   (cost {r['exact_cost']:.4g})")
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
    draw_step_vs_exact(step_vs_exact_rows(env, cells, routes, exact, table, config.angles,
                                          config.w1, config.w2),
                       out / "fig3_step_vs_exact.png")
    write_config(out, record)
    print(f"wrote {out}/plans.csv, fig3_paths.png, fig3_step_vs_exact.png, config.json")
    return out


def main(argv=None) -> int:
    """Parse the command line into a :class:`Config` and :func:`run` it (exit status)."""
    p = experiment_parser("nav_fig3", __doc__.splitlines()[0])
    add_compare_arg(p, "nav_fig3")
    p.add_argument("--angles", default="90,135",
                   help="bouncing angles [deg] (default 90,135: the angles of the paper's plans)")
    p.add_argument("--no-physics", action="store_true", help="plan only, skip execution")
    args = p.parse_args(argv)
    import matplotlib
    matplotlib.use("Agg")                      # this script writes files only
    return run_main("nav_fig3", lambda: Config(
        angles=tuple(parse_angles(args.angles)), physics=not args.no_physics,
        quick=args.quick, seed=args.seed, out=args.out), run, args.compare)


if __name__ == "__main__":
    sys.exit(main())
