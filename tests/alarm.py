"""A wall-clock alarm for tests: a hang fails the test instead of stopping the suite."""

from __future__ import annotations

import contextlib
import signal


@contextlib.contextmanager
def alarm(seconds: float, error: type[BaseException] = TimeoutError, what: str = "the test"):
    """Raise ``error`` inside the block when it runs longer than ``seconds`` of wall time."""
    def on_alarm(signum, frame):
        raise error(f"{what} took longer than {seconds:g} s: a hang")
    old = signal.signal(signal.SIGALRM, on_alarm)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)
