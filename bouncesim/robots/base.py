"""The one Robot interface: only what a bump-and-clock robot has (ARCHITECTURE "one Robot
interface, three bodies").

The execution loop (:func:`bouncesim.runs.execute.execute`) uses nothing but these methods, so
the same code drives the kinematic twin, the PyBullet Create 2 and a real Create 2 over its Open
Interface. Poses (:meth:`Robot.true_pose`) exist for logging in simulation only and are never
used for control.

Units: metres, seconds, degrees (angles at this interface), CCW positive.
"""

from __future__ import annotations

import math
import signal
import threading
from abc import ABC, abstractmethod
from dataclasses import dataclass

from envs import UserError

__all__ = ["CREATE2", "BumpEvent", "EmulatedDeclarations", "Robot", "RobotError", "RobotSpec",
           "SigtermStop"]


class RobotError(RuntimeError):
    """A robot that cannot go on (lost link, stuck, dropped out of Safe mode, ...)."""


@dataclass(frozen=True)
class RobotSpec:
    """Body and drive figures of a differential-drive disk robot.

    Attributes
    ----------
    radius : float            body radius [m]
    wheel_base : float        distance between the drive wheels [m]
    wheel_diameter : float    [m]
    counts_per_rev : float    encoder counts per wheel revolution
    max_wheel_speed : float   [m/s]
    sensor_period : float     bumper/encoder polling period [s]
    mass : float              [kg]
    """

    radius: float = 0.17
    wheel_base: float = 0.235
    wheel_diameter: float = 0.072
    counts_per_rev: float = 508.8
    max_wheel_speed: float = 0.5
    sensor_period: float = 0.015
    mass: float = 3.5

    @property
    def metres_per_count(self) -> float:
        """Wheel travel per encoder count [m]."""
        return math.pi * self.wheel_diameter / self.counts_per_rev

    def check_speed(self, speed: float) -> float:
        """``speed`` [m/s] as a float, or one sentence when it is not finite or beyond the
        wheel limit (a drive of every body checks it the same way).
        """
        speed = float(speed)
        if not math.isfinite(speed) or abs(speed) > self.max_wheel_speed + 1e-12:
            raise UserError(f"speed {speed:g} m/s is beyond the robot's "
                            f"{self.max_wheel_speed:g} m/s wheel limit.")
        return speed

    def turn_time(self, angle_deg: float, wheel_speed: float) -> float:
        """Time [s] to turn in place by |angle| at wheel speeds ±wheel_speed [m/s] (by clock)."""
        omega = 2 * wheel_speed / self.wheel_base
        return abs(math.radians(angle_deg)) / omega


CREATE2 = RobotSpec()
"""The iRobot Create 2 (figures from its Open Interface specification)."""


@dataclass(frozen=True)
class BumpEvent:
    """Outcome of :meth:`Robot.drive_until_bump`.

    Attributes
    ----------
    bumped : bool     the bumper closed (False: the timeout ran out first)
    left, right : bool  which side(s) of the bumper closed
    elapsed : float   time spent driving [s]
    """

    bumped: bool
    left: bool
    right: bool
    elapsed: float


