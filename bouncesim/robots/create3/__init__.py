"""The Create 3 (and Root) over iRobot's Python SDK protocol.

- :mod:`.packets`: the packet layer (CRC-8, commands, events, a stream reader);
- :mod:`.emulator`: :class:`EmulatorBackend`, an SDK backend whose robot is the kinematic twin
  (an unmodified ``irobot-edu-sdk`` script runs against it), and :class:`Create3Emulator`;
- :mod:`.clock`: :class:`VirtualTimeLoop`, the asyncio loop of lockstep runs;
- :mod:`.adapter`: :class:`Create3Robot`, our Robot interface over any SDK backend.

The SDK (``irobot-edu-sdk``, extra ``create3``) is needed only for Bluetooth and for running
SDK scripts; the tests check the packets against its own ``Packet``.
"""

from __future__ import annotations

from .adapter import CREATE3, Create3Robot
from .clock import Deadlock, VirtualTimeLoop
from .emulator import FAULT_KINDS, Create3Emulator, Create3Fault, EmulatorBackend
from .packets import PACKET_LEN, PAYLOAD_LEN, Packet, PacketReader, bump_event, crc8, pose_of

__all__ = ["CREATE3", "FAULT_KINDS", "PACKET_LEN", "PAYLOAD_LEN", "Create3Emulator",
           "Create3Fault", "Create3Robot", "Deadlock", "EmulatorBackend", "Packet",
           "PacketReader", "VirtualTimeLoop", "bump_event", "crc8", "pose_of"]
