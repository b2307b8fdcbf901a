"""A shared clock that runs an in-process OI emulator and the Create 2 adapter in lockstep.

In real time the emulator moves its body by the wall clock, so how far a turn goes before the
adapter's stop arrives depends on how busy the host is. In lockstep the emulated time moves
only when the adapter asks it to, and only after the emulator has read every byte the adapter
wrote before asking, and the adapter goes on only after it has read every byte the emulator
wrote before the time moved. The same calls then give the same bytes and the same poses on
any machine, however loaded.

The protocol, one *advance* at a time:

1. the adapter calls :meth:`Lockstep.advance` with the number of bytes it has written so far
   and the emulated time it wants to reach (at most the next sensor period boundary);
2. the emulator reads until it has received that many bytes, obeys them, moves the body to
   the requested time, sends the stream frame due at a period boundary, and calls
   :meth:`Lockstep.complete`;
3. ``advance`` returns the number of bytes the emulator has written so far; the adapter reads
   until it has received as many.

Every byte written by either side (command, reply, frame, injected garbage) is counted, so a
lost or corrupted frame costs a reading, never a hang. Waits for the other side are bounded
in wall time (``wall_timeout``, generous: a partner that does not answer within it is gone,
not slow).

Lockstep needs the emulator in the same process as the adapter (it shares this object); the
serial bytes still go through the real transport (pty or TCP). Behaviour that needs wall time
(the watchdog, signals) is tested in real time.

Examples
--------
>>> ls = Lockstep(period=0.015)
>>> ls.now(), ls.next_frame
(0.0, 0.015)
"""

from __future__ import annotations

import math
import os
import threading

__all__ = ["Lockstep", "LockstepClosed"]


class LockstepClosed(RuntimeError):
    """The other side of the lockstep went away (closed, or silent for ``wall_timeout``)."""


class Lockstep:
    """The emulated clock and the byte counts shared by an emulator and an adapter.

    Parameters
    ----------
    period : float
        [s] between stream frames (the Create 2's 15 ms).
    wall_timeout : float
        [s] of wall time either side waits for the other before it counts as gone.
    """

    def __init__(self, period: float = 0.015, wall_timeout: float = 30.0) -> None:
        if not (math.isfinite(period) and period > 0):
            raise ValueError(f"period must be positive, got {period}.")
        self.period = float(period)
        self.wall_timeout = float(wall_timeout)
        self._cv = threading.Condition()
        self._t = 0.0                      # emulated time [s]
        self._frame = 1                    # index of the next period boundary
        self._want: tuple[int, float] | None = None   # (host bytes, until) requested
        self._robot_bytes = 0              # bytes the emulator has written so far
        self._closed = False
        self._wake_r, self._wake_w = os.pipe()
        os.set_blocking(self._wake_r, False)
        os.set_blocking(self._wake_w, False)

    # ------------------------------------------------------------------ views
    def now(self) -> float:
        """Emulated time [s]."""
        with self._cv:
            return self._t

    def reaching(self) -> float:
        """The time an advance under way is reaching (the time of a frame sent during it),
        else :meth:`now`.
        """
        with self._cv:
            return self._t if self._want is None else self._want[1]

    @property
    def next_frame(self) -> float:
        """Emulated time [s] of the next period boundary (the next stream frame)."""
        with self._cv:
            return self._frame * self.period

    @property
    def robot_bytes(self) -> int:
        """Bytes the emulator has written so far."""
        with self._cv:
            return self._robot_bytes

    @property
    def closed(self) -> bool:
        """Whether the clock was closed (no more advances)."""
        return self._closed

    # ------------------------------------------------------------------ adapter side
    def advance(self, host_bytes: int, until: float) -> int:
        """Move the emulated time to ``until`` (clipped to the next period boundary, never
        backwards) once the emulator has read ``host_bytes``; returns the bytes the emulator
        has written by then. Raises :class:`LockstepClosed` when the emulator is gone.
        """
        with self._cv:
            if self._closed:
                raise LockstepClosed("the emulator has closed")
            until = min(max(float(until), self._t), self._frame * self.period)
            self._want = (int(host_bytes), until)
            self._cv.notify_all()
            try:                                   # (under the lock: the pipe stays open)
                os.write(self._wake_w, b"!")
            except OSError:
                pass
        with self._cv:
            done = self._cv.wait_for(lambda: self._want is None or self._closed,
                                     timeout=self.wall_timeout)
            if self._closed:
                raise LockstepClosed("the emulator has closed")
            if not done:
                raise LockstepClosed(f"the emulator did not answer within "
                                     f"{self.wall_timeout:g} s")
            return self._robot_bytes

    # ------------------------------------------------------------------ emulator side
    @property
    def wake_fd(self) -> int:
        """A file descriptor that becomes readable when an advance is requested."""
        return self._wake_r

    def drain_wake(self) -> None:
        """Empty the wake pipe after the emulator has seen an advance request."""
        try:
            while os.read(self._wake_r, 64):
                pass
        except (BlockingIOError, OSError):
            pass

    def request(self) -> tuple[int, float] | None:
        """(host bytes to read first, time to reach), or None when nothing is asked."""
        with self._cv:
            return self._want

    def wrote(self, n: int) -> None:
        """The emulator wrote ``n`` more bytes."""
        if n:
            with self._cv:
                self._robot_bytes += int(n)

    def complete(self) -> bool:
        """The requested time is reached; returns True when it is a period boundary (a
        stream frame is then due, and must have been written before this call).
        """
        with self._cv:
            if self._want is None:
                return False
            self._t = self._want[1]
            boundary = self._t >= self._frame * self.period - 1e-12
            if boundary:
                self._frame += 1
            self._want = None
            self._cv.notify_all()
            return boundary

    def at_boundary(self) -> bool:
        """Whether the pending request ends on a period boundary."""
        with self._cv:
            return self._want is not None and \
                self._want[1] >= self._frame * self.period - 1e-12

    def close(self) -> None:
        """Either side is gone: wake and fail every waiter (idempotent)."""
        with self._cv:
            if self._closed:
                return
            self._closed = True
            self._cv.notify_all()
            for fd in (self._wake_w, self._wake_r):
                try:
                    os.close(fd)
                except OSError:
                    pass
