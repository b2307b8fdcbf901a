"""Map diagnostics: what about an environment will surprise the cell models (docs/model.md §4a).

Pure geometry, no planning: :func:`diagnose` returns structured warnings, each a
:class:`MapWarning` with a stable ``code`` and a one-sentence ``message``:

- ``off-grid-walls``: a wall edge is not on the cell grid (not horizontal or vertical, or an
  end not on a grid point); the step model puts bumps at cell centres.
- ``cell-below-diameter``: the cell size h is below the robot's diameter 2r.
- ``narrow-passage``: a passage or dead end of the free space is no wider than the robot.

>>> import envs
>>> [w.code for w in diagnose(envs.load("lab"))]   # the corridor under the east block
['narrow-passage']
>>> [w.code for w in diagnose(envs.load("lab"), checks=("off-grid-walls",))]
[]
>>> [w.code for w in diagnose(envs.load("lab", cell_size=0.2))]
['off-grid-walls', 'cell-below-diameter', 'narrow-passage']
>>> corridor = Environment.from_dict({"boundary": [[0, 0], [2.04, 0], [2.04, 2.04],
...     [0, 2.04]], "obstacles": [[[0.68, 0], [1.36, 0], [1.36, 1.7], [0.68, 1.7]]]})
>>> [w.code for w in diagnose(corridor)]
['narrow-passage']
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import shapely

from .environment import Environment

__all__ = ["CHECKS", "PASSAGE_SLACK", "MapWarning", "diagnose", "narrow_passages",
           "off_grid_edges"]

PASSAGE_SLACK = 0.05
"""A passage up to (1 + PASSAGE_SLACK) robot diameters wide counts as no wider than the robot."""

CHECKS = ("off-grid-walls", "cell-below-diameter", "narrow-passage")


@dataclass(frozen=True)
class MapWarning:
    """One diagnostic of a map.

    Attributes
    ----------
    code : str      one of :data:`CHECKS` (stable: match on it, not on the message)
    message : str   one sentence for a person
    where : tuple of (x, y) [m]
        Example locations (an off-grid edge's first end, a narrow passage's middle).
    """

    code: str
    message: str
    where: tuple = ()

    def to_json(self) -> dict:
        """``{"code", "message", "where"}`` for JSON output."""
        return {"code": self.code, "message": self.message,
                "where": [[round(x, 6), round(y, 6)] for x, y in self.where]}


def off_grid_edges(env: Environment) -> np.ndarray:
    """The wall edges that are not on the cell grid, as an (n, 2, 2) array [m], slanted ones
    first.

    An edge is on the grid when it is horizontal or vertical and both its ends are grid
    points (x0 + i h, y0 + j h), within 1e-6 h.
    """
    segs = env.wall_segments
    h = env.cell_size
    rel = (segs - np.asarray(env.origin)) / h
    on_points = np.all(np.abs(rel - np.round(rel)) <= 1e-6, axis=(1, 2))
    d = np.abs(segs[:, 1] - segs[:, 0])
    axis = np.min(d, axis=1) <= 1e-6 * h
    off = segs[~(on_points & axis)]
    d = np.abs(off[:, 1] - off[:, 0])
    return off[np.argsort(np.min(d, axis=1) <= 1e-6 * h, kind="stable")]   # slanted first


def narrow_passages(env: Environment, slack: float = PASSAGE_SLACK) -> tuple:
    """Middles [m] of the passages and dead ends no wider than the robot (docs/model.md §4a).

    The disk of radius r' = r (1 + ``slack``) cannot sweep the regions of E outside the
    pieces of E eroded by r' dilated by r' again. Such a region is narrow when it touches
    two or more pieces (a passage joining them) or holds a point at least r (1 - 1e-3) from
    every wall (a dead end or corridor the robot fits into, barely); other regions are the
    corners the disk cannot reach. Each narrow region is reported at its centroid (or a
    point inside it when the centroid is not).
    """
    r = env.robot_radius * (1.0 + slack)
    out = []
    for part in shapely.get_parts(env.free_space):
        pieces = [p for p in shapely.get_parts(part.buffer(-r, quad_segs=16)) if p.area > 0]
        swept = [p.buffer(r, quad_segs=16) for p in pieces]
        rest = part.difference(shapely.union_all(swept)) if swept else part
        core = part.buffer(-env.robot_radius * (1 - 1e-3), quad_segs=16)
        for region in shapely.get_parts(rest):
            if not region.area > 0:
                continue                      # a seam left by rounding
            joins = sum(region.distance(s) <= 1e-6 * r for s in swept)
            if joins < 2 and not region.intersects(core):
                continue                      # a corner the disk cannot reach
            mid = region.centroid
            if not region.buffer(1e-9).contains(mid):
                mid = region.point_on_surface()
            out.append((float(mid.x), float(mid.y)))
    return tuple(out)


def diagnose(env: Environment, checks=CHECKS) -> tuple[MapWarning, ...]:
    """The map's warnings (those of ``checks``, in :data:`CHECKS` order); () for a clean map."""
    unknown = set(checks) - set(CHECKS)
    if unknown:
        raise ValueError(f"unknown checks {sorted(unknown)}; use {CHECKS}.")
    h, r = env.cell_size, env.robot_radius
    found = []
    if "off-grid-walls" in checks:
        off = off_grid_edges(env)
        if len(off):
            (x, y), (u, v) = off[0]
            found.append(MapWarning(
                "off-grid-walls",
                f"{len(off)} of {len(env.wall_segments)} wall edges are off the {h:g} m cell "
                f"grid (e.g. ({x:.3g}, {y:.3g}) to ({u:.3g}, {v:.3g}) m): the step model will "
                "put bumps at cell centres; the exact planner and the event model do not "
                "need this.", ((float(x), float(y)),)))
    if "cell-below-diameter" in checks and h < 2 * r * (1 - 1e-9):
        found.append(MapWarning(
            "cell-below-diameter",
            f"the cell size {h:g} m is below the robot's diameter {2 * r:g} m: a cell is "
            "smaller than the robot, so a step or a bump no longer moves it by one "
            "footprint as in the paper (h = 2r)."))
    if "narrow-passage" in checks:
        try:
            mids = narrow_passages(env)
        except shapely.errors.GEOSException:  # pragma: no cover - a diagnostic never fails
            mids = ()
        if mids:
            x, y = mids[0]
            found.append(MapWarning(
                "narrow-passage",
                f"{len(mids)} passage(s) or dead end(s) of the free space are no wider than "
                f"the robot ({2 * r:g} m, within {PASSAGE_SLACK:.0%}), e.g. near "
                f"({x:.2f}, {y:.2f}) m: the robot fits there barely or not at all, so plans "
                "and coverage through them depend on exact geometry and break under "
                "rotation noise.", tuple(mids)))
    return tuple(found)

