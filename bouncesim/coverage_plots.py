"""Heatmaps of coverage over the position cells, drawn on the map (matplotlib).

All functions take plain arrays over the P position cells (or group labels over the N
configuration cells) plus the cell space, so figures can be drawn from CSV files alone.

- :func:`draw_map`: walls and obstacles of an environment.
- :func:`heatmap`: one value per position cell as coloured squares on the map.
- :func:`diff_heatmap`: signed differences on a symmetric diverging scale.
- :func:`save_heatmap`: one heatmap per file.
- :func:`save_mix_vs_target`: the mixed coverage next to the target (same colour scale, unless
  the target is uniform: then its one value is marked on the mix's colour bar) and their
  difference.
- :func:`save_group_slices`: persistent groups drawn on the map for a few orientations.
- :func:`save_cover_curves`: the covered fraction C(t) per policy and team size
  (docs/model.md §20a), the model's mean and 10–90 % band, the simulation's mean when given.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.colors import ListedColormap

from .plots import draw_env, fit_title, save_figure

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.image import AxesImage
    from numpy.typing import ArrayLike

    from planners.cells import CellSpace

__all__ = ["draw_map", "heatmap", "diff_heatmap", "save_heatmap", "save_mix_vs_target",
           "save_group_slices", "position_grid", "save_cover_curves"]


def position_grid(cs, values) -> np.ndarray:
    """(rows, cols) array with values[p] at each free cell and NaN elsewhere (row 0 = bottom)."""
    grid = np.full(cs.index_grid.shape, np.nan)
    ij = cs.cells_ij
    grid[ij[:, 1], ij[:, 0]] = np.asarray(values, dtype=float)
    return grid


def draw_map(ax, env, color: str = "k", lw: float = 1.2) -> None:
    """Draw the outer wall and obstacles [m] as lines; obstacles are filled grey.

    :func:`bouncesim.plots.draw_env` in its ``outline`` style, with a margin of 5 % of the
    room's larger side.
    """
    x0, y0, x1, y1 = env.bounds
    draw_env(ax, env, style="outline", color=color, lw=lw, pad=0.05 * max(x1 - x0, y1 - y0))


def _extent(cs):
    x0, y0 = cs.env.origin
    rows, cols = cs.index_grid.shape
    return (x0, x0 + cols * cs.h, y0, y0 + rows * cs.h)


PROBABILITY = "probability per cell"


def _colorbar(ax: Axes, im, label: str):
    """A colour bar hugging ``ax`` on its right (it follows an equal-aspect map's real size)
    with ``label``; returns it.
    """
    cax = ax.inset_axes([1.03, 0.0, 0.045, 1.0])
    return ax.figure.colorbar(im, cax=cax, label=label)


def heatmap(ax: Axes, cs: CellSpace, values: ArrayLike, title: str | None = None,
            vmax: float | None = None, cmap: str = "viridis", colorbar: bool = True,
            label: str = f"coverage q [{PROBABILITY}]") -> AxesImage:
    """Colour every free position cell by ``values[p]`` on the map; returns the image.

    The title is wrapped to the panel's width; the colour bar (with ``label``, units in
    brackets) sits right of the map.
    """
    grid = position_grid(cs, values)
    vmax = float(np.nanmax(grid)) if vmax is None else vmax
    im = ax.imshow(np.ma.masked_invalid(grid), origin="lower", extent=_extent(cs),
                   cmap=cmap, vmin=0.0, vmax=vmax if vmax > 0 else 1.0,
                   interpolation="nearest", zorder=1)
    draw_map(ax, cs.env)
    if title:
        fit_title(ax, title, fontsize=10)
    if colorbar:
        _colorbar(ax, im, label)
    return im


def diff_heatmap(ax, cs, values, title: str | None = None,
                 label: str = f"difference [{PROBABILITY}]"):
    """Signed values per position cell (e.g. simulated − predicted) on a symmetric diverging
    colour scale, with a colour bar labelled ``label``; returns the image.
    """
    lim = float(np.abs(np.asarray(values, dtype=float)).max()) or 1.0
    im = ax.imshow(np.ma.masked_invalid(position_grid(cs, values)), origin="lower",
                   extent=_extent(cs), cmap="RdBu_r", vmin=-lim, vmax=lim,
                   interpolation="nearest")
    draw_map(ax, cs.env)
    if title:
        fit_title(ax, title, fontsize=10)
    _colorbar(ax, im, label)
    return im


def save_heatmap(path, cs, values, title: str | None = None, vmax: float | None = None) -> Path:
    """Write one heatmap PNG [values over position cells]."""
    fig, ax = plt.subplots(figsize=(6, 5))
    heatmap(ax, cs, values, title=title, vmax=vmax)
    return save_figure(fig, path)


def save_mix_vs_target(path, cs, mixed, target, title: str | None = None,
                       label: str = "Aα") -> Path:
    """Three panels: mixed coverage (``label``, default Aα), target b and their difference.

    A target that varies shares the mix's colour scale. A uniform target would read as one
    flat colour on that scale, so its panel shows it on its own scale with its value in the
    title, and that value is marked on the mix's colour bar.
    """
    mixed = np.asarray(mixed, dtype=float)
    target = np.asarray(target, dtype=float)
    uniform = target.size > 0 and bool(np.ptp(target) <= 1e-12 * max(target.max(), 1e-300))
    vmax = float(mixed.max()) if uniform else float(max(mixed.max(), target.max()))
    x0, y0, x1, y1 = cs.env.bounds
    fig, axes = plt.subplots(1, 3, figsize=(16, 4.0 * (y1 - y0) / (x1 - x0) + 1.6))
    im = heatmap(axes[0], cs, mixed, title=f"mixed coverage {label}", vmax=vmax)
    if uniform:
        b = float(target.flat[0])
        heatmap(axes[1], cs, target, vmax=2 * b, label=f"target b [{PROBABILITY}]",
                title=f"target b: uniform, 1/P = {b:.3g} per cell "
                "(own scale; red line on the left colour bar)")
        cbar = im.colorbar
        if cbar is not None and b <= vmax:
            cbar.ax.axhline(b, color="red", lw=2.0)
            cbar.ax.text(-0.2, b, "b", color="red", ha="right", va="center", fontsize=11,
                         transform=cbar.ax.get_yaxis_transform())
    else:
        heatmap(axes[1], cs, target, title="target b (same colour scale)", vmax=vmax,
                label=f"target b [{PROBABILITY}]")
    diff_heatmap(axes[2], cs, mixed - target, title=f"{label} − b")
    if title:
        fig.suptitle(title)
    return save_figure(fig, path)


def save_group_slices(path, cs, labels, orientations, title: str | None = None) -> Path:
    """Persistent groups on the map, one panel per orientation k.

    Parameters
    ----------
    labels : array (N,) of int
        Group of every configuration z = k*P + p, or -1 for transient ones.
    orientations : sequence of int
        Orientation indices k to draw (heading 360° k / K).
    """
    labels = np.asarray(labels)
    ngroups = int(labels.max()) + 1 if labels.size and labels.max() >= 0 else 0
    base = plt.get_cmap("tab10" if ngroups <= 10 else "tab20")
    colors = [base(i % base.N) for i in range(max(ngroups, 1))]
    cmap = ListedColormap(colors)
    ks = list(orientations)
    fig, axes = plt.subplots(1, len(ks), figsize=(4.2 * len(ks), 4.2), squeeze=False)
    for ax, k in zip(axes[0], ks):
        lab = labels[k * cs.P:(k + 1) * cs.P].astype(float)
        lab[lab < 0] = np.nan
        grid = position_grid(cs, lab)
        ax.imshow(np.ma.masked_invalid(grid), origin="lower", extent=_extent(cs), cmap=cmap,
                  vmin=-0.5, vmax=len(colors) - 0.5, interpolation="nearest")
        draw_map(ax, cs.env)
        x, y = cs.centres[:, 0], cs.centres[:, 1]
        th = np.deg2rad(k * cs.delta_deg)
        rec = ~np.isnan(lab)
        ax.quiver(x[rec], y[rec], np.cos(th), np.sin(th), angles="xy", scale_units="xy",
                  scale=1 / (0.35 * cs.h), width=0.004, color="k", zorder=5)
        ax.set_title(f"heading {k * cs.delta_deg:g}° ({int(rec.sum())} persistent cells)",
                     fontsize=9)
    if title:
        fig.suptitle(title)
    return save_figure(fig, path, dpi=110)


def save_cover_curves(path, records: list, title: str | None = None) -> Path:
    """C(t) against t, one panel per team size: for every record of ``metrics.json``
    (docs/model.md §20a) the model's mean and its 10–90 % band, and where the record has
    ``twin_covered_mean`` the simulated mean (markers).
    """
    sizes = sorted({int(r["robots"]) for r in records})
    fig, axes = plt.subplots(1, len(sizes), figsize=(6.4 * len(sizes), 4.4), squeeze=False)
    for ax, k in zip(axes[0], sizes):
        mine = [r for r in records if int(r["robots"]) == k]
        for i, r in enumerate(mine):
            c = f"C{i}"
            name = "mix" if r["angle"] == "mix" else f"{r['angle']}°"
            t = np.asarray(r["t"], dtype=float)
            ax.plot(t, r["covered_mean"], color=c, label=f"{name}: model ({r['method']})")
            ax.fill_between(t, r["covered_p10"], r["covered_p90"], color=c, alpha=0.15, lw=0)
            if r.get("twin_covered_mean") is not None:
                ax.plot(t, r["twin_covered_mean"], "o", color=c, mfc="none", ms=4,
                        label=f"{name}: simulation ({r['twin_runs']} runs)")
        ax.set_xscale("log")
        ax.set_ylim(0, 1.02)
        ax.set_xlabel("t [steps of each robot]")
        ax.set_ylabel("covered fraction C(t)")
        ax.set_title(f"{k} robot" + ("s" if k > 1 else "") + " (band: 10-90 % of runs)")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="lower right")
    if title:
        fig.suptitle(title, fontsize=10)
    return save_figure(fig, path, dpi=110)
