"""How the Create 2 adapter turns in place (mixed into
:class:`bouncesim.robots.create2.Create2Robot`): by the clock alone, or by the wheel
encoders, either plainly (stop at the first reading within half a reading of the target) or
predictively (slow down near the target, stop early by the rotation expected while the stop
command travels, then measure the settled miss and correct it at creep speed; see
docs/readme_hardware.md, "Turns on a busy host").
"""

from __future__ import annotations

import math

from ..base import RobotError
from .sensing import SensorState

__all__ = ["TurningMixin"]

_CREEP_SPEED = 0.015       # [m/s] wheel speed at the end of a predictive turn
_SLOW_ZONE_DEG = 10.0      # [deg] predictive turns slow down over the last this many degrees
_TURN_CORRECTIONS = 3      # measured misses a predictive turn corrects at most


class TurningMixin:
    """In-place turns of :class:`~bouncesim.robots.create2.Create2Robot` (uses its
    sensing and drive methods; not a robot on its own).
    """

    def turn(self, angle_deg: float) -> None:
        """Turn in place CCW by ``angle_deg`` [deg] (negative: CW), by clock or by encoders."""
        angle = float(angle_deg)
        if not math.isfinite(angle):
            raise ValueError(f"cannot turn by {angle_deg} degrees.")
        self._raise_fault()
        if abs(angle) < 1e-9:
            return
        v = self.turn_speed if angle > 0 else -self.turn_speed      # CCW: right wheel ahead
        duration = self.spec.turn_time(angle, self.turn_speed)
        try:
            if self.turn_mode == "clock":
                self._drive_direct(v, -v)
                self.wait(duration)
                return
            if self.turn_control == "predictive":
                self._turn_predictive(angle)
                return
            start = self._fresh(1)
            target = math.radians(abs(angle))
            omega = 2 * self.turn_speed / self.spec.wheel_base
            lead = omega * self.spec.sensor_period / 2     # stop half a reading early
            mpc = self.spec.metres_per_count
            self._drive_direct(v, -v)
            limit = self.clock() + 2 * duration + 1.0
            seq = start.seq
            while True:
                st = self._next_state(seq, limit)
                if st is None:
                    raise RobotError(f"a {angle:g}° turn by encoders did not finish in "
                                     f"{2 * duration + 1.0:.1f} s; stopped")
                seq = st.seq
                turned = ((st.right - start.right) - (st.left - start.left)) * mpc / \
                    self.spec.wheel_base
                if turned * math.copysign(1.0, angle) >= target - lead:
                    return
        finally:
            self.stop()

    def _turn_predictive(self, angle: float) -> None:
        """Encoder turn that tolerates a slow host (docs/readme_hardware.md, "Turns on a busy
        host"): legs that slow down near the target and stop where the angle will be when the
        stop lands; then the settled miss is measured and corrected at creep speed.
        """
        b, mpc = self.spec.wheel_base, self.spec.metres_per_count
        sense = 1.0 if angle > 0 else -1.0
        target = math.radians(abs(angle))
        start = self._fresh(1)

        def miss(st: SensorState) -> float:
            """[rad] still to turn in the commanded sense (negative: overshot)."""
            return target - sense * ((st.right - start.right) - (st.left - start.left)) * \
                mpc / b

        st = start
        for _ in range(1 + _TURN_CORRECTIONS):
            e = miss(st)
            if abs(e) <= math.radians(self.turn_tolerance):
                return
            way = math.copysign(1.0, e)             # +1: on towards the target, -1: back
            self._turn_leg(sense * way, miss, way, st)
            st = self._settled()

    def _turn_leg(self, sense: float, miss, way: float, st: SensorState) -> None:
        """Spin in ``sense`` (+1 CCW) until ``way * miss(reading)`` [rad] is used up: full turn
        speed far from the end, slowing linearly to creep speed within the slow zone, and a
        stop issued early by the rotation expected while it travels (the reading's age plus
        half a sensor period).
        """
        b, period = self.spec.wheel_base, self.spec.sensor_period
        v_max, v_min = self.turn_speed, min(self.turn_speed, _CREEP_SPEED)
        zone = math.radians(_SLOW_ZONE_DEG)
        budget = self.spec.turn_time(math.degrees(way * miss(st)), v_max) * 2 + \
            2 * zone / (2 * v_min / b) + 1.0
        limit = self.clock() + budget
        v_cmd = 0.0
        try:
            while True:
                omega = 2 * v_cmd / b
                lead = omega * (max(self.clock() - st.t, 0.0) + period / 2)
                left = way * miss(st) - lead
                if left <= omega * period / 2:      # the next reading would come too late
                    return
                v = v_min + (v_max - v_min) * min(1.0, max(left, 0.0) / zone)
                if abs(v - v_cmd) >= 0.002:
                    self._drive_direct(sense * v, -sense * v)
                    v_cmd = v
                st = self._next_state(st.seq, limit)
                if st is None:
                    raise RobotError(f"a turn by encoders did not finish in {budget:.1f} s; "
                                     "stopped")
        finally:
            self.stop()

    def _settled(self) -> SensorState:
        """The first reading whose encoders equal the one before (at most 20 readings)."""
        prev = self._fresh(1)
        for _ in range(20):
            st = self._fresh(1)
            if (st.left, st.right) == (prev.left, prev.right):
                return st
            prev = st
        return prev
