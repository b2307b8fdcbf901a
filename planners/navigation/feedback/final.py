"""The feedback navigator's final drive (docs/model.md §15): the drive length that puts the
most belief mass in the goal cell (:func:`final_drive`), from each particle's interval of
drives that end it in the cell (:func:`goal_intervals`).
"""

from __future__ import annotations

import numpy as np

from envs.motion import unit

from ...measures import heading_ok

__all__ = ["final_drive", "goal_intervals"]

_MAX_FINAL_CANDIDATES = 128   # final drive lengths tried


# ============================================================================ the final drive
def goal_intervals(pos, heading_deg, D, cell_box, goal_heading_deg: float, delta_deg: float,
                   slides=None):
    """The drive lengths that end each particle's flight in the goal cell.

    Parameters
    ----------
    pos : (n, 2) [m];  heading_deg : (n,) [deg];  D : (n,) flight lengths to the bump [m]
    cell_box : (x0, y0, x1, y1) the goal cell's square [m]
    goal_heading_deg, delta_deg : a particle whose heading is more than Δ/2 from the goal
                                  heading gets no interval
    slides : (n,) bool, optional   flights that slide on from their first contact (§9): the
                                  robot does not stop there, so the flight never lands in the
                                  cell (b <= D)

    Returns
    -------
    a, b : (n,) [m]   a drive d ends in the cell when a <= d <= b (b = inf: the flight lands
                      in the cell, where the bump stops the robot); a = inf: never
    """
    pos = np.asarray(pos, dtype=float).reshape(-1, 2)
    u = unit(heading_deg)
    lo = np.zeros(len(pos))
    hi = np.asarray(D, dtype=float).copy()
    box = np.asarray(cell_box, dtype=float)
    for ax in (0, 1):
        p, c = pos[:, ax], u[:, ax]
        inside = (p >= box[ax]) & (p <= box[ax + 2])
        with np.errstate(divide="ignore", invalid="ignore"):
            t0, t1 = (box[ax] - p) / c, (box[ax + 2] - p) / c
        zero = c == 0
        lo = np.where(zero, np.where(inside, lo, np.inf), np.maximum(lo, np.minimum(t0, t1)))
        hi = np.where(zero, np.where(inside, hi, -np.inf), np.minimum(hi, np.maximum(t0, t1)))
    ok = (lo <= hi) & heading_ok(heading_deg, goal_heading_deg, delta_deg)
    lands = ok & (hi >= np.asarray(D) - 1e-9)
    if slides is not None:
        lands &= ~np.asarray(slides, dtype=bool)
    a = np.where(ok, lo, np.inf)
    b = np.where(lands, np.inf, np.where(ok, hi, -np.inf))
    return a, b


def final_drive(pos, heading_deg, D, w, cell_box, goal_heading_deg: float, delta_deg: float,
                margin: float, slides=None) -> tuple[float, float]:
    """The final drive d [m] that puts the most weight in the goal cell.

    A particle (pos, heading, flight D to its bump, weight w) ends at pos + min(d, D)·u. It
    counts when that point lies in the cell and its heading is within Δ/2 of the goal's,
    in full once the point lies ``margin`` [m] or deeper inside the cell (depth: the distance
    to the cell's border), in proportion to its depth when shallower. The best d maximises
    that weight, then the weighted depth. Candidates: the ends of every particle's interval
    in the cell (:func:`goal_intervals`), their midpoints, and every flight's point nearest
    the cell's centre. ``slides`` (n,) bool: flights that slide on from their first contact
    (§9); such a particle counts only for drives up to its D (it does not stop at D).

    Returns (d, mass): mass is the weight whose end point lies in the cell at all; nothing
    in the cell gives (0, 0).

    >>> pos, D = [[0.1, 0.5], [0.1, 0.6]], [3.0, 3.0]
    >>> final_drive(pos, [0.0, 0.0], D, [0.5, 0.5], (1.0, 0.0, 2.0, 1.0), 0.0, 45.0, 0.02)
    (1.4, 1.0)
    """
    pos = np.asarray(pos, dtype=float).reshape(-1, 2)
    head, D, w = (np.asarray(v, dtype=float).reshape(-1) for v in (heading_deg, D, w))
    a, b = goal_intervals(pos, head, D, cell_box, goal_heading_deg, delta_deg, slides)
    ok = np.isfinite(a)
    if not ok.any():
        return 0.0, 0.0
    u = unit(head)
    box = np.asarray(cell_box, dtype=float)
    centre = (box[:2] + box[2:]) / 2
    half = (box[2] - box[0]) / 2
    near = np.clip(((centre - pos) * u).sum(1), a, np.minimum(b, D))[ok]
    ends = np.unique(np.concatenate([a[ok], b[ok & np.isfinite(b)]]))
    cand = np.unique(np.round(np.concatenate([ends, (ends[:-1] + ends[1:]) / 2, near]), 4))
    cand = cand[cand >= 0]
    if len(cand) > _MAX_FINAL_CANDIDATES:          # evenly spread over the sorted ones
        cand = cand[np.linspace(0, len(cand) - 1, _MAX_FINAL_CANDIDATES).round().astype(int)]
    t = np.minimum(cand[:, None], D[None])                       # (C, n) travelled
    end = pos[None] + t[..., None] * u[None]
    depth = half - np.abs(end - centre).max(axis=2)
    good = heading_ok(head, goal_heading_deg, delta_deg)[None]
    inside = good & (depth >= 0)
    if slides is not None:
        inside &= ~(np.asarray(slides, dtype=bool)[None] & (cand[:, None] > D[None]))
    soft = (w[None] * np.where(inside, np.clip(depth / max(margin, 1e-12), 0, 1), 0)).sum(1)
    deep = (w[None] * np.where(inside, depth, 0)).sum(1)
    best = np.lexsort((-deep, -np.round(soft, 9)))[0]
    return float(cand[best]), float((w[None] * inside).sum(1)[best])
