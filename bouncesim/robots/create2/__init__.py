"""The iRobot Create 2 over its Open Interface (extra ``hardware``: pyserial).

- :mod:`.oi`: the protocol as pure functions of bytes (commands, packets, stream parser);
- :mod:`.adapter`: :class:`Create2Robot`, the Robot interface over a serial port, with its
  sensing (:mod:`.sensing`) and in-place turns (:mod:`.turning`);
- :mod:`.emulator`: :class:`OIEmulator`, a Create 2 on a pseudo-terminal or TCP port moving in
  the kinematic twin, with injectable faults (:mod:`.faults`), its end of the link
  (:mod:`.transport`) and an optional lockstep clock shared with the adapter
  (:mod:`.lockstep`).

pyserial is imported when an adapter opens its port.
"""

from .adapter import Create2Robot
from .emulator import OIEmulator
from .faults import FAULT_KINDS, Fault, parse_fault

__all__ = ["Create2Robot", "OIEmulator", "Fault", "FAULT_KINDS", "parse_fault"]
