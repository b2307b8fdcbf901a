"""Alarms for tests: a hang fails the test instead of stopping the suite."""

from __future__ import annotations

import contextlib
import signal

# clock -> (timer, signal, what the time is)
_CLOCKS = {"wall": (signal.ITIMER_REAL, signal.SIGALRM, "s"),
           "cpu": (signal.ITIMER_PROF, signal.SIGPROF, "s of CPU")}


@contextlib.contextmanager
def alarm(seconds: float, error: type[BaseException] = TimeoutError, what: str = "the test",
          clock: str = "wall"):
    """Raise ``error`` inside the block when it runs longer than ``seconds``.

    ``clock="wall"`` counts wall time; ``clock="cpu"`` counts the process's CPU time (all
    threads), which a busy machine does not inflate: a spinning hang trips it, a blocked one
    needs a wall-clock alarm as well.
    """
    timer, signum, unit = _CLOCKS[clock]

    def on_alarm(signum, frame):
        raise error(f"{what} took longer than {seconds:g} {unit}: a hang")
    old = signal.signal(signum, on_alarm)
    signal.setitimer(timer, seconds)
    try:
        yield
    finally:
        signal.setitimer(timer, 0)
        signal.signal(signum, old)
