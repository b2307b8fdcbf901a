"""A body whose bump sensor lies now and then: any simulated :class:`~bouncesim.robots.base.Robot`
wrapped with the sensor faults of docs/model.md §15, at given rates.

- **Wrong side** (``p_side``): a bump reports one of the two other bumper readings (left,
  right, both), chosen uniformly.
- **Missed bump** (``p_miss``): the body stops at the wall as usual, but the bumper stays open;
  the robot pushes on (without moving) until the drive's timeout, and the drive returns
  "no bump" after the whole timeout.
- **Phantom bump** (``p_phantom``): the bumper closes in free space, at a distance uniform over
  the flight the body would have flown, with a uniformly chosen reading. The body flies the
  real flight, is put back at its start and flies the phantom's share (so it needs
  ``place``/``true_pose``: a simulator).

At most one fault strikes a drive; the three rates must sum below 1. Time spent pushing on is
added to the clock; a phantom's rewound flight is taken off it, so the clock reads what a real
robot's would. Everything else (turns, waits, poses) is the wrapped body's.

>>> from envs import load
>>> from bouncesim.robots.kinematic import KinematicRobot
>>> import numpy as np
>>> env = load("lab", orientations=8)
>>> body = FaultyRobot(KinematicRobot(env), p_miss=1.0, rng=np.random.default_rng(0))
>>> body.place(0.5, 0.5, 180.0)
>>> ev = body.drive_until_bump(0.2, 20.0)
>>> ev.bumped, round(ev.elapsed, 6), [round(v, 3) for v in body.true_pose()[:2]]
(False, 20.0, [0.17, 0.5])
"""

from __future__ import annotations

import math

import numpy as np

from envs import UserError

from .base import BumpEvent, Robot

__all__ = ["FaultyRobot"]

READINGS = ((True, False), (False, True), (True, True))
"""The bumper readings a bump can give: left, right, both."""


class FaultyRobot(Robot):
    """``body`` with sensor faults at the given per-drive rates.

    Parameters
    ----------
    body : Robot          a simulated body (the kinematic twin, PyBullet, the Create 2 emulator)
    p_side : float        probability that a bump's side reading is wrong
    p_miss : float        probability that a bump is missed (pushes on until the timeout)
    p_phantom : float     probability that a drive ends in a phantom bump
    rng : numpy.random.Generator   draws the faults (required when any rate is positive)
    """

    def __init__(self, body: Robot, *, p_side: float = 0.0, p_miss: float = 0.0,
                 p_phantom: float = 0.0, rng: np.random.Generator | None = None) -> None:
        rates = {"p_side": p_side, "p_miss": p_miss, "p_phantom": p_phantom}
        for name, p in rates.items():
            if not (isinstance(p, (int, float)) and math.isfinite(p) and 0 <= p <= 1):
                raise UserError(f"{name} must be a probability in [0, 1], got {p!r}.")
        if p_miss + p_phantom > 1:
            raise UserError("p_miss + p_phantom must not exceed 1 (one fault per drive).")
        if any(rates.values()) and rng is None:
            raise UserError("a FaultyRobot with faults needs an rng (numpy Generator).")
        if p_phantom and body.true_pose() is None:
            raise UserError("phantom bumps need a simulated body (one with place/true_pose).")
        self.body = body
        self.p_side, self.p_miss, self.p_phantom = float(p_side), float(p_miss), float(p_phantom)
        self.rng = rng
        self.spec = body.spec
        self.env = body.env
        self._extra = 0.0             # [s] clock correction: pushing on, rewound phantoms
        self.faults = {"side": 0, "miss": 0, "phantom": 0}
        """How many faults of each kind struck so far."""

    # ------------------------------------------------------------------ pass-through
    @property
    def contact(self):
        """The wrapped body's declared contact rule (docs/model.md §9), if any."""
        return getattr(self.body, "contact", None)

    @property
    def turn_errors(self):
        """The wrapped body's declared turn errors (a noise spec), if any."""
        return getattr(self.body, "turn_errors", None)

    def contact_at(self, speed: float | None):
        """The wrapped body's contact rule at drive ``speed`` (its ``contact_at``, else its
        ``contact``).
        """
        at = getattr(self.body, "contact_at", None)
        return at(speed) if callable(at) else self.contact

    def turn_errors_at(self, speed: float | None):
        """The wrapped body's turn errors after a bump at ``speed`` (its ``turn_errors_at``,
        else its ``turn_errors``).
        """
        at = getattr(self.body, "turn_errors_at", None)
        return at(speed) if callable(at) else self.turn_errors

    def drive(self, speed: float) -> None:
        """The wrapped body's ``drive``."""
        self.body.drive(speed)

    def stop(self) -> None:
        """The wrapped body's ``stop``."""
        self.body.stop()

    def bumper(self) -> tuple[bool, bool]:
        """The wrapped body's ``bumper``."""
        return self.body.bumper()

    def clock(self) -> float:
        """The wrapped body's ``clock``."""
        return self.body.clock() + self._extra

    def wait(self, duration: float) -> None:
        """The wrapped body's ``wait``."""
        self.body.wait(duration)

    def turn(self, angle_deg: float) -> None:
        """The wrapped body's ``turn``."""
        self.body.turn(angle_deg)

    def encoders(self) -> tuple[int, int] | None:
        """The wrapped body's ``encoders``."""
        return self.body.encoders()

    def close(self) -> None:
        """The wrapped body's ``close``."""
        self.body.close()

    def place(self, x: float, y: float, heading_deg: float) -> None:
        """The wrapped body's ``place``."""
        self.body.place(x, y, heading_deg)

    def true_pose(self) -> tuple[float, float, float] | None:
        """The wrapped body's ``true_pose``."""
        return self.body.true_pose()

    # ------------------------------------------------------------------ the faults
    def _other_reading(self, left: bool, right: bool) -> tuple[bool, bool]:
        others = [r for r in READINGS if r != (bool(left), bool(right))]
        return others[int(self.rng.integers(len(others)))]

    def drive_until_bump(self, speed: float, timeout: float) -> BumpEvent:
        """The body's drive, with at most one fault drawn for it."""
        if not (self.p_side or self.p_miss or self.p_phantom):
            return self.body.drive_until_bump(speed, timeout)
        u = float(self.rng.random())
        start = self.body.true_pose() if self.p_phantom else None
        ev = self.body.drive_until_bump(speed, timeout)
        if u < self.p_phantom and speed > 0 and ev.elapsed > 0:
            share = float(self.rng.random()) * ev.elapsed
            self.body.place(*start)
            self._extra -= ev.elapsed
            self.body.drive_for(speed, share)
            self.faults["phantom"] += 1
            left, right = READINGS[int(self.rng.integers(len(READINGS)))]
            return BumpEvent(True, left, right, share)
        if not ev.bumped:
            return ev
        if u < self.p_phantom + self.p_miss:
            self._extra += max(float(timeout) - ev.elapsed, 0.0)
            self.faults["miss"] += 1
            return BumpEvent(False, False, False, max(float(timeout), ev.elapsed))
        if float(self.rng.random()) < self.p_side:
            self.faults["side"] += 1
            left, right = self._other_reading(ev.left, ev.right)
            return BumpEvent(True, left, right, ev.elapsed)
        return ev

    def __repr__(self) -> str:
        return (f"FaultyRobot({self.body!r}, p_side={self.p_side}, p_miss={self.p_miss}, "
                f"p_phantom={self.p_phantom})")
