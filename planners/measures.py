"""Named measurements shared by both wings, the run loop and the Gymnasium environment: one
definition each (docs/model.md §21).

- :func:`wrap180`: a heading difference [deg] wrapped into (−180°, 180°];
- :func:`heading_ok`: a heading within ±(Δ/2 + :data:`HEADING_TOL`) of a goal heading;
- :func:`goal_check` (one pose) and :func:`in_goal` (many): the goal rule of §21, the final
  position in the goal configuration's cell and its heading within ±(Δ/2 + 1e-9°);
- :func:`flight_cap` and :func:`flight_limit`: how far a drive until a bump may go before a
  run gives up ("no bump");
- :func:`step_flights`: the expected flights of a step-model plan (§21: the length of the run
  of zeros before every bump, and of the trailing run).

Examples
--------
>>> wrap180(190.0), wrap180(-180.0), wrap180(540.0)
(-170.0, 180.0, 180.0)
>>> import envs
>>> from planners.cells import CellSpace
>>> cs = CellSpace(envs.load("lab"))                # h = 0.34 m, K = 8: Δ/2 = 22.5°
>>> g = goal_check(cs, 0, (0.20, 0.10, 22.5))       # cell 0 facing east, 22.5° off
>>> g.success, g.in_cell, round(g.position_error, 4), g.heading_error
(True, True, 0.0762, 22.5)
>>> goal_check(cs, 0, (0.20, 0.10, 22.6)).success   # just outside the heading tolerance
False
>>> round(flight_cap(cs), 4)                        # the 3.06 m x 2.04 m room's diagonal + h
4.0177
>>> round(flight_limit(cs, 2.0, zeros=3), 9), round(flight_limit(cs, 2.0, flight_m=0.5), 9)
(3.4, 2.36)
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .cells import CellSpace

__all__ = ["GoalCheck", "HEADING_TOL", "flight_cap", "flight_limit", "goal_check",
           "heading_ok", "in_goal", "step_flights", "wrap180"]

HEADING_TOL = 1e-9
"""[deg] added to Δ/2 in the goal rule's heading test, so that a heading exactly Δ/2 off
(computed with rounding) still counts."""


def wrap180(deg):
    """A heading difference [deg] wrapped into (−180°, 180°] (a float for a scalar, else an
    array); exact for differences already in that range.
    """
    w = np.fmod(np.asarray(deg, dtype=float), 360.0)
    w = np.where(w > 180.0, w - 360.0, w)
    w = np.where(w <= -180.0, w + 360.0, w)
    return float(w) if w.ndim == 0 else w


def heading_ok(heading_deg, goal_heading_deg: float, delta_deg: float):
    """Whether heading(s) [deg] lie within ±(Δ/2 + :data:`HEADING_TOL`) of the goal heading."""
    return np.abs(wrap180(np.asarray(heading_deg, dtype=float) - goal_heading_deg)) \
        <= delta_deg / 2 + HEADING_TOL


@dataclass(frozen=True)
class GoalCheck:
    """The goal rule (docs/model.md §21) applied to one final pose.

    Attributes
    ----------
    success : bool          in the goal cell and the heading within ±(Δ/2 + 1e-9°)
    in_cell, heading_ok : bool   the two halves of the rule
    position_error : float  [m] from the goal configuration's cell centre
    heading_error : float   [deg] final heading less the goal heading, in (−180°, 180°]
    """

    success: bool
    in_cell: bool
    heading_ok: bool
    position_error: float
    heading_error: float


def goal_check(cells: CellSpace, goal: int, pose) -> GoalCheck:
    """The goal rule of docs/model.md §21 for final ``pose`` (x [m], y [m], heading [deg])
    against goal configuration ``goal``.
    """
    gx, gy, gh = cells.pose(int(goal))
    x, y, th = (float(v) for v in pose[:3])
    err = wrap180(th - gh)
    in_cell = int(cells.cell_of_point([[x, y]])[0]) == int(cells.pk(int(goal))[0])
    ok = bool(abs(err) <= cells.delta_deg / 2 + HEADING_TOL)
    return GoalCheck(bool(in_cell and ok), bool(in_cell), ok, math.hypot(x - gx, y - gy), err)


def in_goal(cells: CellSpace, goal: int, xy, heading_deg) -> np.ndarray:
    """The goal rule of docs/model.md §21 for many final poses: (n,) bool."""
    p_goal = int(cells.pk(int(goal))[0])
    in_cell = cells.cell_of_point(np.asarray(xy, dtype=float).reshape(-1, 2)) == p_goal
    return in_cell & heading_ok(heading_deg, cells.pose(int(goal))[2], cells.delta_deg)


def flight_cap(cells: CellSpace) -> float:
    """[m] the longest straight drive a run allows: the diagonal of the environment's bounding
    box plus one cell (no straight line in the room is longer).
    """
    x0, y0, x1, y1 = cells.env.bounds
    return math.hypot(x1 - x0, y1 - y0) + cells.h


def flight_limit(cells: CellSpace, max_factor: float, *, zeros: int | None = None,
                 flight_m: float | None = None) -> float:
    """[m] how far one drive until a bump may go before the run gives up: ``max_factor``
    times the expected flight plus two cells, and never more than :func:`flight_cap`. The
    expected flight is a step plan's run of ``zeros`` cells (``max_factor``·(n + 2)·h) or an
    exact flight of ``flight_m`` metres (``max_factor``·(flight + 2h)).
    """
    h = cells.h
    if (zeros is None) == (flight_m is None):
        raise TypeError("flight_limit needs exactly one of zeros and flight_m.")
    want = max_factor * (zeros + 2) * h if zeros is not None else max_factor * (flight_m + 2 * h)
    return min(want, flight_cap(cells))


def step_flights(cells: CellSpace, plan, k0: int) -> tuple[list, float]:
    """The expected flights [m] of a step-model plan (docs/model.md §21): the length of the
    run of zeros before every bump, and of the trailing run, from start orientation ``k0``
    (:meth:`planners.cells.CellSpace.run_length`: n·h along an axis, n·√2·h along a
    diagonal at K = 8; the orientation after each bump is the previous one turned by its
    angle).

    >>> import envs
    >>> from planners.cells import CellSpace
    >>> from planners.plan import Plan
    >>> cs = CellSpace(envs.load("lab"))
    >>> step_flights(cs, Plan.parse("90° 90° 00000000 90° 90°"), 0)   # configuration 8: east
    ([0.0, 0.0, 2.72, 0.0], 0.0)
    """
    k = int(k0)
    flights, final = [], 0.0
    for zeros, angle in plan.segments():
        length = cells.run_length(k, zeros)
        if angle is None:
            final = length
        else:
            flights.append(length)
            k = int(cells.orientation_of(k * cells.delta_deg + angle))
    return flights, final
