"""Flight chords through position cells (docs/model.md §13): where a straight flight
crosses each free cell, and the point of each crossing nearest the cell's centre (the exact
planner's goal arrivals, and the feedback planner's).
"""

from __future__ import annotations

import numpy as np

from ...cells import CellSpace

__all__ = ["chords"]


def chords(cells: CellSpace, pos, u, dist):
    """The free cells each flight passes through, with the point of each chord nearest the
    cell's centre.

    Parameters
    ----------
    cells : CellSpace
    pos : (n, 2) flight starts [m];  u : (n, 2) unit headings;  dist : (n,) lengths [m]

    Returns
    -------
    flight : (c,) int     index of the flight
    p : (c,) int          free position cell crossed (cells in no free cell are left out)
    t : (c,) float        [m] along the flight: the point of the chord (the part of the flight
                          inside the cell) nearest the cell's centre
    depth : (c,) float    [m] that point's distance to the cell's border
    """
    pos = np.asarray(pos, dtype=float).reshape(-1, 2)
    u = np.asarray(u, dtype=float).reshape(-1, 2)
    dist = np.asarray(dist, dtype=float).reshape(-1)
    h = cells.h
    origin = cells.origin
    rel = pos - origin
    ts = [np.zeros((len(pos), 1)), dist[:, None]]
    for ax in (0, 1):
        c, p = u[:, ax], rel[:, ax]
        nmax = int(np.ceil(np.max(dist * np.abs(c), initial=0.0) / h)) + 2
        sgn = np.sign(c)
        first = np.where(c > 0, np.floor(p / h) + 1, np.ceil(p / h) - 1)
        g = first[:, None] + sgn[:, None] * np.arange(nmax)[None]
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (g * h - p[:, None]) / c[:, None]
        ok = (c[:, None] != 0) & (t > 0) & (t < dist[:, None])
        ts.append(np.where(ok, t, dist[:, None]))
    T = np.sort(np.concatenate(ts, axis=1), axis=1)
    a, b = T[:, :-1], T[:, 1:]
    # a flight of length 0 (a bump at once) still has its start point: a chord of length 0
    fi, col = np.nonzero((b - a > 1e-12) | (np.arange(a.shape[1]) == 0)[None])
    a, b = a[fi, col], b[fi, col]
    mid = pos[fi] + ((a + b) / 2)[:, None] * u[fi]
    cell = cells.cell_of_point(mid)
    keep = cell >= 0
    fi, a, b, cell = fi[keep], a[keep], b[keep], cell[keep]
    # the point of the chord nearest the cell's centre, and its depth: the distance to the
    # cell's border, min(x − X0, X1 − x, y − Y0, Y1 − y)
    centre = cells.centres[cell]
    t = np.clip(((centre - pos[fi]) * u[fi]).sum(1), a, b)
    off = np.abs(pos[fi] + t[:, None] * u[fi] - centre)
    best = h / 2 - off.max(axis=1)
    return fi, cell, t, best

