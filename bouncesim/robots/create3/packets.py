"""Packets of iRobot's robot protocol as the Python SDK speaks it to a Create 3 or a Root
(the BLE protocol, v1.5): 20 bytes, ``device, command, id``, a 16-byte payload and a CRC-8
(polynomial 0x07, initial 0, most significant bit first) over the first 19 bytes.

Our own code: the SDK (``irobot-edu-sdk``) stays an optional dependency, and
``tests/test_create3_packets.py`` checks these packets against its ``Packet`` on random ones.

Commands built here (device, command; payload big-endian):

- :meth:`Packet.wheel_speeds` (1, 4): left and right [mm/s] as ``>ii``, from cm/s, capped;
- :meth:`Packet.move` (1, 8): distance [mm] as ``>i``, from cm;
- :meth:`Packet.turn` (1, 12): angle [decidegrees] as ``>i``, **positive clockwise** (the
  SDK's ``turn_left(a)`` sends −10·a);
- :meth:`Packet.simple` for the commands without a payload: get_position (1, 16),
  reset_navigation (1, 15), stop (0, 3), disconnect (0, 6).

Events and answers read here: :func:`bump_event` (device 12, command 0: a uint32 timestamp
[ms], then the state byte, 0x80 left and 0x40 right) and :func:`pose_of` (the pose in a
move, turn or get_position answer: x and y [mm] as ``>i`` at bytes 4 and 8, the heading
[decidegrees] as ``>h`` at byte 12).

>>> p = Packet.turn(90.0, inc=3, left=True)
>>> p.device, p.command, p.inc, p.to_bytes()[3:7].hex()
(1, 12, 3, 'fffffc7c')
>>> Packet.from_bytes(p.to_bytes()) == p
True
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

from envs import UserError

__all__ = ["PACKET_LEN", "PAYLOAD_LEN", "MAX_SPEED_MM_S", "Packet", "PacketReader",
           "bump_event", "crc8", "pose_of"]

PACKET_LEN = 20
"""Bytes per packet: device, command, id, 16 payload bytes, CRC."""
PAYLOAD_LEN = 16
MAX_SPEED_MM_S = 306
"""The Create 3's top wheel speed [mm/s] (0.306 m/s); wheel speeds are capped to it."""


def _table() -> list[int]:
    out = []
    for byte in range(256):
        crc = byte
        for _ in range(8):
            crc = ((crc << 1) ^ 0x07) & 0xFF if crc & 0x80 else (crc << 1) & 0xFF
        out.append(crc)
    return out


_CRC = _table()


def crc8(data: bytes) -> int:
    """CRC-8 of ``data`` with polynomial 0x07, initial value 0, MSB first, no final XOR.

    >>> crc8(b"123456789")        # the catalogued check value of CRC-8 (SMBus)
    244
    """
    crc = 0
    for byte in bytes(data):
        crc = _CRC[crc ^ byte]
    return crc


