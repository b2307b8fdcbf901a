"""The figures of docs/model.md, and the knife-edge table it quotes.

Three figures, drawn from the library's own objects (nothing is measured):

- ``model_grid.png``: a small room's grid, its position ids p and configuration ids
  z = k·P + p (docs/model.md, "Configurations and headings");
- ``model_steps.png``: the step offsets (di, dj) of a forward move at K = 8 and K = 16 (the
  step model);
- ``model_cspace.png``: ``lab``'s free space E, the C-space rings (E eroded by the robot's
  radius) cut into contact bins, one flight with its counted cells, and the corridor one robot
  wide whose C-space is a ring spike of zero width.

``--knife-edge`` prints the table of docs/model.md's knife-edge warning instead: the event
model's coverage of ``lab`` (K = 8, ε = 45°, r = 0.8) with one motion constant changed at a
time, as the total-variation distance from the defaults (and the free cells P).

    python -m experiments.model_figures                 # docs/figures/model_*.png
    python -m experiments.model_figures --out DIR       # DIR/model_*.png
    python -m experiments.model_figures --knife-edge    # the table, on stdout
"""

from __future__ import annotations

import argparse
import math
from contextlib import ExitStack
from pathlib import Path
from unittest import mock

import numpy as np

import envs
import envs.motion
import planners.boundary
from bouncesim.plots import draw_env, fit_title, save_figure
from envs import Environment
from planners.boundary import Boundary
from planners.cells import CellSpace

__all__ = ["FIGURES", "KNIFE_EDGE_VARIANTS", "cspace_figure", "grid_figure", "knife_edge_table",
           "main", "small_room", "steps_figure"]

OUT = Path(__file__).resolve().parent.parent / "docs" / "figures"
FIGURES = ("model_grid.png", "model_steps.png", "model_cspace.png")
_BIN_COLORS = ("#1f77b4", "#ff7f0e")
_FLIGHT = ((0.51, 0.51), 90.0)          # the flight of docs/model.md's worked example


def small_room(orientations: int = 4) -> Environment:
    """A 4 × 3 cell room (h = 0.34 m, r = 0.17 m) with one obstacle cell at (i, j) = (2, 1)."""
    return Environment.from_dict({
        "name": "small", "boundary": [[0, 0], [1.36, 0], [1.36, 1.02], [0, 1.02]],
        "obstacles": [[[0.68, 0.34], [1.02, 0.34], [1.02, 0.68], [0.68, 0.68]]],
        "robot_radius": 0.17,
        "discretization": {"cell_size": 0.34, "orientations": orientations}})


# ============================================================================ grid indices
def grid_figure(path: Path) -> Path:
    """Position ids p (with the grid's (i, j)) and configuration ids z = k·P + p at K = 4."""
    import matplotlib.pyplot as plt

    env = small_room(4)
    cs = CellSpace(env)
    h = cs.h
    rows, cols = env.grid_shape
    fig, axes = plt.subplots(1, 2, figsize=(12, 5.0))
    for ax in axes:
        draw_env(ax, env, cs, grid=False, pad=0.06)
        for i in range(1, cols):
            ax.plot([i * h, i * h], [0, rows * h], color="0.75", lw=0.6, zorder=1)
        for j in range(1, rows):
            ax.plot([0, cols * h], [j * h, j * h], color="0.75", lw=0.6, zorder=1)
        ax.set_xticks([(i + 0.5) * h for i in range(cols)])
        ax.set_xticklabels([f"i = {i}" for i in range(cols)])
        ax.set_yticks([(j + 0.5) * h for j in range(rows)])
        ax.set_yticklabels([f"j = {j}" for j in range(rows)])
        ax.set_xlabel("")
        ax.set_ylabel("")
        ax.plot([0], [0], "ks", ms=5, zorder=6)
        ax.annotate("(x0, y0)", (0, 0), (0.01, 0.01), fontsize=8, ha="left", va="bottom")
    ax = axes[0]
    for p, (x, y) in enumerate(cs.centres):
        ax.text(x, y, f"p = {p}", ha="center", va="center", fontsize=12, weight="bold")
    ax.text(0.85, 0.51, "not free", ha="center", va="center", fontsize=9,
            bbox={"facecolor": "white", "edgecolor": "none", "pad": 1})
    fit_title(ax, f"position ids p: the free cells row-major from the bottom (P = {cs.P})")
    ax = axes[1]
    r = 0.30 * h
    for k in range(cs.K):
        t = math.radians(k * cs.delta_deg)
        for p, (x, y) in enumerate(cs.centres):
            z = k * cs.P + p
            ax.annotate("", (x + 0.16 * h * math.cos(t), y + 0.16 * h * math.sin(t)), (x, y),
                        arrowprops={"arrowstyle": "-|>", "color": "0.45", "lw": 0.8})
            ax.text(x + r * math.cos(t), y + r * math.sin(t), str(z), ha="center",
                    va="center", fontsize=9, color="#1f4e99")
    fit_title(ax, f"configuration ids z = k·P + p (K = {cs.K}, N = {cs.N}), each placed "
                  f"towards its heading θ_k = k·90°; the paper's id is z + 1")
    return save_figure(fig, path)


