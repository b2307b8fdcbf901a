"""Figures shared by the CLI, the experiments and notebooks (matplotlib).

Nothing here chooses a backend: in a notebook figures show inline, and without a display
matplotlib falls back to Agg by itself. Scripts that only write files may call
``matplotlib.use("Agg")`` in their ``main``.

- :func:`draw_env`: the map (walls, obstacles, optionally the cell grid); the one map-drawing
  helper, also behind :func:`bouncesim.coverage_plots.draw_map`;
- :func:`draw_route`: a planned route through configuration cells;
- :func:`draw_trace`: an executed run's path, bumps and turns from its :class:`Trace`;
- :func:`angle_use_bars`, :func:`save_figure`.

Examples
--------
>>> import envs
>>> from bouncesim.runs.trace import Trace
>>> tr = Trace()
>>> tr.add(0.0, (0.17, 0.17, 0.0), "start")
>>> tr.add(1.7, (2.89, 0.17, 0.0), "bump", "left+right")
>>> ax = draw_trace(tr, envs.load("lab"), goal=(2.89, 0.17, 90.0))
>>> [t.get_text() for t in ax.get_legend().get_texts()]
['executed', 'bump', 'start', 'goal']
>>> plt.close(ax.figure)
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.patches import FancyArrow
from matplotlib.patches import Polygon as MplPolygon

__all__ = ["angle_use_bars", "draw_env", "draw_route", "draw_trace", "save_figure"]


def save_figure(fig: Figure, path: str | Path, dpi: int = 120) -> Path:
    """Lay out, write and close a figure; returns the path."""
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=dpi)
    plt.close(fig)
    return path


def angle_use_bars(hist: Any, path: str | Path, title: str = "") -> None:
    """Write a bar chart of the number of plans by distinct angles used.

    ``hist`` has columns ``angles_used`` and ``plans`` (a DataFrame or a dict of lists).
    """
    fig, ax = plt.subplots(figsize=(5, 3.4))
    ax.bar(hist["angles_used"], hist["plans"], color="#4477aa")
    for x, y in zip(hist["angles_used"], hist["plans"]):
        ax.annotate(f"{y}", (x, y), ha="center", va="bottom", fontsize=8)
    ax.set_xlabel("distinct bouncing angles in the plan")
    ax.set_ylabel("number of (start, goal) pairs")
    ax.set_xticks(list(hist["angles_used"]))
    ax.set_title(title, fontsize=9)
    save_figure(fig, path)


def draw_env(ax: Axes, env: Any, cells: Any = None, grid: bool = True, *,
             style: str = "filled", color: str = "black", lw: float = 2.0,
             pad: float = 0.05) -> None:
    """Draw the walls, obstacles and (optionally) the free cells of an environment on ``ax``.

    Parameters
    ----------
    ax : matplotlib Axes
    env : envs.Environment
    cells : planners.cells.CellSpace, optional
        With ``grid``, its free cells are outlined in light grey.
    style : {"filled", "outline"}
        ``filled``: a white room with hatched brown obstacles (route and trace figures);
        ``outline``: lines only, obstacles filled grey above the layers below (heatmaps).
    color, lw : str, float
        Wall colour and line width [pt] (obstacles ``outline`` get ``0.8 lw``).
    pad : float
        Margin around the room's bounding box [m].
    """
    if style == "filled":
        ax.add_patch(MplPolygon(np.asarray(env.boundary.exterior.coords), closed=True,
                                facecolor="white", edgecolor=color, lw=lw))
        for ob in env.obstacles:
            ax.add_patch(MplPolygon(np.asarray(ob.exterior.coords), closed=True,
                                    facecolor="#b5651d", edgecolor=color, lw=lw / 2,
                                    hatch="///"))
    elif style == "outline":
        x, y = env.boundary.exterior.xy
        ax.plot(x, y, color=color, lw=lw)
        for ob in env.obstacles:
            ox, oy = ob.exterior.xy
            ax.fill(ox, oy, color="0.55", zorder=3)
            ax.plot(ox, oy, color=color, lw=lw * 0.8, zorder=4)
    else:
        raise ValueError(f"unknown map style {style!r}; use 'filled' or 'outline'.")
    if cells is not None and grid:
        h = cells.h
        for (x, y) in cells.centres:
            ax.add_patch(plt.Rectangle((x - h / 2, y - h / 2), h, h, fill=False,
                                       edgecolor="#cccccc", lw=0.5))
    x0, y0, x1, y1 = env.bounds
    ax.set_xlim(x0 - pad, x1 + pad)
    ax.set_ylim(y0 - pad, y1 + pad)
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")


def draw_route(ax: Axes, cells: Any, path: Sequence[int], color: str = "#1f77b4",
               label: str | None = None) -> None:
    """Draw a route through configuration cells: centres joined, an arrow per heading.

    The start is marked red and the goal green; ``path`` holds configuration indices z
    (e.g. :attr:`planners.navigation.Route.path`).
    """
    pts = np.array([cells.pose(z) for z in path])
    ax.plot(pts[:, 0], pts[:, 1], "-", color=color, lw=2, alpha=0.8, label=label)
    L = 0.35 * cells.h
    for x, y, deg in pts:
        t = np.radians(deg)
        ax.add_patch(FancyArrow(x, y, L * np.cos(t), L * np.sin(t), width=0.01,
                                head_width=0.05, color=color, alpha=0.6,
                                length_includes_head=True))
    for (x, y, deg), c in ((pts[0], "red"), (pts[-1], "green")):
        t = np.radians(deg)
        ax.plot([x], [y], "o", color=c, ms=9)
        ax.add_patch(FancyArrow(x, y, 1.2 * L * np.cos(t), 1.2 * L * np.sin(t), width=0.02,
                                head_width=0.08, color=c, length_includes_head=True))


def _trace_columns(trace: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(x [m], y [m], heading [deg], event) arrays of a Trace, a run, or a trace DataFrame."""
    trace = getattr(trace, "trace", trace)          # a PlanRun or MixRun: its trace
    if hasattr(trace, "rows"):
        rows = trace.rows
        x = np.array([r.x for r in rows], dtype=float)
        y = np.array([r.y for r in rows], dtype=float)
        h = np.array([r.heading for r in rows], dtype=float)
        ev = np.array([r.event for r in rows], dtype=object)
    else:                                             # Trace.to_frame() or a read CSV
        x, y = np.asarray(trace["x"], dtype=float), np.asarray(trace["y"], dtype=float)
        h = np.asarray(trace["heading"], dtype=float)
        ev = np.asarray(trace["event"], dtype=object)
    return x, y, h, ev


