"""The navigation wing's one protocol and one record: :class:`Planner` and :class:`Route`.

Every planner of :data:`planners.navigation.PLANNERS` (the paper's step model, the exact
planner, the reliable planner, feedback navigation) is built as
``make_planner(name, cells, angles, **options)`` and answers ``plan(start, goal)`` with a
:class:`Route` (or None: no plan). What it needs besides the map and the angles is declared in
``needs`` (``"noise"``, ``"rng"``, ``"contact"``), so a front end asks for exactly that.
``policy(start, goal)`` is what :func:`bouncesim.runs.execute.execute` runs: an open-loop
planner's :class:`~planners.plan.Plan`, or a closed-loop policy that chooses the next turn
after each bump (feedback).

Examples
--------
>>> import envs
>>> from planners.cells import CellSpace
>>> from planners.navigation import make_planner
>>> cs = CellSpace(envs.load("lab"))
>>> route = make_planner("step", cs, [90, 135]).plan(8, 0)
>>> route.planner, str(route.plan), route.cost, route.plan.flights_m
('step', '90° 90° 00000000 90° 90°', 12.0, (0.0, 0.0, 2.72, 0.0))
>>> sorted(route.to_json())                        # one JSON form for every planner
['angles', 'angles_used', 'cost', 'exact_flights', 'final_m', 'flights_m', 'goal', 'path', \
'plan', 'plan_text', 'planner', 'poses', 'start']
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any, ClassVar, Protocol, runtime_checkable

import numpy as np

from envs import UserError

from ..cells import CellSpace
from ..plan import Plan

__all__ = ["NEEDS", "PairTable", "Planner", "Route", "check_angles", "check_config",
           "check_weights"]

NEEDS = ("noise", "rng", "contact")
"""What a planner may need besides the map, the angles and the weights: the turn noise it
plans for, a random source, and the executing body's contact rule (docs/model.md §9)."""


def _r9(v) -> float | int:
    f = round(float(v), 9)
    return int(f) if f.is_integer() else f


@dataclass(frozen=True)
class Route:
    """A plan from one configuration to another, as every planner returns it.

    Attributes
    ----------
    start, goal : int        configuration indices z
    plan : Plan              the observation string with its flights (``flights_m``,
                             ``final_m``): the exact flights of an exact plan, the step
                             model's run lengths of a step plan (``plan.exact_flights``
                             says which; docs/model.md §21, §13)
    cost : float             the planner's cost (w1 per step or step-equivalent of travel
                             and per same-angle bump, w2 per change of angle)
    poses : tuple of (x [m], y [m], heading [deg])
        The planned poses: the step model's cell-centre pose of every configuration on its
        path; an exact plan's start pose, its pose after every bump and turn, and its final
        pose.
    planner : str            the :data:`~planners.navigation.PLANNERS` name that made it
    path : tuple of int      the configurations the step model visits (start first, goal
                             last); empty for plans over exact poses
    extras : mapping         what one planner adds (the reliable planner's success
                             estimate, ...); readable as attributes (``route.p_success``)
    """

    start: int
    goal: int
    plan: Plan
    cost: float
    poses: tuple
    planner: str
    path: tuple = ()
    extras: Mapping = field(default_factory=dict, hash=False)

    def __getattr__(self, name: str) -> Any:
        if name.startswith("__"):
            raise AttributeError(name)
        try:
            return object.__getattribute__(self, "extras")[name]
        except (AttributeError, KeyError):
            raise AttributeError(f"{type(self).__name__} has no attribute {name!r}") from None

    @property
    def angles_used(self) -> int:
        """Number of distinct bouncing angles in the plan."""
        return self.plan.angles_used

    def to_json(self) -> dict:
        """The route as one JSON-ready dict, the same keys for every planner: start, goal,
        the plan's fields (:meth:`Plan.to_json`: plan, plan_text, planner, angles, flights_m,
        final_m, exact_flights), cost, angles_used, poses (rounded to 1e-9), path (the step
        model's configurations; [] otherwise), then the planner's extras.
        """
        out: dict = {"start": int(self.start), "goal": int(self.goal)}
        out.update(self.plan.to_json())
        out.update({"planner": self.planner, "cost": _r9(self.cost),
                    "angles_used": self.angles_used,
                    "poses": [[_r9(v) for v in p] for p in self.poses],
                    "path": [int(z) for z in self.path]})
        for key, value in self.extras.items():
            out[key] = _jsonable(value)
        return out

    @staticmethod
    def none_json(start: int, goal: int, planner: str) -> dict:
        """The JSON of a query without a route: :meth:`to_json`'s keys, ``plan`` None."""
        return {"start": int(start), "goal": int(goal), "plan": None, "plan_text": None,
                "planner": planner, "angles": None, "flights_m": None, "final_m": None,
                "exact_flights": None, "cost": None, "angles_used": None, "poses": None,
                "path": None}