# ============================================================================ step offsets
def _steps_panel(ax, K: int) -> None:
    env = Environment.from_dict({"boundary": [[0, 0], [1.02, 0], [1.02, 1.02], [0, 1.02]],
                                 "robot_radius": 0.17,
                                 "discretization": {"cell_size": 0.34, "orientations": K}})
    cs = CellSpace(env)
    h = cs.h
    c = cs.centres[4]                                  # the middle cell (1, 1)
    for i in range(4):
        ax.plot([i * h, i * h], [0, 3 * h], color="0.7", lw=0.8)
        ax.plot([0, 3 * h], [i * h, i * h], color="0.7", lw=0.8)
    ring = np.linspace(0, 2 * np.pi, 200)
    ax.plot(c[0] + h * np.cos(ring), c[1] + h * np.sin(ring), ":", color="0.5", lw=0.8)
    ends = c + h * cs.units
    labelled = set()
    for k, (di, dj) in enumerate(cs.step_offsets.tolist()):
        d = c + h * np.array([di, dj])
        ax.plot([ends[k, 0], d[0]], [ends[k, 1], d[1]], "--", color="#d62728", lw=0.8)
        if (di, dj) in labelled:
            continue
        labelled.add((di, dj))
        ax.annotate("", d, c, arrowprops={"arrowstyle": "-|>", "color": "#1f77b4",
                                          "lw": 1.4, "shrinkA": 0, "shrinkB": 0})
        ax.plot([d[0]], [d[1]], "o", color="#1f77b4", ms=5, zorder=6)
        w = np.array([di, dj]) / math.hypot(di, dj)
        ax.text(d[0] + 0.1 * w[0], d[1] + 0.1 * w[1], f"({di}, {dj})", ha="center",
                va="center", fontsize=9, color="#1f4e99")
    ax.plot(ends[:, 0], ends[:, 1], "o", color="#d62728", ms=4, zorder=7,
            label="c' = c + h·u_k (dashed: to the destination centre)")
    ax.plot([c[0]], [c[1]], "ko", ms=5, zorder=8)
    ax.text(c[0] + 0.03, c[1] - 0.06, "c", fontsize=10)
    if K == 16:
        k = 1                                          # 22.5°: rounds to (1, 0)
        ax.annotate(f"θ_1 = 22.5°: c' lies in the\ncell east of c, (di, dj) = "
                    f"{tuple(cs.step_offsets[k].tolist())}", ends[k], (0.45, -0.2), fontsize=8.5,
                    arrowprops={"arrowstyle": "->", "lw": 0.7}, color="#a02020")
    ax.set_xlim(-0.1, 3 * h + 0.1)
    ax.set_ylim(-0.26, 3 * h + 0.06)
    ax.set_aspect("equal")
    ax.set_xticks([])
    ax.set_yticks([])


def steps_figure(path: Path) -> Path:
    """The forward moves from a cell centre c: offsets (di, dj) at K = 8 and K = 16."""
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(10, 5.6))
    for ax, K in zip(axes, (8, 16)):
        _steps_panel(ax, K)
        ax.set_title(f"K = {K}: a forward move from the centre c of a cell", fontsize=10)
    axes[0].legend(loc="lower left", fontsize=8.5, frameon=False)
    fig.suptitle("step offset (di, dj) = (floor(½ + (1 + 1e-6)·cos θ_k), floor(½ + (1 + 1e-6)"
                 "·sin θ_k)):\nthe centre moves to a neighbour's centre, h·|(di, dj)| away "
                 "(√2·h on a diagonal)", fontsize=10)
    return save_figure(fig, path)


