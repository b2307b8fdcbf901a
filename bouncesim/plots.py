"""Figures shared by the CLI and the experiments (matplotlib, Agg backend)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.patches import FancyArrow
from matplotlib.patches import Polygon as MplPolygon

__all__ = ["angle_use_bars", "draw_env", "draw_route", "save_figure"]


def save_figure(fig, path, dpi: int = 120) -> Path:
    """Lay out, write and close a figure; returns the path."""
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=dpi)
    plt.close(fig)
    return path


def angle_use_bars(hist, path: Path, title: str = "", reference: dict | None = None) -> None:
    """Bar chart of the number of plans by distinct angles used."""
    fig, ax = plt.subplots(figsize=(5, 3.4))
    ax.bar(hist["angles_used"], hist["plans"], color="#4477aa")
    for x, y in zip(hist["angles_used"], hist["plans"]):
        ax.annotate(f"{y}", (x, y), ha="center", va="bottom", fontsize=8)
    ax.set_xlabel("distinct bouncing angles in the plan")
    ax.set_ylabel("number of (start, goal) pairs")
    ax.set_xticks(list(hist["angles_used"]))
    ax.set_title(title, fontsize=9)
    save_figure(fig, path)


def draw_env(ax, env, cells=None, grid: bool = True) -> None:
    """Walls, obstacles and (optionally) the free cells of an environment on ``ax``."""
    ax.add_patch(MplPolygon(np.asarray(env.boundary.exterior.coords), closed=True,
                            facecolor="white", edgecolor="black", lw=2))
    for ob in env.obstacles:
        ax.add_patch(MplPolygon(np.asarray(ob.exterior.coords), closed=True,
                                facecolor="#b5651d", edgecolor="black", lw=1, hatch="///"))
    if cells is not None and grid:
        h = cells.h
        for (x, y) in cells.centres:
            ax.add_patch(plt.Rectangle((x - h / 2, y - h / 2), h, h, fill=False,
                                       edgecolor="#cccccc", lw=0.5))
    x0, y0, x1, y1 = env.bounds
    ax.set_xlim(x0 - 0.05, x1 + 0.05)
    ax.set_ylim(y0 - 0.05, y1 + 0.05)
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")


def draw_route(ax, cells, path, color="#1f77b4", label=None) -> None:
    """A route through configuration cells: cell centres joined, an arrow for each heading,
    start in red and goal in green."""
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