class Robot(ABC):
    """A bump-and-clock robot.

    Backends implement the abstract methods; :meth:`drive_until_bump` has a polling default
    that any backend may replace by an exact or faster equivalent with the same meaning.
    """

    spec: RobotSpec = CREATE2
    env = None
    """The room the robot is in (an :class:`envs.Environment`): simulators move in it, and
    :func:`bouncesim.runs.execute.execute` builds its cells from it. None when the robot does
    not know it (pass the cells to ``execute`` then); :func:`bouncesim.robots.make_robot` sets
    it for the Create 2 to the environment it was given."""

    # -------------------------------------------------------------- what the robot has
    @abstractmethod
    def drive(self, speed: float) -> None:
        """Start driving straight at ``speed`` [m/s] (negative: backwards) until told otherwise."""

    @abstractmethod
    def stop(self) -> None:
        """Stop both wheels."""

    @abstractmethod
    def bumper(self) -> tuple[bool, bool]:
        """(left, right) bumper state now."""

    @abstractmethod
    def clock(self) -> float:
        """Time [s] since the robot was started (simulated time in simulation)."""

    @abstractmethod
    def wait(self, duration: float) -> None:
        """Let ``duration`` [s] pass with the current drive command (simulators step physics)."""

    @abstractmethod
    def turn(self, angle_deg: float) -> None:
        """Turn in place CCW by ``angle_deg`` [deg] (blocking), by clock or by encoders as the
        backend is configured. Simulators add their seeded rotation noise here.
        """

    def encoders(self) -> tuple[int, int] | None:
        """(left, right) cumulative wheel encoder counts, or None where there are none."""
        return None

    def close(self) -> None:
        """Stop and release the robot (idempotent)."""
        self.stop()

    # -------------------------------------------------------------- composite behaviour
    def drive_until_bump(self, speed: float, timeout: float) -> BumpEvent:
        """Drive forward at ``speed`` [m/s] until the bumper closes or ``timeout`` [s] passes,
        then stop. Polls the bumper every sensor period.
        """
        t0 = self.clock()
        self.drive(speed)
        try:
            while True:
                left, right = self.bumper()
                elapsed = self.clock() - t0
                if left or right:
                    return BumpEvent(True, left, right, elapsed)
                if elapsed >= timeout:
                    return BumpEvent(False, False, False, elapsed)
                self.wait(min(self.spec.sensor_period, max(timeout - elapsed, 1e-6)))
        finally:
            self.stop()

    def drive_for(self, speed: float, duration: float) -> BumpEvent:
        """Drive at ``speed`` [m/s] for ``duration`` [s] by the clock, stopping early on a bump."""
        return self.drive_until_bump(speed, duration)

    # -------------------------------------------------------------- simulation only
    def place(self, x: float, y: float, heading_deg: float) -> None:
        """Put the robot at a pose (simulators; on hardware a person places the robot)."""
        raise NotImplementedError(f"{type(self).__name__} cannot be placed by software.")

    def true_pose(self) -> tuple[float, float, float] | None:
        """(x [m], y [m], heading [deg]) for logging in simulation; None on hardware."""
        return None

    def __enter__(self) -> Robot:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


class EmulatedDeclarations:
    """For hardware adapters: on an emulator, what the emulated body declares of itself (its
    contact rule, docs/model.md §9, and its turn errors, §15); on a real robot nothing, which
    a user declares with ``--contact`` and ``--noise``. An adapter says where its emulator is
    (:meth:`_emulator`).
    """

    def _emulator(self):
        """The emulator the adapter drives, or None on a real robot."""
        return None

    @property
    def contact(self):
        """The emulated body's contact rule (None on a real robot): what the feedback filter
        assumes.
        """
        return self._emulated("contact")

    @property
    def turn_errors(self):
        """The emulated body's declared turn errors (None on a real robot)."""
        return self._emulated("turn_errors")

    def _emulated(self, name: str):
        """The emulated body's attribute ``name`` (None on a real robot or when it has none)."""
        emulator = self._emulator()
        return None if emulator is None else getattr(emulator.body, name, None)


class SigtermStop:
    """For hardware adapters: SIGTERM (a process manager, ``kill``) ends the program through
    SystemExit(143), so that the adapter's ``with`` block and ``close`` stop the robot, as
    Ctrl-C does. Installed only in the main thread and only over the default handler;
    :meth:`_on_sigterm` may stop the wheels at once first (when that is safe to do from a
    signal handler).
    """

    _prev_sigterm = None
    _sigterm_handler = None

    def _on_sigterm(self) -> None:
        """Called first in the handler (default: nothing)."""

    def _install_sigterm(self) -> None:
        if threading.current_thread() is not threading.main_thread():
            return
        if signal.getsignal(signal.SIGTERM) not in (signal.SIG_DFL, None):
            return

        def on_sigterm(signum, frame):
            self._on_sigterm()
            raise SystemExit(128 + signum)

        self._prev_sigterm = signal.getsignal(signal.SIGTERM)
        self._sigterm_handler = on_sigterm
        signal.signal(signal.SIGTERM, on_sigterm)

    def _restore_sigterm(self) -> None:
        if self._prev_sigterm is None:
            return
        try:
            if signal.getsignal(signal.SIGTERM) is self._sigterm_handler:
                signal.signal(signal.SIGTERM, self._prev_sigterm)
        except ValueError:                        # not the main thread
            pass
        self._prev_sigterm = None