def _jsonable(v):
    if isinstance(v, float):
        return round(v, 9) if math.isfinite(v) else None
    if isinstance(v, (tuple, list)):
        return [_jsonable(x) for x in v]
    if hasattr(v, "item"):                      # numpy scalars
        return _jsonable(v.item())
    return v


@runtime_checkable
class Planner(Protocol):
    """What every navigation planner offers (:data:`planners.navigation.PLANNERS`).

    Attributes
    ----------
    name : str                      its registry name
    needs : frozenset of str        subset of :data:`NEEDS` it is built with
    closed_loop : bool              True when it decides after every bump (its policy is
                                    not a fixed plan)
    cells : CellSpace
    angles : tuple of float         the bouncing angles Φ [deg]
    """

    name: ClassVar[str]
    needs: ClassVar[frozenset]
    closed_loop: ClassVar[bool]
    cells: CellSpace
    angles: tuple

    def plan(self, start: int, goal: int) -> Route | None:
        """The planner's route from configuration ``start`` to ``goal``, or None when its
        model has none: no sequence of its bouncing angles leads from ``start`` to ``goal``
        (the goal is not reachable from the start; with more angles, or another K, it may
        be). None is an answer, not an error: ``bouncesim plan`` prints "no path with angles
        ..." (JSON ``"plan": null``) and exits with status 3. Bad input (a configuration out
        of range) raises :class:`envs.UserError` instead.
        """

    def policy(self, start: int, goal: int):
        """What :func:`bouncesim.runs.execute.execute` runs from ``start`` to ``goal``: the
        route's plan (None when there is none), or a closed-loop policy.
        """


class PairTable:
    """What every all-pairs result shares (:class:`~planners.navigation.AllPairs`,
    :class:`~planners.navigation.ExactAllPairs`): ``weights`` (N, N) float, −1 where
    unreachable, 0 on the diagonal; ``angles_used`` (N, N) int8, −1 where unreachable or
    i == j; ``m`` the number of bouncing angles.
    """

    weights: np.ndarray
    angles_used: np.ndarray
    m: int

    @property
    def N(self) -> int:
        """Number of configurations N."""
        return int(self.weights.shape[0])

    def histogram(self) -> np.ndarray:
        """Counts of plans by number of angles used (0..m) over reachable pairs i != j."""
        used = self.angles_used[self.angles_used >= 0]
        return np.bincount(used, minlength=self.m + 1)

    @cached_property
    def reachable_fraction(self) -> float:
        """Fraction of the ordered pairs (i ≠ j) with a plan."""
        N = self.N
        return float((self.weights[~np.eye(N, dtype=bool)] >= 0).mean()) if N > 1 else 1.0


# ---------------------------------------------------------------- shared argument checks
def check_config(cells: CellSpace, z, what: str) -> int:
    """``z`` as a configuration index of ``cells``; one-sentence :class:`UserError` else."""
    try:
        zi = int(z)
    except (TypeError, ValueError, OverflowError):
        raise UserError(f"{what} {z!r} is not a configuration index.") from None
    if not 0 <= zi < cells.N:
        raise UserError(f"{what} {zi} is out of range: configurations are 0 to "
                        f"{cells.N - 1}.")
    return zi


def check_angles(cells: CellSpace, angles: Iterable[float], who: str) -> tuple:
    """The bouncing angles [deg] as floats: at least one, multiples of Δ, no repeats."""
    angles = tuple(float(a) for a in angles)
    if not angles:
        raise UserError(f"{who} needs at least one bouncing angle.")
    steps = [cells.angle_steps(a) for a in angles]
    if len(set(steps)) != len(steps):
        raise UserError(f"the bouncing angles {list(angles)} repeat an angle.")
    return angles


def check_weights(w1: float, w2: float) -> tuple[float, float]:
    """The weights (w1, w2) as positive finite floats."""
    for name, w in (("w1", w1), ("w2", w2)):
        if not (math.isfinite(w) and w > 0):
            raise UserError(f"{name} must be a positive number, got {w}.")
    return float(w1), float(w2)
