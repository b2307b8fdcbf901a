"""Figures shared by the CLI, the experiments and notebooks (matplotlib).

Nothing here chooses a backend: in a notebook figures show inline, and without a display
matplotlib falls back to Agg by itself. Scripts that only write files may call
``matplotlib.use("Agg")`` in their ``main``.

- :func:`draw_env`: the map (walls, obstacles, optionally the cell grid); the one map-drawing
  helper, also behind :func:`bouncesim.coverage_plots.draw_map`;
- :func:`draw_route`: a planned route through configuration cells;
- :func:`draw_trace`: an executed run's path, bumps and turns from its :class:`Trace`;
- :func:`draw_pose`: a start or goal marker (dot or star, heading arrow, legend entry);
- :func:`draw_cell_ids`: position ids p (or configuration ids z) in the cells, font scaled to
  the cell size on the laid-out page (:func:`id_fontsize`, :func:`ids_figsize`);
- :func:`plan_vs_executed`: a planned route and an executed trace on one map;
- :func:`fit_title`: a title wrapped to its axes' width;
- :func:`angle_use_bars`, :func:`save_figure` (constrained layout, so no title is clipped).

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

__all__ = ["ID_MIN_PT", "angle_use_bars", "draw_cell_ids", "draw_env", "draw_pose",
           "draw_route", "draw_trace", "fit_title", "id_fontsize", "ids_figsize", "map_figsize",
           "map_legend", "plan_vs_executed", "save_figure"]

START_COLOR, GOAL_COLOR, EXECUTED_COLOR = "#d62728", "#2ca02c", "#ff7f0e"


def save_figure(fig: Figure, path: str | Path, dpi: int = 120) -> Path:
    """Lay out (constrained layout: titles, labels and colour bars are not clipped), write
    (PNG, SVG, PDF by the suffix) and close a figure; returns the path.
    """
    if fig.get_layout_engine() is None:
        fig.set_layout_engine("constrained")
    path = Path(path)
    fig.savefig(path, dpi=dpi)
    plt.close(fig)
    return path


def fit_title(ax: Axes, text: str, fontsize: float = 10, **kw) -> Any:
    """Set ``text`` as the title of ``ax``, wrapped at spaces to the axes' width so that it
    neither overflows into the next panel nor is clipped by the figure.
    """
    import textwrap
    fig = ax.figure
    width_in = ax.get_position().width * fig.get_figwidth()
    chars = max(12, int(width_in * 72 / (0.55 * fontsize)))
    wrapped = "\n".join(textwrap.fill(line, chars) for line in str(text).split("\n"))
    return ax.set_title(wrapped, fontsize=fontsize, **kw)


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


def draw_route(ax: Axes, cells: Any, path: Sequence, color: str = "#1f77b4",
               label: str | None = None, markers: bool = True, lw: float = 2.0,
               alpha: float = 0.8) -> None:
    """Draw a planned route: its poses joined, an arrow per heading.

    ``path`` holds configuration indices z (a step-model route,
    :attr:`planners.navigation.Route.path`: drawn through the cell centres) or poses
    (x [m], y [m], heading [deg]) (a route over exact poses,
    :attr:`planners.navigation.Route.poses`: the bump points themselves). With ``markers``
    the start is marked red and the goal green, with legend entries ``start`` and ``goal``.
    ``lw`` and ``alpha``: a wide pale route lets a run drawn over it show (an executed path
    that follows the plan exactly would hide under a line of the same width).
    """
    pts = np.asarray(path, dtype=float)
    if pts.ndim == 1:
        pts = np.array([cells.pose(int(z)) for z in path])
    ax.plot(pts[:, 0], pts[:, 1], "-", color=color, lw=lw, alpha=alpha, label=label,
            solid_capstyle="round")
    L = 0.35 * cells.h
    for x, y, deg in pts:
        t = np.radians(deg)
        ax.add_patch(FancyArrow(x, y, L * np.cos(t), L * np.sin(t), width=0.01,
                                head_width=0.05, color=color, alpha=0.6,
                                length_includes_head=True))
    if markers:
        draw_pose(ax, pts[0], "start", length=1.2 * L)
        draw_pose(ax, pts[-1], "goal", length=1.2 * L)


def route_label(path: Sequence) -> str:
    """Legend entry of a planned route: cell centres (configuration indices) or exact poses."""
    return ("planned (exact poses)" if np.asarray(path, dtype=float).ndim == 2
            else "planned (cell centres)")


def draw_pose(ax: Axes, pose: Sequence[float], kind: str = "start", label: str | None = None,
              length: float | None = None) -> None:
    """Mark a start (red dot) or goal (green star) pose (x [m], y [m][, heading [deg]]) with a
    heading arrow of ``length`` [m] (default 6 % of the larger axis range) and a legend
    entry ``label`` (default ``kind``).
    """
    if kind not in ("start", "goal"):
        raise ValueError(f"kind must be 'start' or 'goal', got {kind!r}.")
    color = START_COLOR if kind == "start" else GOAL_COLOR
    marker, ms = ("o", 9) if kind == "start" else ("*", 15)
    x, y = float(pose[0]), float(pose[1])
    ax.plot([x], [y], marker, color=color, ms=ms, mec="black", mew=0.6, ls="none",
            label=label or kind, zorder=8)
    if len(pose) > 2 and pose[2] is not None and math.isfinite(pose[2]):
        if length is None:
            length = 0.06 * max(np.ptp(ax.get_xlim()), np.ptp(ax.get_ylim()))
        _arrow(ax, x, y, float(pose[2]), length, color)


ID_MIN_PT = 5.0
"""Smallest font size [pt] of cell ids that stays readable on the page; :func:`ids_figsize`
sizes a figure so that its ids get at least this."""

_DIGIT_EM = 0.64            # width of a digit [em] (DejaVu Sans: 0.636)


def id_fontsize(cell_pt: float, digits: int, kind: str = "positions") -> float:
    """Font size [pt] of cell ids of ``digits`` digits in a cell ``cell_pt`` [pt] wide on
    the page: a position id fills half a cell's width in its top-left corner; the K
    configuration ids of a cell sit around its centre (:func:`draw_cell_ids`), each at most
    0.27 of the cell wide, so that the ids of one cell stand closer to each other (0.04 of
    the cell apart) than to those of the next cell (0.11).
    """
    if kind == "positions":
        return min(0.5 * cell_pt / (_DIGIT_EM * digits), 0.3 * cell_pt)
    return min(0.27 * cell_pt / (_DIGIT_EM * digits), 0.22 * cell_pt)


def _id_digits(cells: Any, kind: str) -> int:
    return len(str(max((cells.P if kind == "positions" else cells.N) - 1, 0)))


def ids_figsize(env: Any, cells: Any, kind: str = "positions", width: float = 7.0,
                extra: float = 0.9) -> tuple[float, float]:
    """(width, height) [in] of a one-map figure (:func:`map_figsize`) at least ``width``
    wide, wider where its cell ids of ``kind`` would otherwise be set below
    :data:`ID_MIN_PT`; ``extra`` [in] is the room for labels (and a colour bar).
    """
    cell_pt = ID_MIN_PT / id_fontsize(1.0, _id_digits(cells, kind), kind)   # proportional
    x0, y0, x1, y1 = env.bounds
    w = 1.1 * cell_pt * (x1 - x0) / cells.h / 72 + extra     # 10 %: ticks and the layout
    if w <= width:
        return map_figsize(env, width, extra)
    return w, (w - extra) * (y1 - y0) / max(x1 - x0, 1e-9) + extra


def draw_cell_ids(ax: Axes, cells: Any, kind: str = "positions",
                  fontsize: float | None = None, halo: bool = False) -> list:
    """Write the id of every cell on ``ax``: the position id p in each cell's top-left corner
    (the centre stays free for paths and poses), or (kind ``configurations``) the K
    configuration ids z = k·P + p around it, each towards its heading 360° k / K on a square
    0.31 of the cell from its centre (the outer squares of a 3 x 3 grid for K = 8), tied to
    the centre by a faint spoke. The font size
    (:func:`id_fontsize`) follows the cell's size on the page once the figure is laid out,
    so draw the ids after the title and legend; ``halo`` outlines the digits in white
    (readable on a heatmap, slower to draw).

    Returns the list of Text artists (P of them, or N).
    """
    if kind not in ("positions", "configurations"):
        raise ValueError(f"kind must be 'positions' or 'configurations', got {kind!r}.")
    if fontsize is None:
        fontsize = float(np.clip(id_fontsize(_cell_points(ax, cells), _id_digits(cells, kind),
                                             kind), 2.0, 9.0))
    from matplotlib import patheffects
    halo = [patheffects.withStroke(linewidth=2.2, foreground="white")] if halo else None
    texts = []
    c = cells.centres
    if kind == "positions":
        d = 0.40 * cells.h             # top-left corner: the centre stays free for paths
        for p, (x, y) in enumerate(c):
            texts.append(ax.text(x - d, y + d, str(p), ha="left", va="top", fontsize=fontsize,
                                 color="black", zorder=4, path_effects=halo))
        return texts
    spokes = []
    for k in range(cells.K):
        t = math.radians(k * cells.delta_deg)
        u = (math.cos(t), math.sin(t))
        edge = 0.31 * cells.h / max(abs(u[0]), abs(u[1]))   # on a square around the centre
        for p, (x, y) in enumerate(c):
            # a faint spoke from the centre towards the id ties it to its cell and heading
            spokes.append([(x + 0.05 * cells.h * u[0], y + 0.05 * cells.h * u[1]),
                           (x + 0.14 * cells.h * u[0], y + 0.14 * cells.h * u[1])])
            texts.append(ax.text(x + edge * u[0], y + edge * u[1], str(k * cells.P + p),
                                 ha="center", va="center", fontsize=fontsize, color="black",
                                 zorder=4, path_effects=halo))
    from matplotlib.collections import LineCollection
    ax.add_collection(LineCollection(spokes, colors="#9a9a9a", linewidths=0.5, zorder=3))
    return texts


def _cell_points(ax: Axes, cells: Any) -> float:
    """The side [pt] of a cell on the page once the figure is laid out (its layout engine
    run, the map's equal aspect applied).
    """
    fig = ax.figure
    engine = fig.get_layout_engine()
    if engine is not None:
        engine.execute(fig)
    ax.apply_aspect()
    (x0, _), (x1, _) = ax.transData.transform([(0.0, 0.0), (cells.h, 0.0)])
    return abs(x1 - x0) * 72 / fig.dpi


def plan_vs_executed(env: Any, cells: Any, path: Sequence[int] | None, trace: Any,
                     goal: Sequence[float] | None = None, title: str | None = None) -> Figure:
    """One map with a planned route (configuration indices ``path``) and an executed run's
    trace over it, the start and goal marked; returns the figure (see :func:`save_figure`).
    """
    fig, ax = plt.subplots(figsize=map_figsize(env))
    draw_env(ax, env, cells)
    if path is not None:
        draw_route(ax, cells, path, label=route_label(path), markers=False)
    draw_trace(trace, ax=ax, goal=goal, legend=False, color=EXECUTED_COLOR)
    if title:
        fit_title(ax, title, fontsize=10)
    map_legend(ax)
    return fig


def map_figsize(env: Any, width: float = 7.0, extra: float = 0.9) -> tuple[float, float]:
    """(width, height) [in] of a one-map figure: the map's aspect plus room for labels."""
    x0, y0, x1, y1 = env.bounds
    return width, min(12.0, max(3.0, (width - extra) * (y1 - y0) / max(x1 - x0, 1e-9) + extra))


def map_legend(ax: Axes, **kw) -> Any:
    """A legend outside the map, below its x tick labels and x label (offset in points, so
    it clears them on a map of any height), hiding nothing; duplicate labels once.
    """
    from matplotlib.transforms import offset_copy
    handles, labels = ax.get_legend_handles_labels()
    seen: dict = {}
    for h, lab in zip(handles, labels):
        seen.setdefault(lab, h)
    tick, label = ax.xaxis.get_major_ticks()[:1], ax.xaxis.label
    below = 6.0 + (tick[0].label1.get_size() + tick[0].get_pad() + tick[0].get_tick_padding()
                   if tick else 0.0)
    if label.get_text():
        below += 1.2 * label.get_size() + ax.xaxis.labelpad
    opts = {"loc": "upper center", "bbox_to_anchor": (0.5, 0.0),
            "bbox_transform": offset_copy(ax.transAxes, fig=ax.figure, y=-below,
                                          units="points"),
            "fontsize": 8, "ncol": min(len(seen), 4), "frameon": False}
    opts.update(kw)
    return ax.legend(list(seen.values()), list(seen.keys()), **opts)


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
               legend: bool = True, markers: bool = True) -> Axes:
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
    markers : bool
        Mark the start, and the goal (or the end); off when the caller marks them.

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
                # above the start and end markers: a run often bumps where it starts or ends
                ax.plot(x[sel], y[sel], marker, color="black" if kind == "bump" else color,
                        ms=ms, ls="none", label=name, zorder=9)
    L = 0.12 * max(np.ptp(ax.get_xlim()), np.ptp(ax.get_ylim())) / 2
    if markers:
        draw_pose(ax, (x[0], y[0], h[0]), "start", length=L)
        if goal is not None:
            draw_pose(ax, goal, "goal", length=L)
        else:
            ax.plot([x[-1]], [y[-1]], "s", color=GOAL_COLOR, ms=8, label="end", zorder=7)
    if legend:
        map_legend(ax)                  # below the map: it hides none of the path
    return ax


def _arrow(ax: Axes, x: float, y: float, deg: float, length: float, color: str) -> None:
    t = math.radians(deg)
    ax.add_patch(FancyArrow(x, y, length * math.cos(t), length * math.sin(t), width=0.015,
                            head_width=0.07, color=color, length_includes_head=True,
                            zorder=7))
