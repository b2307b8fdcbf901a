"""How the Create 2 adapter reads its sensors (mixed into
:class:`bouncesim.robots.create2.Create2Robot`).

Every sensor period (15 ms) the adapter reads :data:`SENSOR_IDS`: from a Stream (148) in a
background reader thread, or by Query List (149) on demand; in lockstep with an in-process
emulator (:mod:`bouncesim.robots.create2.lockstep`) the emulated clock advances only when a
reading is asked for. Each reading is checked: wheel drops and the OI mode (packet 35), the
link (no valid data for ``link_timeout``), stalled wheels, and the watchdog that stops a drive
command nobody is reading the sensors for.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

from ..base import RobotError
from . import oi
from .lockstep import LockstepClosed

__all__ = ["SENSOR_IDS", "SensorState", "SensingMixin"]

SENSOR_IDS = (7, 43, 44, 35)
"""Packets read every sensor period: bumps and wheel drops, encoders, OI mode."""
_MIN_WHEEL = 0.02          # [m/s] below this a wheel command is not checked for a stall
_STALL_COUNTS = 2          # encoder counts that prove a wheel turns


@dataclass(frozen=True)
class SensorState:
    """One reading of :data:`SENSOR_IDS`.

    Attributes
    ----------
    seq : int            reading number (increasing)
    t : float            adapter clock when it arrived [s]
    bump_left, bump_right, wheel_drop : bool
    left, right : int    unwrapped cumulative encoder counts
    mode : int           packet 35 as read (0 Off, 1 Passive, 2 Safe, 3 Full)
    """

    seq: int
    t: float
    bump_left: bool
    bump_right: bool
    wheel_drop: bool
    left: int
    right: int
    mode: int

_LISTEN_CAP = 0.05         # [s] a read counts at most this much towards a silent link
_LISTEN_MIN = 0.001        # [s] and at least this much (bytes that never form a frame)


class SensingMixin:
    """The sensing half of :class:`~bouncesim.robots.create2.Create2Robot`: the
    reader thread, queries, lockstep reads, link, stall and watchdog checks. It uses the
    adapter's link and state attributes and is not a robot on its own.
    """

    def _reader(self) -> None:
        """Stream mode: read frames, keep the latest state, watch the link and the wheels.

        The link counts as lost after ``link_timeout`` seconds of *listening* without a valid
        frame: each read adds the time it waited, at most ``_LISTEN_CAP``, so a reader thread
        that a busy host did not run for a while does not mistake that for a silent robot.
        """
        silent = 0.0
        while not self._closing:
            t0 = time.monotonic()
            try:
                n = self._ser.in_waiting
                chunk = self._ser.read(max(1, min(n, 4096)))
            except Exception as exc:               # noqa: BLE001 - any I/O failure
                if not self._closing:
                    self._set_fault(RobotError(f"lost the serial link to {self.port}: {exc}"),
                                    stop=True)
                return
            listened = min(time.monotonic() - t0, _LISTEN_CAP)
            framed = False
            if chunk:
                for values in self._parser.feed(chunk):
                    self._update(values)
                    framed = True
                with self._cv:
                    self._rx += len(chunk)
                    self._cv.notify_all()
            if self._ls is not None:               # lockstep: judged in robot time
                continue
            silent = 0.0 if framed else silent + max(listened, _LISTEN_MIN)
            if silent > self.link_timeout and self._fault is None:
                self._set_fault(RobotError(
                    f"no valid sensor data from {self.port} for {silent:.2f} s of listening: "
                    "lost the link; tried to stop the robot"), stop=True)
            self._check_watchdog(self.clock())

    def _watchdog_loop(self) -> None:
        """Query mode: only the watchdog runs in the background."""
        while not self._closing:
            time.sleep(0.02)
            self._check_watchdog(self.clock())

    def _check_watchdog(self, now: float) -> None:
        if self._ls is not None:                   # lockstep: time stands still unless asked
            return
        with self._cv:
            driving = self._cmd != (0, 0)
            idle = now - self._last_call
        if driving and idle > self.watchdog and self._fault is None:
            self._set_fault(RobotError(
                f"the wheels were driving while nothing read the sensors for {idle:.2f} s; "
                "stopped by the watchdog"), stop=True)

    def _update(self, values: dict) -> SensorState:
        """Take one reading; detect wheel drops, mode drops and stalls (stopping the robot)."""
        now = self.clock() if self._ls is None else self._ls.reaching()
        bits = values[7]
        raw = (values[43], values[44])
        problem = None
        with self._cv:
            if self._raw is None:
                counts = self._counts
            else:
                counts = (self._counts[0] + oi.encoder_delta(raw[0], self._raw[0]),
                          self._counts[1] + oi.encoder_delta(raw[1], self._raw[1]))
            self._raw, self._counts = raw, counts
            self._last_valid = now
            seq = 0 if self._state is None else self._state.seq + 1
            st = SensorState(seq, now, bool(bits & oi.BUMP_LEFT), bool(bits & oi.BUMP_RIGHT),
                             bool(bits & (oi.WHEEL_DROP_LEFT | oi.WHEEL_DROP_RIGHT)),
                             counts[0], counts[1], values[35])
            self._state = st
            if st.wheel_drop:
                problem = ("a wheel dropped (the robot was lifted or went over an edge); "
                           "the robot leaves Safe mode for Passive; stopped")
            elif self._mode_checked and st.mode in (oi.MODE_PASSIVE, oi.MODE_OFF):
                problem = (f"the robot dropped from {oi.MODE_NAMES[self._expected_mode]} to "
                           f"{oi.MODE_NAMES[st.mode]} mode (wheel drop, cliff or charger); "
                           "stopped")
            else:
                problem = self._stall_check(st)
            self._cv.notify_all()
        if problem is not None and self._fault is None:
            self._set_fault(RobotError(problem), stop=True)
        return st

    def _stall_check(self, st: SensorState) -> str | None:
        cmd_left, cmd_right = self._cmd[1], self._cmd[0]
        if (st.bump_left or st.bump_right) and cmd_left > 0 and cmd_right > 0:
            self._stall_mark = [(st.left, st.t), (st.right, st.t)]   # pushing a wall
            return None
        for i, (name, cmd, count) in enumerate((("left", cmd_left, st.left),
                                                ("right", cmd_right, st.right))):
            mark = self._stall_mark[i]
            if abs(cmd) < _MIN_WHEEL * 1000 or mark is None:
                continue
            if abs(count - mark[0]) >= _STALL_COUNTS:
                self._stall_mark[i] = (count, st.t)
            elif st.t - mark[1] > self.stall_time:
                return (f"the {name} wheel has not turned for {st.t - mark[1]:.2f} s while "
                        f"commanded at {cmd} mm/s (stalled or blocked); stopped")
        return None

    def _query(self, deadline: float = math.inf) -> SensorState | None:
        """Query mode: one Query List exchange, retried after a short or garbled reply; None
        when the robot clock reaches ``deadline`` before the next query is due.
        """
        if self._ls is not None:
            return self._query_lockstep(deadline)
        need = oi.reply_size(SENSOR_IDS)
        request = oi.encode_query_list(SENSOR_IDS)
        wall_period = self.spec.sensor_period / self.time_scale
        timeout = max(0.05, 4 * wall_period)
        for _ in range(3):
            wait = self._last_query + wall_period - time.monotonic()
            if wait > 0:                            # never poll faster than the robot
                left = (deadline - self.clock()) / self.time_scale
                if left <= wait:
                    time.sleep(max(left, 0.0))
                    return None
                time.sleep(wait)
            try:
                with self._wlock:
                    self._flush_input()
                    self._ser.write(request)
                    self._last_query = time.monotonic()
                    data = bytearray()
                    end = time.monotonic() + timeout
                    while len(data) < need and time.monotonic() < end:
                        data += self._ser.read(need - len(data))
                    time.sleep(0)
                    extra = self._ser.in_waiting
            except Exception as exc:                # noqa: BLE001 - any I/O failure
                err = RobotError(f"lost the serial link to {self.port}: {exc}")
                self._set_fault(err, stop=True)
                raise err from None
            if len(data) == need and not extra:
                return self._update(oi.decode_packets(SENSOR_IDS, bytes(data)))
        err = RobotError(f"no valid reply to a sensor query from {self.port} in 3 tries: "
                         "lost the link; tried to stop the robot")
        self._set_fault(err, stop=True)
        raise err

    def _query_lockstep(self, deadline: float) -> SensorState | None:
        """:meth:`_query` in lockstep: the clock moves to the next sensor period, then the
        query is asked and answered with the clock standing still.
        """
        need = oi.reply_size(SENSOR_IDS)
        request = oi.encode_query_list(SENSOR_IDS)
        for _ in range(3):
            due = self._last_query + self.spec.sensor_period
            if due > deadline:
                self._advance(deadline)
                return None
            while self.clock() < due - 1e-12:
                self._advance(due)
            self._flush_input()
            self._write(request)
            self._last_query = self.clock()
            data = self._read_until(self._advance(self.clock()))
            if len(data) == need:
                return self._update(oi.decode_packets(SENSOR_IDS, data))
        err = RobotError(f"no valid reply to a sensor query from {self.port} in 3 tries: "
                         "lost the link; tried to stop the robot")
        self._set_fault(err, stop=True)
        raise err

    def _advance(self, until: float) -> int:
        """Lockstep: move the emulated clock towards ``until`` (at most one sensor period);
        returns the bytes the emulator has written by then. A gone emulator is a lost link.
        """
        try:
            return self._ls.advance(self._tx, until)
        except LockstepClosed as exc:
            err = RobotError(f"lost the link to {self.port}: {exc}")
            self._set_fault(err)
            raise err from None

    def _next_state_lockstep(self, after: int | None, deadline: float) -> SensorState | None:
        """:meth:`_next_state` in stream mode and lockstep: read what the emulator sent, and
        move its clock to the next frame until a new reading or ``deadline`` comes.
        """
        while True:
            with self._cv:
                self._cv.wait_for(lambda: self._rx >= self._ls.robot_bytes or
                                  self._fault is not None, timeout=self._ls.wall_timeout)
                if self._fault is not None:
                    raise self._fault
                if self._rx < self._ls.robot_bytes:
                    err = RobotError(f"lost the link to {self.port}: the bytes sent did not "
                                     "arrive")
                    self._fault = err
                    raise err
                st = self._state
                self._last_call = self.clock()
                if st is not None and (after is None or st.seq > after):
                    return st
            now = self.clock()
            if now - self._last_valid > self.link_timeout:
                self._set_fault(RobotError(
                    f"no valid sensor data from {self.port} for {now - self._last_valid:.2f} s "
                    "of robot time: lost the link; tried to stop the robot"), stop=True)
                raise self._fault
            if now >= deadline:
                return None
            self._advance(min(deadline, self._ls.next_frame))

    def _next_state(self, after: int | None, deadline: float, check: bool = True
                    ) -> SensorState | None:
        """The next reading newer than ``after`` (None: any), or None once the robot clock
        passes ``deadline``. Raises the pending RobotError, if any.
        """
        with self._cv:
            self._last_call = self.clock()
        if self.sensing == "query":
            if self.clock() >= deadline:
                return None
            if check:
                self._raise_fault()
            st = self._query(deadline)
            self._raise_fault()
            return st
        if self._ls is not None:
            return self._next_state_lockstep(after, deadline)
        with self._cv:
            while True:
                if self._fault is not None:
                    raise self._fault
                st = self._state
                if st is not None and (after is None or st.seq > after):
                    self._last_call = self.clock()
                    return st
                left = (deadline - self.clock()) / self.time_scale
                if left <= 0:
                    return None
                self._cv.wait(min(left, 0.05))

    def _fresh(self, n: int = 1) -> SensorState:
        """A reading taken after this call (the ``n``-th one; the first may have been in
        flight already).
        """
        st = self._state
        seq = None if st is None else st.seq
        limit = self.clock() + max(1.0, self.link_timeout * 2)
        for _ in range(n):
            st = self._next_state(seq, limit)
            if st is None:
                err = RobotError(f"no sensor data from {self.port}: lost the link")
                self._set_fault(err, stop=True)
                raise err
            seq = st.seq
        return st