# ============================================================================ C-space ring
def _draw_bins(ax, bd: Boundary, label_every: int, fontsize: float = 6.5) -> None:
    frac = np.linspace(0.0, 1.0, 12)
    for b in range(bd.n_bins):
        pts = bd.points(np.full(frac.size, b), frac)
        ax.plot(pts[:, 0], pts[:, 1], "-", color=_BIN_COLORS[b % 2], lw=2.2,
                solid_capstyle="butt", zorder=5)
        if label_every and b % label_every == 0:
            m, seg = bd.points([b], [0.5], return_segment=True)
            w = bd.seg_inward[seg[0]]                   # labels on the free side
            ax.plot([m[0, 0]], [m[0, 1]], ".", color="k", ms=3, zorder=6)
            ax.annotate(str(b), m[0], xytext=(9 * w[0], 9 * w[1]), textcoords="offset points",
                        fontsize=fontsize, ha="center", va="center", zorder=7)
    for ring in range(len(bd.ring_length)):
        b0 = int(bd.ring_first_bin[ring])
        a, e = bd.points([b0, b0], [0.0, 0.9])
        ax.annotate("", e, a, arrowprops={"arrowstyle": "-|>", "color": "#2ca02c", "lw": 1.6},
                    zorder=8)
        ax.plot([a[0]], [a[1]], "o", color="#2ca02c", ms=5, zorder=8)


def cspace_figure(path: Path) -> Path:
    """``lab``'s C-space rings cut into contact bins (bin length h/4), one flight and the
    corridor one robot wide (its zoom).
    """
    import matplotlib.pyplot as plt
    from matplotlib.patches import Circle, Rectangle

    from envs.motion import casters, drive_distance, flight_steps, unit

    env = envs.load("lab")
    cs = CellSpace(env)
    bd = Boundary(env, cs.h / 4)
    h, r = cs.h, env.robot_radius
    fig, axes = plt.subplots(1, 2, figsize=(13, 6.2), width_ratios=[1.55, 1])
    ax = axes[0]
    draw_env(ax, env, cs, grid=False, pad=0.08)
    for cx, cy in cs.centres:                          # the free cells, under the walls
        ax.add_patch(Rectangle((cx - h / 2, cy - h / 2), h, h, fill=False, edgecolor="0.8",
                               lw=0.5, zorder=1.5))
    ax.plot(*env.boundary.exterior.xy, color="black", lw=2, zorder=4)
    _draw_bins(ax, bd, label_every=10)
    # the worked example's flight and the cells its steps are counted in
    (x, y), heading = _FLIGHT
    u = unit([heading])[0]
    D = float(drive_distance(casters(env)[0].cast([[x, y]], [u]))[0])
    n = int(flight_steps(D, h))
    counted = [np.array([x, y]) + s * h * u for s in range(n)] + [np.array([x, y]) + D * u]
    for s, pt in enumerate(counted):
        p = int(cs.cell_of_point([pt])[0])
        cx, cy = cs.centres[p]
        ax.add_patch(Rectangle((cx - h / 2, cy - h / 2), h, h, color="#9467bd", alpha=0.18,
                               zorder=2))
        ax.text(cx + 0.3 * h, cy - 0.3 * h, f"p={p}", fontsize=6.5, color="#5b3a86",
                ha="center", va="center", zorder=3)
        ax.plot([pt[0]], [pt[1]], "s" if s == n else "^", color="#5b3a86", ms=5, zorder=9)
    ax.annotate("", (x + D * u[0], y + D * u[1]), (x, y),
                arrowprops={"arrowstyle": "-|>", "color": "#5b3a86", "lw": 1.8}, zorder=9)
    ax.text(0.75, 0.45, f"flight from (0.51, 0.51) m at 90°:\nD = {D:.9f} m, {n} forward "
            "steps (▲)\nand the bump step (■), counted in\nthe shaded cells", fontsize=7,
            color="#5b3a86", zorder=9,
            bbox={"facecolor": "white", "alpha": 0.9, "edgecolor": "none", "pad": 1})
    ax.add_patch(Rectangle((2.05, -0.04), 1.06, 0.46, fill=False, ls="--", color="k", lw=0.8,
                           zorder=9))
    fit_title(ax, f"lab: C-space rings (E eroded by r_b = {r} m) in {bd.n_bins} contact "
                  f"bins of about h/4; green: each ring's start and direction", fontsize=9)
    # zoom: the corridor one robot wide under the east block
    ax = axes[1]
    draw_env(ax, env, None, grid=False, pad=0.0)
    _draw_bins(ax, bd, label_every=1, fontsize=6)
    ax.add_patch(Circle((2.62, 0.17), r, fill=False, color="#d62728", lw=1.2, zorder=7))
    ax.plot([2.62], [0.17], "+", color="#d62728", ms=8, zorder=7)
    ax.text(2.09, 0.60, "The ring runs out along y = 0.17 m to (2.89, 0.17) m and back: a\n"
            "spike of zero width, bins on both sides (0-5 out, 112-118 back).\nShapely "
            "puts the way back at y = 0.16999999999999998: a point on\nthe spike goes to "
            "the nearer side, decided in the last bit.", fontsize=7, va="top", zorder=9,
            bbox={"facecolor": "white", "alpha": 0.92, "edgecolor": "none", "pad": 2})
    ax.set_xlim(2.05, 3.11)
    ax.set_ylim(-0.04, 0.62)
    fit_title(ax, "zoom: the corridor exactly one robot wide (the robot, red, touches "
                  "both walls)", fontsize=9)
    return save_figure(fig, path)


