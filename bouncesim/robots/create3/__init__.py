"""The Create 3 (and Root) over iRobot's Python SDK protocol: the packet layer
(:mod:`.packets`). The SDK (``irobot-edu-sdk``, extra ``create3``) is not needed to use it;
the tests check it against the SDK's own ``Packet``.
"""

from __future__ import annotations

from .packets import PACKET_LEN, PAYLOAD_LEN, Packet, PacketReader, bump_event, crc8, pose_of

__all__ = ["PACKET_LEN", "PAYLOAD_LEN", "Packet", "PacketReader", "bump_event", "crc8",
           "pose_of"]
