"""``bouncesim show ENV``: one figure of a map with whatever the options name.

The map (walls, obstacles, the cell grid), optionally the cell ids, the start and goal poses,
a planned path (replayed on the step model, docs/model.md §7, §12), an executed trace (the CSV of
``run-plan --trace``) and a coverage heatmap (``coverage.csv`` of ``coverage --out``). PNG or
SVG by the suffix of ``--out``.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from envs import UserError
from planners.cells import CellSpace
from planners.plan import Plan

from .common import FIGURE_FORMATS, add_env_args, add_output, load_env, make_cells, warn
from .plan import parse_config

__all__ = ["FORMATS", "read_coverage", "read_plan", "read_trace", "register", "replay_plan",
           "run"]

FORMATS = FIGURE_FORMATS

DESCRIPTION = """\
Draw ENV's map and cell grid with, as the options ask: the cell ids (--ids: position id p in
each cell's corner, or --ids configurations: z = k*P + p around each centre towards heading
360 k/K), start and goal poses, a planned path (--plan: the JSON of `bouncesim plan --json`,
or a file holding an observation string, replayed on the step model from --start), the
executed trace of `run-plan --trace` over it, and a coverage heatmap (--coverage DIR: the
coverage.csv of `bouncesim coverage --out DIR`, series --series). Writes one PNG, SVG or PDF
(by the suffix; SVG and PDF are vector graphics). A figure with ids is made wide enough for
them to stay readable.
"""

EXAMPLES = """\
examples:
  bouncesim show lab --ids --out lab_ids.png
  bouncesim show lab --start 8 --goal 0 --out query.svg
  bouncesim plan lab --angles 90,135 --start 8 --goal 0 --json > plan.json
  bouncesim run-plan lab --angles 90,135 --start 8 --goal 0 --noise gauss:3 --trace run.csv
  bouncesim show lab --plan plan.json --trace run.csv --out plan_and_run.png
  bouncesim coverage lab --angles 90,135 --out cov/
  bouncesim show lab --coverage cov --series 135 --out coverage_135.png