# ============================================================================ knife edges
KNIFE_EDGE_VARIANTS = (
    ("defaults", {}),
    ("CONTACT_GAP 1e-9 -> 3e-7 m", {"CONTACT_GAP": 3e-7}),
    ("GRAZE_TOL 1e-7 -> 0 m", {"GRAZE_TOL": 0.0}),
    ("STEP_TOL 1e-6 -> 1e-10 m", {"STEP_TOL": 1e-10}),
    ("BUMP_RANGE 1e-6 -> 1e-10 m", {"BUMP_RANGE": 1e-10}),
    ("Environment.tol 1e-9 -> 0 m", {"tol": 0.0}),
)
"""(label, changed constants) of :func:`knife_edge_table`, the defaults first."""


def _patched(stack: ExitStack, change: dict) -> None:
    """Enter patches that change the constants of ``change`` for the event model: the motion
    layer's constants where they are read, including the modules' own copies made at import
    (the boundary's flight-start offset is CONTACT_GAP, the casters' corner test GRAZE_TOL).
    """
    motion = envs.motion
    if "CONTACT_GAP" in change:
        stack.enter_context(mock.patch.object(motion, "CONTACT_GAP", change["CONTACT_GAP"]))
        stack.enter_context(mock.patch.object(planners.boundary, "_NUDGE",
                                              change["CONTACT_GAP"]))
    if "GRAZE_TOL" in change:
        for name in ("GRAZE_TOL", "_GRAZE_TOL"):
            stack.enter_context(mock.patch.object(motion, name, change["GRAZE_TOL"]))
    for name in ("STEP_TOL", "BUMP_RANGE"):
        if name in change:
            stack.enter_context(mock.patch.object(motion, name, change[name]))
    if "tol" in change:
        stack.enter_context(mock.patch.object(Environment, "tol",
                                              property(lambda self: change["tol"])))


def knife_edge_table(angles=(45.0, 90.0, 135.0), eps_deg: float = 45.0, r: float = 0.8
                     ) -> list[dict]:
    """The event model's coverage of ``lab`` at K = 8 under §11 noise (ε, r), each variant of
    :data:`KNIFE_EDGE_VARIANTS` against the defaults: free cells P and TV per angle (None
    where P differs, so the cells are not the same).
    """
    from planners.coverage import TurnNoise, clear_cache, model_for

    rows, base = [], None
    for label, change in KNIFE_EDGE_VARIANTS:
        with ExitStack() as stack:
            _patched(stack, change)
            envs.motion.casters.cache_clear()
            clear_cache()
            cs = CellSpace(envs.load("lab", orientations=8))
            n_free = cs.P
            model = model_for(cs, "event")
            qs = [model.analyse(a, TurnNoise(eps_deg, r)).q for a in angles]
        envs.motion.casters.cache_clear()
        clear_cache()
        if base is None:
            base = qs
        tv = [0.5 * float(np.abs(q - b).sum()) if q.shape == b.shape else None
              for q, b in zip(qs, base)]
        rows.append({"variant": label, "P": n_free, "tv": dict(zip(angles, tv))})
    return rows


# ============================================================================ main
def main(argv: list[str] | None = None) -> int:
    """Command line: ``--out`` (default docs/figures) or ``--knife-edge``."""
    p = argparse.ArgumentParser(prog="python -m experiments.model_figures",
                                description=__doc__.splitlines()[0])
    p.add_argument("--out", type=Path, default=OUT,
                   help="folder for model_grid.png, model_steps.png and model_cspace.png "
                        "(default: docs/figures)")
    p.add_argument("--knife-edge", action="store_true",
                   help="print the knife-edge table of docs/model.md instead of drawing")
    args = p.parse_args(argv)
    if args.knife_edge:
        rows = knife_edge_table()
        angles = list(rows[0]["tv"])
        print("lab, event model, K = 8, noise eps = 45 deg, r = 0.8: TV from the defaults")
        print(f"{'variant':32s} {'P':>3s} " + " ".join(f"{a:>7g}°" for a in angles))
        for row in rows:
            tvs = " ".join(f"{v:8.4f}" if v is not None else f"{'(P)':>8s}"
                           for v in row["tv"].values())
            print(f"{row['variant']:32s} {row['P']:3d} {tvs}")
        return 0
    import matplotlib
    matplotlib.use("Agg")
    args.out.mkdir(parents=True, exist_ok=True)
    for name, draw in zip(FIGURES, (grid_figure, steps_figure, cspace_figure)):
        print(f"wrote {draw(args.out / name)}")
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
