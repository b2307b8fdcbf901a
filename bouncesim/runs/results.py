"""The records a run returns (:func:`bouncesim.runs.execute.execute`): a plan's
:class:`PlanRun` with its :class:`Deviation` list, a mix's :class:`MixRun`, and the
:class:`SegmentDone` progress record (docs/model.md §8, §21, §13).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from planners.plan import Plan

from .trace import Trace

__all__ = ["Deviation", "MixRun", "PlanRun", "SegmentDone"]


@dataclass(frozen=True)
class Deviation:
    """A bump more than one cell length early or late (docs/model.md §21); for an exact plan
    more than h/4, the contact-bin length (§13).

    Attributes
    ----------
    segment : int        index into ``plan.segments()`` (exact plans: the flight's index)
    expected : float     planned travel: the run's length in the step model, or the exact
                         plan's expected flight [m]
    travelled : float    speed x elapsed time [m]
    kind : str           'early' or 'late'
    t : float            robot clock at the bump [s]
    """

    segment: int
    expected: float
    travelled: float
    kind: str
    t: float


@dataclass(frozen=True)
class SegmentDone:
    """What ``execute(..., on_segment=)`` reports after each plan segment: its 1-based
    ``index`` of ``total``, the drive (``travelled`` = speed x time [m], ``seconds`` [s],
    ``bumped``) and the ``turn`` after the bump [deg] (None: a trailing run of zeros).
    """

    index: int
    total: int
    travelled: float
    seconds: float
    bumped: bool
    turn: float | None

    def __str__(self) -> str:
        end = (f"bump after {self.seconds:.1f} s" if self.bumped
               else f"stop after {self.seconds:.1f} s")
        turn = "" if self.turn is None else f", turn {self.turn:g}°"
        return f"segment {self.index}/{self.total}: drive {self.travelled:.2f} m, {end}{turn}"


@dataclass(frozen=True)
class PlanRun:
    """Outcome of :func:`execute` for a plan.

    Attributes
    ----------
    plan : Plan
    success : bool or None    None when there is no goal or no true pose (hardware)
    reason : str              'reached the goal', or why not
    completed : bool          every segment was executed
    final_pose : (x [m], y [m], heading [deg]) or None
    position_error : float or None   distance from the goal cell's centre [m]
    heading_error : float or None    final minus goal heading, wrapped to (−180, 180] [deg]
    deviations : tuple of Deviation
    bumps : int
    elapsed : float           robot clock from start to end [s]
    start_pose, goal_pose : (x, y, heading) or None
    trace : Trace
    """

    plan: Plan
    success: bool | None
    reason: str
    completed: bool
    final_pose: tuple | None
    position_error: float | None
    heading_error: float | None
    deviations: tuple
    bumps: int
    elapsed: float
    start_pose: tuple | None
    goal_pose: tuple | None
    trace: Trace

    def to_json(self) -> dict:
        """The run as plain JSON types (non-finite numbers as None)."""
        def num(v):
            return None if v is None else round(float(v), 6)
        return {"plan": str(self.plan), "success": self.success, "reason": self.reason,
                "completed": self.completed,
                "final_pose": None if self.final_pose is None else
                [num(v) for v in self.final_pose],
                "position_error": num(self.position_error),
                "heading_error": num(self.heading_error),
                "deviations": [{"segment": d.segment, "expected": num(d.expected),
                                "travelled": num(d.travelled), "kind": d.kind}
                               for d in self.deviations],
                "bumps": self.bumps, "elapsed": num(self.elapsed)}


@dataclass(frozen=True)
class MixRun:
    """Outcome of :func:`execute` for a policy mix.

    Attributes
    ----------
    counts : (P,) int array or None   steps counted per free position cell (None on hardware)
    dropped : int        steps counted in no free cell
    steps : int          steps executed (may fall short of the budget when the run stopped)
    bumps : int          bump steps
    reason : str         'finished', or why the run stopped early
    epoch_angles : tuple of float     the angle drawn for each epoch [deg]
    final_pose : tuple or None
    elapsed : float      robot clock [s]
    trace : Trace
    """

    counts: np.ndarray | None
    dropped: int
    steps: int
    bumps: int
    reason: str
    epoch_angles: tuple
    final_pose: tuple | None
    elapsed: float
    trace: Trace

    @property
    def coverage(self) -> np.ndarray | None:
        """(P,) fraction of the counted steps per position cell (docs/model.md §8)."""
        if self.counts is None:
            return None
        s = self.counts.sum()
        return self.counts / s if s > 0 else self.counts.astype(float)