"""


def register(sub) -> None:
    """Add the ``show`` sub-command to the CLI's sub-parsers."""
    p = sub.add_parser("show", help="draw a map with ids, poses, plans, traces or coverage",
                       description=DESCRIPTION, epilog=EXAMPLES,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    add_env_args(p)
    p.add_argument("--ids", nargs="?", const="positions",
                   choices=("positions", "configurations"), default=None,
                   help="write the cell ids: position ids p (default) or configuration ids "
                   "z = k*P + p")
    p.add_argument("--start", metavar="S", help="start: z or X,Y,DEG")
    p.add_argument("--goal", metavar="G", help="goal: z or X,Y,DEG")
    p.add_argument("--plan", type=Path, metavar="FILE",
                   help="a plan: the JSON line of `plan --json`, or an observation string "
                   "(then --start is needed)")
    p.add_argument("--trace", type=Path, metavar="CSV",
                   help="an executed run: the CSV of `run-plan --trace`")
    p.add_argument("--coverage", type=Path, metavar="DIR",
                   help="a coverage heatmap from DIR/coverage.csv (`coverage --out DIR`)")
    p.add_argument("--series", default="mix", metavar="NAME",
                   help="which coverage.csv series: mix (default), target, mix_epochs or a "
                   "bouncing angle")
    p.add_argument("--title", default=None, help="figure title (default: what is drawn)")
    add_output(p, "--out", required=True, metavar="FILE.png|.svg|.pdf", suffixes=FORMATS,
               help="the figure file (.png, or .svg or .pdf for vector graphics)")
    p.set_defaults(func=run)


# ----------------------------------------------------------------------------- readers
def replay_plan(cells: CellSpace, plan: Plan, start: int) -> list[int]:
    """Configuration indices z visited when ``plan`` runs on the step model from ``start``
    (docs/model.md §7, §12): a 0 steps forward, an angle needs a bump there and turns CCW.

    A 90° turn adds 2 orientations (K = 8), i.e. 2 P = 96 to z; a step west along lab's
    bottom row takes one from z:

    >>> import envs
    >>> replay_plan(CellSpace(envs.load("lab")), Plan.parse("90° 90° 00000000 90° 90°"), 8)
    [8, 104, 200, 199, 198, 197, 196, 195, 194, 193, 192, 288, 0]
    """
    z = int(start)
    path = [z]
    for i, label in enumerate(plan.labels):
        nxt = int(cells.forward[z])
        if label == 0:
            if nxt < 0:
                raise UserError(f"the plan does not fit the map: observation {i + 1} is a "
                                f"step but configuration {z} faces a wall.")
            z = nxt
        else:
            if nxt >= 0:
                raise UserError(f"the plan does not fit the map: observation {i + 1} is a "
                                f"bump but configuration {z} can step forward.")
            z = int(cells.rotate(z, float(label)))
        path.append(z)
    return path


def read_plan(path: Path, cells: CellSpace, start: int | None) -> tuple[int, int | None,
                                                                          list, str]:
    """(start, goal or None, path, plan text) of a ``plan --json`` line or of an observation
    string file (which needs ``start``). The path is the configurations z the step model
    visits, or for a plan that runs by its exact flights (the exact, reliable and feedback
    planners', ``"exact_flights": true``) its poses (x, y, heading).
    """
    try:
        text = Path(path).read_text().strip()
    except FileNotFoundError:
        raise UserError(f"no plan file at {path}.") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise UserError(f"cannot read the plan file {path} ({exc}).") from None
    if text.startswith("{"):
        lines = [ln for ln in text.splitlines() if ln.strip()]
        if len(lines) != 1:
            raise UserError(f"{path} holds {len(lines)} plans; give a file with one.")
        try:
            obj = json.loads(lines[0])
        except json.JSONDecodeError:
            raise UserError(f"{path} is not the JSON of `bouncesim plan --json`.") from None
        if not isinstance(obj, dict) or not {"start", "goal", "plan"} <= set(obj):
            raise UserError(f"{path} lacks the start, goal and plan of `plan --json`.")
        if obj["plan"] is None:
            raise UserError(f"{path} holds no plan (its query had no path).")
        s, g = obj["start"], obj["goal"]
        if not all(isinstance(v, int) and 0 <= v < cells.N for v in (s, g)):
            raise UserError(f"{path} was written for another map: its start or goal is not "
                            f"a configuration 0 to {cells.N - 1}.")
        if start is not None:
            raise UserError("--plan with a JSON plan brings its start and goal; drop --start "
                            "and --goal.")
        plan = Plan.from_json(obj)
        if plan.is_exact:                  # it runs by its angles: draw its exact poses
            return s, g, _exact_poses(obj, cells, path), str(plan)
        plan = Plan.parse(" ".join(str(v) for v in obj["plan"]) or "")
        z = replay_plan(cells, plan, s)
        if z[-1] != g:
            raise UserError(f"{path} does not fit this map: its plan ends in configuration "
                            f"{z[-1]}, not at its goal {g}.")
        return s, g, z, str(plan)
    if start is None:
        raise UserError("--plan with an observation string needs --start.")
    plan = Plan.parse(text)
    return start, None, replay_plan(cells, plan, start), str(plan)


def _exact_poses(obj: dict, cells: CellSpace, path: Path) -> list:
    """The poses of an exact plan's JSON, checked against the map: they start at the start
    configuration's pose and lie in the room.
    """
    poses = obj.get("poses") or obj.get("path")      # "path": files before the one Route
    try:
        pts = np.asarray(poses, dtype=float)
    except (TypeError, ValueError):
        pts = np.empty((0, 0))
    if pts.ndim != 2 or pts.shape[1] != 3 or len(pts) < 2 or not np.isfinite(pts).all():
        raise UserError(f"{path} lacks the exact poses of `plan --planner exact --json`.")
    x0, y0, x1, y1 = cells.env.bounds
    inside = ((pts[:, 0] >= x0 - 1e-6) & (pts[:, 0] <= x1 + 1e-6)
              & (pts[:, 1] >= y0 - 1e-6) & (pts[:, 1] <= y1 + 1e-6))
    if not np.allclose(pts[0, :2], cells.pose(obj["start"])[:2], atol=1e-6) or not inside.all():
        raise UserError(f"{path} was written for another map: its poses do not start at its "
                        "start configuration or leave the room.")
    return pts.tolist()


def read_trace(path: Path):
    """The trace CSV of ``run-plan --trace`` as a DataFrame (t, x, y, heading, event)."""
    import pandas as pd
    try:
        df = pd.read_csv(path)
    except FileNotFoundError:
        raise UserError(f"no trace file at {path}.") from None
    except (OSError, UnicodeDecodeError, pd.errors.ParserError,
            pd.errors.EmptyDataError) as exc:
        raise UserError(f"cannot read the trace {path} ({str(exc).strip()}).") from None
    need = {"t", "x", "y", "heading", "event"}
    if not need <= set(df.columns):
        raise UserError(f"{path} needs the columns t,x,y,heading,event of `run-plan --trace`.")
    if not (np.isfinite(pd.to_numeric(df["x"], errors="coerce"))
            & np.isfinite(pd.to_numeric(df["y"], errors="coerce"))).any():
        raise UserError(f"{path} has no poses to draw (a hardware run logs none).")
    return df


MAX_K_IDS = 8
"""``--ids configurations`` writes every configuration id up to this K (beyond it, the
position ids and the rule z = k·P + p)."""

MAX_IDS_WIDTH = 24.0
"""[in] the widest figure ``--ids`` makes to keep its ids readable; a map that would need a
wider one for its configuration ids gets its position ids and the rule z = k·P + p."""


def trace_outcome(trace) -> str | None:
    """How the traced run ended ("success: ..." or "failure: ..."), from its ``outcome`` row;
    None when the trace does not say (written before that row existed, or a run without a
    goal), so that nothing false is drawn.
    """
    rows = trace[trace["event"] == "outcome"]
    detail = None if rows.empty else rows["detail"].iloc[-1]
    if not isinstance(detail, str) or detail.split(":")[0] not in ("success", "failure"):
        return None
    return detail


def ids_kind(asked: str | None, cells: CellSpace, env, width: float, extra: float):
    """The ids ``--ids`` draws and the figure size [in]: configuration ids only while K ids
    fit around a cell (K <= :data:`MAX_K_IDS`) and the figure they need stays at most
    :data:`MAX_IDS_WIDTH` wide, else position ids (with a warning naming z = k·P + p).
    """
    from bouncesim.plots import ids_figsize, map_figsize
    if asked is None:
        return None, map_figsize(env, width=width, extra=extra)
    size = ids_figsize(env, cells, asked, width, extra)
    if asked == "configurations" and (cells.K > MAX_K_IDS or size[0] > MAX_IDS_WIDTH):
        why = (f"readable up to K = {MAX_K_IDS}; with K = {cells.K}" if cells.K > MAX_K_IDS
               else f"here they would need a figure {size[0]:.0f} in wide;")
        warn(f"--ids configurations writes K ids per cell, {why} the figure shows the "
             f"position ids p (z = k·{cells.P} + p for heading k·{cells.delta_deg:g}°).")
        return "positions", ids_figsize(env, cells, "positions", width, extra)
    return asked, size


def read_coverage(folder: Path, cells: CellSpace, series: str = "mix") -> np.ndarray:
    """Column q of ``folder/coverage.csv`` for one series, in position order p (P values)."""
    import pandas as pd
    path = Path(folder) / "coverage.csv"
    try:
        df = pd.read_csv(path, dtype={"angle": str})
    except FileNotFoundError:
        raise UserError(f"no coverage.csv in {folder} (write one with `bouncesim coverage "
                        f"--out {folder}`).") from None
    except (OSError, UnicodeDecodeError, pd.errors.ParserError,
            pd.errors.EmptyDataError) as exc:
        raise UserError(f"cannot read {path} ({str(exc).strip()}).") from None
    if not {"angle", "p", "i", "j", "q"} <= set(df.columns):
        raise UserError(f"{path} needs the columns angle,p,i,j,q of `bouncesim coverage`.")
    names = list(dict.fromkeys(df["angle"]))
    d = df[df["angle"] == str(series)].sort_values("p")
    if d.empty:
        raise UserError(f"{path} has no series {series!r}; it has {', '.join(names)}.")
    ij = cells.cells_ij
    if (len(d) != cells.P or not np.array_equal(d["p"].to_numpy(), np.arange(cells.P))
            or not np.array_equal(d[["i", "j"]].to_numpy(), ij)):
        raise UserError(f"{path} was written for another map or cell size ({len(d)} cells, "
                        f"this map has {cells.P}).")
    return d["q"].to_numpy(dtype=float)


# ----------------------------------------------------------------------------- figure
def build_figure(args, env, cells):
    """The figure of ``bouncesim show`` (not yet written)."""
    import matplotlib.pyplot as plt

    from bouncesim.coverage_plots import heatmap
    from bouncesim.plots import (
        EXECUTED_COLOR,
        draw_cell_ids,
        draw_env,
        draw_pose,
        draw_route,
        draw_trace,
        fit_title,
        map_legend,
        route_label,
    )
    start = parse_config(args.start, cells, "start") if args.start is not None else None
    goal = parse_config(args.goal, cells, "goal") if args.goal is not None else None
    route = plan_text = None
    if args.plan is not None:
        start, plan_goal, route, plan_text = read_plan(args.plan, cells, start)
        if plan_goal is not None:                   # a JSON plan brings its own goal
            if goal is not None:
                raise UserError("--plan with a JSON plan brings its start and goal; drop "
                                "--start and --goal.")
            goal = plan_goal
    trace = read_trace(args.trace) if args.trace is not None else None
    q = read_coverage(args.coverage, cells, args.series) if args.coverage is not None else None

    kind, size = ids_kind(args.ids, cells, env, 7.5 if q is not None else 7.0,
                          1.6 if q is not None else 0.9)
    fig, ax = plt.subplots(figsize=size, layout="constrained")
    what = []
    if q is not None:
        series = args.series
        label = "coverage q [probability per cell]"
        heatmap(ax, cells, q, label=label)
        x0, y0, x1, y1 = env.bounds
        pad = 0.05
        ax.set_xlim(x0 - pad, x1 + pad)
        ax.set_ylim(y0 - pad, y1 + pad)
        what.append(f"coverage ({series}{'°' if _is_number(series) else ''})")
    else:
        draw_env(ax, env, cells)
    if kind is not None:                    # drawn last: their font follows the layout
        what.append("position ids p" + (f" (z = k·{cells.P} + p)" if args.ids != kind else "")
                    if kind == "positions" else f"configuration ids z = k·{cells.P} + p "
                    f"(towards heading k·{cells.delta_deg:g}°)")
    if route is not None:
        draw_route(ax, cells, route, label=route_label(route), markers=False)
        what.append(f"plan {plan_text}")
    if trace is not None:
        outcome = trace_outcome(trace)
        draw_trace(trace, ax=ax, legend=False, color=EXECUTED_COLOR,
                   label="executed" + (f" ({outcome.split(':')[0]})" if outcome else ""),
                   markers=start is None and goal is None)
        what.append("executed trace" + (f" ({outcome})" if outcome else ""))
    if start is not None:
        draw_pose(ax, cells.pose(start), "start", label=f"start (z = {start})")
    if goal is not None:
        draw_pose(ax, cells.pose(goal), "goal", label=f"goal (z = {goal})")
    elif route is not None:
        draw_pose(ax, cells.pose(route[-1]), "goal", label=f"plan end (z = {route[-1]})")
    title = args.title if args.title is not None else (
        f"{env.name}: P = {cells.P} cells of {cells.h:g} m, K = {cells.K} "
        f"({cells.delta_deg:g}° steps)" + ("; " + "; ".join(what) if what else ""))
    if title:
        fit_title(ax, title, fontsize=10)
    if ax.get_legend_handles_labels()[0]:
        map_legend(ax)
    if kind is not None:
        draw_cell_ids(ax, cells, kind, halo=q is not None)
    return fig


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def run(args) -> int:
    """Run ``bouncesim show``: check the output, draw, write; exit status."""
    from bouncesim.plots import save_figure
    out = args.out                          # a .png/.svg path checked before the work
    if args.series != "mix" and args.coverage is None:
        raise UserError("--series needs --coverage DIR.")
    env = load_env(args)
    cells = make_cells(args, env)
    fig = build_figure(args, env, cells)
    save_figure(fig, out, dpi=150)
    print(f"wrote {out}")
    return 0
