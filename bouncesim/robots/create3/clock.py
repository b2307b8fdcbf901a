"""An asyncio event loop on emulated time, so that an SDK script and the Create 3 emulator run
in lockstep: the same poses and packets on any machine, however busy, and as fast as the CPU
allows.

:class:`VirtualTimeLoop` is a selector event loop whose :meth:`~VirtualTimeLoop.time` is an
emulated clock. Time moves only when nothing is left to do at the current instant:

- the loop is idle until its next timer (``asyncio.sleep``, the emulator's own wake-ups):
  the clock jumps to that timer;
- or the only work left is polling: tasks that yield with ``asyncio.sleep(0)`` while they
  wait, as the SDK's response completer does. After ``patience`` loop passes in a row with
  no timer due, no file descriptor ready and no :meth:`~VirtualTimeLoop.activity` (the
  emulator's backend reports every packet it carries), the clock jumps to the next timer.
  Reactions (a packet read, decoded, handled, answered) take a handful of passes and so no
  emulated time; a chain of more than ``patience`` passes without a packet would let time
  move on (raise ``patience`` for such scripts).

Computation takes no emulated time. The SDK's completers time out by the wall clock
(``time.time``), so a response that never comes still ends the wait after its timeout.

>>> import asyncio
>>> loop = VirtualTimeLoop()
>>> async def nap():
...     await asyncio.sleep(3600.0)
...     return loop.time()
>>> loop.run_until_complete(nap())
3600.0
>>> loop.close()
"""

from __future__ import annotations

import asyncio
import heapq
import itertools
import selectors

from envs import UserError

__all__ = ["VirtualTimeLoop", "Deadlock"]


class Deadlock(UserError):
    """Nothing can ever happen again: no timer, no ready task, no file descriptor."""


class _Selector(selectors.DefaultSelector):
    """The loop's selector: never blocks; advances the loop's emulated clock instead."""

    def __init__(self) -> None:
        super().__init__()
        self.loop: VirtualTimeLoop | None = None

    def select(self, timeout=None):
        ready = super().select(0)
        loop = self.loop
        if loop is None:
            return ready
        if ready:
            loop._busy = 0
            return ready
        if timeout is None:
            if not loop._wait_for_ever:
                raise Deadlock("the script waits for something that can never happen in "
                               "the emulator (no timer, no motion, no task ready).")
            return super().select(None)
        if timeout > 0:
            loop._busy = 0
            loop._now += timeout
            return ready
        loop._busy += 1
        if loop._busy >= loop.patience:
            loop._busy = 0
            nxt = loop._next_timer()
            if nxt is not None and nxt > loop._now:
                loop._now = nxt
        return ready


class VirtualTimeLoop(asyncio.SelectorEventLoop):
    """A selector event loop whose clock is emulated (see the module docstring).

    Parameters
    ----------
    patience : int
        Loop passes of pure polling after which the clock jumps to the next timer.
    start : float
        The clock's first reading [s].
    """

    def __init__(self, patience: int = 64, start: float = 0.0) -> None:
        selector = _Selector()
        super().__init__(selector)
        selector.loop = self
        self.patience = int(patience)
        self._now = float(start)
        self._busy = 0
        self._timers: list = []
        self._seq = itertools.count()
        self._wait_for_ever = False

    def activity(self) -> None:
        """Something happened (a packet went in or out): polling is not all that is left."""
        self._busy = 0

    def time(self) -> float:
        """Emulated seconds."""
        return self._now

    def call_at(self, when, callback, *args, context=None):
        """Schedule as asyncio does, and remember the timer for the clock's jumps."""
        handle = super().call_at(when, callback, *args, context=context)
        heapq.heappush(self._timers, (handle.when(), next(self._seq), handle))
        return handle

    def _next_timer(self) -> float | None:
        while self._timers and (self._timers[0][2].cancelled() or
                                self._timers[0][0] <= self._now):
            heapq.heappop(self._timers)
        return self._timers[0][0] if self._timers else None