@dataclass(frozen=True)
class Packet:
    """One packet: ``device``, ``command``, ``inc`` (the id a response repeats) in 0…255 and
    ``payload`` (at most 16 bytes, padded with zeros to 16).
    """

    device: int
    command: int
    inc: int
    payload: bytes = bytes(PAYLOAD_LEN)

    def __post_init__(self) -> None:
        for name in ("device", "command", "inc"):
            v = getattr(self, name)
            if not (isinstance(v, int) and 0 <= v <= 255):
                raise UserError(f"a packet's {name} must be a byte (0 to 255), got {v!r}.")
        payload = bytes(self.payload)
        if len(payload) > PAYLOAD_LEN:
            raise UserError(f"a packet's payload holds at most {PAYLOAD_LEN} bytes, got "
                            f"{len(payload)}.")
        object.__setattr__(self, "payload", payload + bytes(PAYLOAD_LEN - len(payload)))

    def to_bytes(self) -> bytes:
        """The 20 bytes on the wire, CRC last."""
        head = bytes([self.device, self.command, self.inc]) + self.payload
        return head + bytes([crc8(head)])

    @classmethod
    def from_bytes(cls, raw: bytes) -> Packet:
        """The packet of 20 bytes; one sentence when the length or the CRC is wrong."""
        raw = bytes(raw)
        if len(raw) != PACKET_LEN:
            raise UserError(f"a packet is {PACKET_LEN} bytes, got {len(raw)}.")
        if crc8(raw[:-1]) != raw[-1]:
            raise UserError(f"packet {raw[:3].hex()} fails its CRC ({raw[-1]:#04x}, "
                            f"computed {crc8(raw[:-1]):#04x}).")
        return cls(raw[0], raw[1], raw[2], raw[3:19])

    # ------------------------------------------------------------------ commands
    @classmethod
    def simple(cls, device: int, command: int, inc: int = 0) -> Packet:
        """A command without a payload (get_position 1/16, reset_navigation 1/15, stop 0/3,
        disconnect 0/6).
        """
        return cls(device, command, inc)

    @classmethod
    def wheel_speeds(cls, left_cm_s: float, right_cm_s: float, inc: int = 0,
                     max_mm_s: int = MAX_SPEED_MM_S) -> Packet:
        """Set wheel speeds [cm/s] (sent as whole mm/s, truncated as the SDK does, capped at
        ± ``max_mm_s``).
        """
        def mm(v):
            return min(max_mm_s, max(-max_mm_s, int(float(v) * 10)))
        return cls(1, 4, inc, struct.pack(">ii", mm(left_cm_s), mm(right_cm_s)))

    @classmethod
    def move(cls, distance_cm: float, inc: int = 0) -> Packet:
        """Drive ``distance_cm`` [cm] (negative: backwards), sent as whole mm."""
        return cls(1, 8, inc, struct.pack(">i", int(float(distance_cm) * 10)))

    @classmethod
    def turn(cls, angle_deg: float, inc: int = 0, left: bool = False) -> Packet:
        """Turn ``angle_deg`` [deg] to the right (clockwise), or to the left with ``left``,
        sent as whole decidegrees, positive clockwise.
        """
        angle = -float(angle_deg) if left else float(angle_deg)
        return cls(1, 12, inc, struct.pack(">i", int(angle * 10)))


def bump_event(packet: Packet) -> tuple[int, bool, bool] | None:
    """(timestamp [ms], left, right) of a bump event (device 12, command 0), else None."""
    if (packet.device, packet.command) != (12, 0):
        return None
    (ms,) = struct.unpack(">I", packet.payload[:4])
    state = packet.payload[4]
    return ms, bool(state & 0x80), bool(state & 0x40)


def pose_of(packet: Packet) -> tuple[float, float, float]:
    """(x [cm], y [cm], heading [deg]) in a move, turn or get_position answer (the SDK's
    units: mm and decidegrees on the wire).
    """
    x, y = struct.unpack(">ii", packet.payload[4:12])
    (h,) = struct.unpack(">h", packet.payload[12:14])
    return x / 10, y / 10, h / 10


class PacketReader:
    """Packets from a byte stream that arrives in pieces of any size (a serial line or a
    socket): :meth:`feed` bytes, get the complete packets so far. A packet that fails its CRC
    drops its first byte and the reader looks for the next packet one byte later
    (``dropped`` counts those bytes), so a corrupted byte costs its packet, not the stream
    (a shifted window passes the CRC by chance about once in 256; then the packet after it
    is lost too before the reader is back in step).
    """

    def __init__(self) -> None:
        self._buf = bytearray()
        self.dropped = 0

    def feed(self, data: bytes) -> list[Packet]:
        """The complete packets in the stream after ``data``."""
        self._buf.extend(data)
        out = []
        while len(self._buf) >= PACKET_LEN:
            raw = bytes(self._buf[:PACKET_LEN])
            if crc8(raw[:-1]) == raw[-1]:
                out.append(Packet.from_bytes(raw))
                del self._buf[:PACKET_LEN]
            else:
                del self._buf[0]
                self.dropped += 1
        return out
