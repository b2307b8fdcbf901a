"""The tasks of the learning environments, without gymnasium: the goal rule of a flight
(navigate) and the counted steps of a flight (cover), docs/model.md §23.

:mod:`bouncesim.gym` (one robot) and :mod:`bouncesim.team` (a team) both use them, so a
team's robot reaches its goal and counts its visits exactly as ``bouncesim/Bounce-v0`` does.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from envs import UserError
from envs.motion import flight_steps, unit
from planners.cells import CellSpace
from planners.coverage.targets import load_target, uniform_target
from planners.measures import heading_ok

__all__ = ["check_goal", "check_task", "cover_target", "flight_reaches", "goal_stop",
           "flight_cells", "start_pose"]


def check_goal(cells: CellSpace, goal) -> int:
    """A navigate task's goal: a configuration index z of ``cells`` (one sentence otherwise).

    >>> import envs
    >>> check_goal(CellSpace(envs.load("lab")), 999)
    Traceback (most recent call last):
    ...
    envs.errors.UserError: goal 999 is out of range: configurations are 0 to 383.
    """
    try:
        z = int(goal)
    except (TypeError, ValueError):
        raise UserError(f"goal {goal!r} is not a configuration index.") from None
    if not 0 <= z < cells.N:
        raise UserError(f"goal {z} is out of range: configurations are 0 to {cells.N - 1}.")
    return z


def check_task(cells: CellSpace, angles, noise, max_steps, step_cost, speed) -> tuple:
    """A learning environment's common settings, checked (one sentence otherwise):
    (angles [deg] as floats, the noise model, max_steps, step_cost, speed [m/s]).
    """
    from .robots.base import CREATE2
    from .robots.noise import parse_noise
    angles = tuple(float(a) for a in angles)
    if not angles or len(set(angles)) != len(angles):
        raise UserError("the bouncing angles must be one or more distinct angles.")
    for a in angles:
        cells.angle_steps(a)
    noise = parse_noise(noise, cells.delta_deg) if isinstance(noise, str) else noise
    steps = int(max_steps)
    if steps < 1:
        raise UserError(f"max_steps must be at least 1, got {max_steps}.")
    cost = float(step_cost)
    if not math.isfinite(cost):
        raise UserError(f"the step cost must be a finite number, got {step_cost}.")
    v = float(speed)
    if not (math.isfinite(v) and 0 < v <= CREATE2.max_wheel_speed):
        raise UserError(f"speed must lie in (0, {CREATE2.max_wheel_speed:g}] m/s, got "
                        f"{speed}.")
    return angles, noise, steps, cost, v


def start_pose(cells: CellSpace, start) -> tuple[float, float, float]:
    """A robot's start, a configuration z or a pose (x [m], y [m], heading [deg]), as a pose
    (one sentence when it is out of range or the robot does not fit there).
    """
    if isinstance(start, (int, np.integer)):
        if not 0 <= int(start) < cells.N:
            raise UserError(f"start {int(start)} is out of range: configurations are 0 to "
                            f"{cells.N - 1}.")
        return cells.pose(int(start))
    try:
        x, y, h = (float(v) for v in start)
    except (TypeError, ValueError):
        raise UserError("a start must be a configuration index or a pose "
                        "(x, y, heading).") from None
    if not cells.env.points_free([[x, y]])[0]:
        raise UserError(f"the robot does not fit at the start ({x:g}, {y:g}).")
    return x, y, h


def cover_target(cells: CellSpace, target) -> np.ndarray:
    """A cover task's target over the P position cells, summing to 1: uniform (None), a
    target file (docs/model.md §17) or P non-negative weights.
    """
    if target is None:
        return uniform_target(cells)
    if isinstance(target, (str, Path)):
        return load_target(target, cells)
    b = np.asarray(target, dtype=float).ravel()
    if b.shape != (cells.P,) or not np.all(np.isfinite(b)) or (b < 0).any() \
            or not b.sum() > 0:
        raise UserError(f"the target must be {cells.P} non-negative weights with a "
                        "positive sum, one per position cell.")
    return b / b.sum()


def flight_reaches(start_xy, end_xy, heading_deg: float, cells: CellSpace, goal: int) -> bool:
    """Whether a straight flight reaches goal configuration ``goal`` (docs/model.md §23):
    :func:`goal_stop` is not None.

    True when the flight's heading [deg] is within ±(Δ/2 + 1e-9°) of the goal heading and the
    segment from ``start_xy`` to ``end_xy`` [m] meets the goal's position cell, a half-open
    square as in docs/model.md §4 (its left and bottom borders belong to it).

    >>> import envs
    >>> cs = CellSpace(envs.load("lab"))
    >>> flight_reaches((2.89, 0.17), (0.17, 0.17), 180.0, cs, cs.z(0, 4))   # west, row 0
    True
    >>> flight_reaches((2.89, 0.17), (0.34, 0.17), 180.0, cs, cs.z(0, 4))   # at its right border
    False
    >>> flight_reaches((2.89, 0.17), (0.34, 0.17), 180.0, cs, cs.z(1, 4))   # cell 1's left border
    True
    >>> flight_reaches((2.89, 0.17), (0.35, 0.17), 180.0, cs, cs.z(0, 4))   # short of it
    False
    >>> flight_reaches((2.89, 0.17), (0.17, 0.17), 135.0, cs, cs.z(0, 4))   # wrong heading
    False
    """
    return goal_stop(start_xy, end_xy, heading_deg, cells, goal) is not None


def goal_stop(start_xy, end_xy, heading_deg: float, cells: CellSpace,
              goal: int) -> np.ndarray | None:
    """Where a robot on this flight stops in the goal configuration's cell (docs/model.md
    §23): the midpoint of the part of the segment in the cell, the point farthest from its
    borders along the flight; None when the flight does not reach the goal.

    >>> import envs
    >>> cs = CellSpace(envs.load("lab"))
    >>> goal_stop((2.89, 0.17), (0.17, 0.17), 180.0, cs, cs.z(1, 4)).round(6).tolist()
    [0.51, 0.17]
    >>> goal_stop((2.89, 0.17), (0.17, 0.17), 180.0, cs, cs.z(0, 4)).round(6).tolist()
    [0.255, 0.17]

    In cell 0 the flight ends at the wall, x = 0.17 m: it stops half-way through the part
    of the cell it crosses.
    """
    p, k = (int(v) for v in cells.pk(int(goal)))
    if not heading_ok(heading_deg, k * cells.delta_deg, cells.delta_deg):
        return None
    h = cells.h
    cx, cy = cells.centres[p]
    lo = np.array([cx - h / 2, cy - h / 2])
    hi = lo + h
    a = np.asarray(start_xy, dtype=float)
    b = np.asarray(end_xy, dtype=float)
    d = b - a
    t0, t1 = 0.0, 1.0                       # Liang-Barsky clip of the segment to the square
    for i in range(2):
        if d[i] == 0.0:
            if not lo[i] <= a[i] <= hi[i]:
                return None
            continue
        ta, tb = (lo[i] - a[i]) / d[i], (hi[i] - a[i]) / d[i]
        t0, t1 = max(t0, min(ta, tb)), min(t1, max(ta, tb))
    if t0 > t1:
        return None
    # the clipped part may only touch the square's right or top border, which belongs to the
    # neighbouring cell: its midpoint decides with the §4 point -> cell rule
    def at(t: float) -> np.ndarray:         # the end points exactly, not a + d rounded
        return a if t == 0.0 else b if t == 1.0 else a + t * d

    mid = 0.5 * (at(t0) + at(t1))
    return mid if int(cells.cell_of_point([mid])[0]) == p else None


def flight_cells(cells: CellSpace, before, after) -> np.ndarray:
    """The position cells of a flight's counted steps (docs/model.md §8, §23): n forward
    steps, the l-th at start + l·h·u, then one bump step at the end; −1 where a point lies in
    no free cell (a dropped step).

    ``before`` is the pose (x [m], y [m], heading [deg]) at the start of the flight, ``after``
    its end point (x, y, ...) [m].

    >>> import envs
    >>> cs = CellSpace(envs.load("lab"))
    >>> flight_cells(cs, (0.17, 0.17, 0.0), (2.89, 0.17)).tolist()   # 8 steps, the bump in 8
    [0, 1, 2, 3, 4, 5, 6, 7, 8]
    """
    x, y, deg = before[:3]
    u = unit(np.array([deg]))[0]            # the twin's unit vectors, axes exact
    length = math.hypot(after[0] - x, after[1] - y)
    n = int(flight_steps(length, cells.h))
    pts = np.vstack([np.array([x, y]) + np.arange(n)[:, None] * cells.h * u, [after[:2]]])
    return cells.cell_of_point(pts)
