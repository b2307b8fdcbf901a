"""What a run policy asks the robot to do, and what it hears back (the vocabulary of the one
run loop, :func:`bouncesim.runs.execute.execute`).

A *runner* turns a policy (a plan, a mix, a feedback navigator) into a generator of moves:
it yields a move, the loop makes the robot do it and sends back a :class:`Moved`; the
generator's return value is the reason the run ended ("" when the policy finished). The
loop alone talks to the robot, checks the time limit before every drive, logs the robot's
own actions (turns, back-offs) and stops the robot whatever ends the run; a runner logs what
it reads into the moves with :class:`Note` (bumps, deviations, steps).

- :class:`Fly`: drive until the bumper closes, giving up after ``limit_m``;
- :class:`Drive`: drive ``distance_m`` by the clock (a bump stops it early);
- :class:`Turn`: turn in place by ``angle_deg`` (CCW positive);
- :class:`BackOff`: reverse ``distance_m`` by the clock (the bumper is still pressed);
- :class:`Note`: no motion, a row of the trace.

They are named tuples (cheap to make: a coverage run makes one per step).
"""

from __future__ import annotations

from typing import NamedTuple

__all__ = ["BackOff", "Drive", "Fly", "Move", "Moved", "Note", "Turn"]


class Fly(NamedTuple):
    """Drive until a bump; the run gives up after ``limit_m`` [m] without one."""

    limit_m: float


class Drive(NamedTuple):
    """Drive ``distance_m`` [m] by the clock and stop (a bump stops it early)."""

    distance_m: float


class Turn(NamedTuple):
    """Spin in place by ``angle_deg`` [deg], counter-clockwise positive (a bump by φ is a
    spin by wrap180(φ), the shorter way: docs/model.md §21).
    """

    angle_deg: float


class BackOff(NamedTuple):
    """Reverse ``distance_m`` [m] by the clock after a bump, before turning."""

    distance_m: float


class Note(NamedTuple):
    """A trace row: ``event`` and ``detail``, at ``pose`` (default: the robot's true pose)."""

    event: str
    detail: str = ""
    pose: tuple | None = None


Move = Fly | Drive | Turn | BackOff | Note


class Moved(NamedTuple):
    """What the loop sends back after a move.

    Attributes
    ----------
    event : BumpEvent or None   the drive's outcome (``bumped``, ``left``, ``right``,
                                ``elapsed`` [s]); None after a turn, a back-off or a note
    travelled : float           speed × elapsed [m] (the robot only has a clock); 0 else
    pose : tuple or None        the true pose after the move (None on hardware)
    t : float                   robot clock since the start of the run [s]
    """

    event: object
    travelled: float
    pose: tuple | None
    t: float