def draw_trace(trace: Any, env: Any = None, ax: Axes | None = None, *,
               goal: Sequence[float] | None = None, cells: Any = None,
               color: str = "#1f77b4", label: str = "executed", events: bool = True,
               legend: bool = True) -> Axes:
    """Draw an executed run's path on the map: poses joined, bumps and turns, start and goal.

    Parameters
    ----------
    trace : Trace, PlanRun, MixRun or DataFrame
        The run's :class:`bouncesim.runs.trace.Trace` (a run record's ``.trace`` is taken;
        ``Trace.to_frame()`` or its CSV read back also work). Rows without a pose (hardware)
        are skipped.
    env : envs.Environment, optional
        Draws the map first (:func:`draw_env`); without it only the path is drawn.
    ax : matplotlib Axes, optional
        Default: a new figure's axes.
    goal : (x [m], y [m]) or (x, y, heading [deg]), optional
        Goal marker (a green star and, with a heading, an arrow); for a plan run pass
        ``run.goal_pose``. Without it the final pose is marked ``end``.
    cells : planners.cells.CellSpace, optional
        Outlines the free cells under the map.
    color, label : str
        Path colour and its legend entry.
    events : bool
        Mark bumps (crosses) and turns (small dots).
    legend : bool
        Add a legend (path, bump, turn, start, goal or end).

    Returns
    -------
    matplotlib Axes
    """
    if ax is None:
        _, ax = plt.subplots(figsize=(6, 4.5))
    if env is not None:
        draw_env(ax, env, cells, grid=cells is not None)
    x, y, h, ev = _trace_columns(trace)
    ok = np.isfinite(x) & np.isfinite(y)
    x, y, h, ev = x[ok], y[ok], h[ok], ev[ok]
    if len(x) == 0:
        raise ValueError("the trace has no poses to draw (a hardware run logs none).")
    ax.plot(x, y, "-", color=color, lw=1.6, alpha=0.85, label=label, zorder=5)
    if events:
        for kind, marker, ms, name in (("bump", "x", 7, "bump"), ("turn", ".", 5, "turn")):
            sel = ev == kind
            if sel.any():
                ax.plot(x[sel], y[sel], marker, color="black" if kind == "bump" else color,
                        ms=ms, ls="none", label=name, zorder=6)
    L = 0.12 * max(np.ptp(ax.get_xlim()), np.ptp(ax.get_ylim())) / 2
    ax.plot([x[0]], [y[0]], "o", color="red", ms=9, label="start", zorder=7)
    if np.isfinite(h[0]):
        _arrow(ax, x[0], y[0], h[0], L, "red")
    if goal is not None:
        ax.plot([goal[0]], [goal[1]], "*", color="green", ms=14, label="goal", zorder=7)
        if len(goal) > 2 and goal[2] is not None and math.isfinite(goal[2]):
            _arrow(ax, goal[0], goal[1], goal[2], L, "green")
    else:
        ax.plot([x[-1]], [y[-1]], "s", color="green", ms=8, label="end", zorder=7)
    if legend:
        ax.legend(fontsize=7, loc="best")
    return ax


def _arrow(ax: Axes, x: float, y: float, deg: float, length: float, color: str) -> None:
    t = math.radians(deg)
    ax.add_patch(FancyArrow(x, y, length * math.cos(t), length * math.sin(t), width=0.015,
                            head_width=0.07, color=color, length_includes_head=True,
                            zorder=7))
