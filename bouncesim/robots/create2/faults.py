"""Faults the OI emulator can inject (:class:`bouncesim.robots.create2.OIEmulator`): what a
real Create 2 and its link do wrong, scheduled in emulated time.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

from envs import UserError

__all__ = ["FAULT_KINDS", "Fault", "parse_fault"]

FAULT_KINDS = ("wheel-drop", "charger", "stall-left", "stall-right", "drop-byte", "garbage",
               "mute")
"""wheel-drop: packet 7 bits 2-3 set, Safe drops to Passive; charger: Safe or Full drops to
Passive; stall-left/right: that wheel stops turning; drop-byte: a byte of the next transmission
is lost; garbage: a burst of random bytes full of false frame headers; mute: the robot stops
talking."""


@dataclass(frozen=True)
class Fault:
    """A fault that strikes ``at`` [s] of emulated time after the first non-zero drive
    command.

    Attributes
    ----------
    kind : str      one of :data:`FAULT_KINDS`
    at : float      [s]
    """

    KINDS: ClassVar[tuple] = FAULT_KINDS
    kind: str
    at: float = 0.0

    def __post_init__(self) -> None:
        if self.kind not in self.KINDS:
            raise UserError(f"unknown fault {self.kind!r}; use one of {', '.join(self.KINDS)}.")
        if not (math.isfinite(self.at) and self.at >= 0):
            raise UserError(f"a fault time must be a non-negative number of seconds, "
                            f"got {self.at}.")


def parse_fault(text: str, cls: type = Fault) -> Fault:
    """``KIND`` or ``KIND@SECONDS`` -> :class:`Fault` (or ``cls``, a subclass with its own
    ``KINDS``).

    >>> parse_fault("wheel-drop@2.5")
    Fault(kind='wheel-drop', at=2.5)
    """
    kind, _, at = str(text).strip().partition("@")
    try:
        seconds = float(at) if at else 0.0
    except ValueError:
        raise UserError(f"a fault is KIND or KIND@SECONDS, got {text!r}.") from None
    return cls(kind, seconds)
