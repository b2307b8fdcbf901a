"""The iRobot Create 2 Open Interface (OI) at the byte level: no I/O, no clocks.

Everything here is a pure function of bytes (or a small state machine fed with bytes), so the
hardware adapter (:mod:`bouncesim.robots.create2.adapter`) and the emulator
(:mod:`bouncesim.robots.create2.emulator`) share one implementation of the protocol, and the
tests check it against the worked examples of iRobot's "Create 2 Open Interface Specification"
(docs/readme_hardware.md says how the adapter uses them).

- Commands: :func:`encode_drive`, :func:`encode_drive_direct`, :func:`encode_sensors`,
  :func:`encode_query_list`, :func:`encode_stream`, :func:`encode_pause_resume` and the
  one-byte commands (``bytes([START])`` ...). Multi-byte values are big-endian, two's
  complement.
- Sensor packets: :data:`PACKETS` (size and signedness of packets 7-58), :data:`GROUPS`
  (0, 6, 100, 101), :func:`decode_packets` (a Sensors / Query List reply, which has no header
  and no checksum) and :func:`encode_packets` (the emulator's side).
- Streams: :func:`encode_stream_frame` builds ``19, n, id1, data1…, id2, data2…, checksum``
  (all bytes sum to 0 mod 256); :class:`StreamParser` takes arbitrary chunks of a byte stream
  and returns the valid frames, resynchronising after garbage, lost bytes or a bad checksum.
- Commands as the robot sees them: :class:`CommandParser` splits a byte stream into whole
  commands (opcode + data bytes), keeping an incomplete command until its data arrives, as the
  robot does.

Examples
--------
The specification's worked examples: Drive at −200 mm/s on a 500 mm radius, and the stream
frame that answers ``[148] [2] [29] [13]`` (cliff front left signal 2 = 0x0219, virtual
wall 13 = 0):

>>> list(encode_drive(-200, 500))
[137, 255, 56, 1, 244]
>>> list(encode_stream_frame([(29, 537), (13, 0)]))
[19, 5, 29, 2, 25, 13, 0, 163]
>>> p = StreamParser([29, 13])
>>> p.feed(bytes([7, 7, 19, 5, 29, 2, 25, 13, 0, 163, 19]))
[{29: 537, 13: 0}]
>>> p.skipped
2
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = [
    "START", "RESET", "SAFE", "FULL", "STOP", "DRIVE", "DRIVE_DIRECT", "SENSORS",
    "QUERY_LIST", "STREAM", "PAUSE_RESUME", "STREAM_HEADER", "OPCODE_DATA",
    "RADIUS_STRAIGHT", "RADIUS_STRAIGHT_ALT", "RADIUS_CW", "RADIUS_CCW", "MAX_WHEEL_MM_S",
    "MAX_RADIUS_MM", "MAX_FRAME", "MODE_OFF", "MODE_PASSIVE", "MODE_SAFE", "MODE_FULL",
    "MODE_NAMES", "PACKETS", "GROUPS", "BUMP_RIGHT", "BUMP_LEFT", "WHEEL_DROP_RIGHT",
    "WHEEL_DROP_LEFT", "ANGLE_BUG_FACTOR", "PacketSpec", "OIError", "checksum",
    "expand_ids", "reply_size", "encode_drive", "encode_drive_direct", "encode_sensors",
    "encode_query_list", "encode_stream", "encode_pause_resume", "encode_packets",
    "decode_packets", "encode_stream_frame", "StreamParser", "CommandParser",
    "encoder_delta",
]

# ------------------------------------------------------------------------- opcodes
START = 128
RESET = 7
SAFE = 131
FULL = 132
STOP = 173
DRIVE = 137
DRIVE_DIRECT = 145
SENSORS = 142
QUERY_LIST = 149
STREAM = 148
PAUSE_RESUME = 150
STREAM_HEADER = 19
"""The first byte of every stream frame."""

OPCODE_DATA: dict[int, int | None] = {
    START: 0, RESET: 0, SAFE: 0, FULL: 0, STOP: 0, DRIVE: 4, DRIVE_DIRECT: 4, SENSORS: 1,
    QUERY_LIST: None, STREAM: None, PAUSE_RESUME: 1,
}
"""Data bytes after each opcode the adapter uses; None: a count byte n, then n ids."""

RADIUS_STRAIGHT = -32768       # 0x8000
RADIUS_STRAIGHT_ALT = 32767    # 0x7FFF
RADIUS_CW = -1
RADIUS_CCW = 1
MAX_WHEEL_MM_S = 500
MAX_RADIUS_MM = 2000
MAX_FRAME = 172
"""Longest stream frame the robot sends [bytes]."""

MODE_OFF, MODE_PASSIVE, MODE_SAFE, MODE_FULL = 0, 1, 2, 3
MODE_NAMES = {0: "Off", 1: "Passive", 2: "Safe", 3: "Full"}

BUMP_RIGHT, BUMP_LEFT, WHEEL_DROP_RIGHT, WHEEL_DROP_LEFT = 0x01, 0x02, 0x04, 0x08
"""Bits of packet 7."""

ANGLE_BUG_FACTOR = 0.324056
"""Firmware up to 3.4.0 reports packet 20 (angle) scaled by this factor."""


class OIError(ValueError):
    """Bytes that are not a valid Open Interface command, reply or frame."""


@dataclass(frozen=True)
class PacketSpec:
    """One sensor packet: ``size`` [bytes], ``signed`` (two's complement) and a name."""

    size: int
    signed: bool
    name: str


def _table() -> dict[int, PacketSpec]:
    u1, u2, s1, s2 = (1, False), (2, False), (1, True), (2, True)
    rows = [
        (7, u1, "bumps and wheel drops"), (8, u1, "wall"), (9, u1, "cliff left"),
        (10, u1, "cliff front left"), (11, u1, "cliff front right"), (12, u1, "cliff right"),
        (13, u1, "virtual wall"), (14, u1, "wheel overcurrents"), (15, u1, "dirt detect"),
        (16, u1, "unused"), (17, u1, "infrared omni"), (18, u1, "buttons"),
        (19, s2, "distance [mm]"), (20, s2, "angle [deg]"), (21, u1, "charging state"),
        (22, u2, "voltage [mV]"), (23, s2, "current [mA]"), (24, s1, "temperature [C]"),
        (25, u2, "battery charge [mAh]"), (26, u2, "battery capacity [mAh]"),
        (27, u2, "wall signal"), (28, u2, "cliff left signal"),
        (29, u2, "cliff front left signal"), (30, u2, "cliff front right signal"),
        (31, u2, "cliff right signal"), (32, u1, "unused"), (33, u2, "unused"),
        (34, u1, "charging sources"), (35, u1, "OI mode"), (36, u1, "song number"),
        (37, u1, "song playing"), (38, u1, "stream packets"),
        (39, s2, "requested velocity [mm/s]"), (40, s2, "requested radius [mm]"),
        (41, s2, "requested right velocity [mm/s]"),
        (42, s2, "requested left velocity [mm/s]"), (43, s2, "left encoder counts"),
        (44, s2, "right encoder counts"), (45, u1, "light bumper"),
        (46, u2, "light bump left"), (47, u2, "light bump front left"),
        (48, u2, "light bump centre left"), (49, u2, "light bump centre right"),
        (50, u2, "light bump front right"), (51, u2, "light bump right"),
        (52, u1, "infrared left"), (53, u1, "infrared right"),
        (54, s2, "left motor current [mA]"), (55, s2, "right motor current [mA]"),
        (56, s2, "main brush current [mA]"), (57, s2, "side brush current [mA]"),
        (58, u1, "stasis"),
    ]
    return {pid: PacketSpec(sz, sg, name) for pid, (sz, sg), name in rows}


PACKETS: dict[int, PacketSpec] = _table()
"""Size and signedness of the single packets 7-58."""

GROUPS: dict[int, tuple[int, ...]] = {
    0: tuple(range(7, 27)), 6: tuple(range(7, 43)), 100: tuple(range(7, 59)),
    101: tuple(range(43, 59)),
}
"""Group packets: id -> the single packets they stand for, in order."""


# ------------------------------------------------------------------------- helpers
def checksum(frame_without_checksum) -> int:
    """The byte that makes the whole frame sum to 0 mod 256.

    >>> checksum([19, 5, 29, 2, 25, 13, 0])
    163
    """
    return (-sum(frame_without_checksum)) & 0xFF


def expand_ids(ids) -> list[int]:
    """Packet ids with groups replaced by their single packets; unknown ids are an OIError."""
    out: list[int] = []
    for pid in ids:
        pid = int(pid)
        if pid in GROUPS:
            out.extend(GROUPS[pid])
        elif pid in PACKETS:
            out.append(pid)
        else:
            raise OIError(f"unknown sensor packet id {pid}.")
    return out


def reply_size(ids) -> int:
    """Bytes in the reply to a Sensors / Query List request for ``ids`` (groups allowed).

    >>> reply_size([7, 43, 44, 35]), reply_size([0]), reply_size([6]), reply_size([100])
    (6, 26, 52, 80)
    """
    return sum(PACKETS[p].size for p in expand_ids(ids))


def _int_bytes(value: int, size: int, signed: bool, what: str) -> bytes:
    try:
        return int(value).to_bytes(size, "big", signed=signed)
    except OverflowError:
        raise OIError(f"{what} {value} does not fit in {size} byte(s).") from None


def _s16(value, what: str, lo: int, hi: int) -> bytes:
    v = int(round(value))
    if not lo <= v <= hi:
        raise OIError(f"{what} {v} is outside [{lo}, {hi}].")
    return v.to_bytes(2, "big", signed=True)


def encoder_delta(new: int, old: int) -> int:
    """Signed change of a 16-bit wrapping encoder from ``old`` to ``new`` [counts].

    >>> encoder_delta(-32760, 32760), encoder_delta(100, 90), encoder_delta(32760, -32760)
    (16, 10, -16)
    """
    return ((int(new) - int(old) + 32768) & 0xFFFF) - 32768


# ------------------------------------------------------------------------- commands
def encode_drive(velocity_mm_s: float, radius_mm: int) -> bytes:
    """Drive (137): velocity [mm/s] in −500…500 and radius [mm] in −2000…2000, or one of the
    special radii (straight 0x8000 / 0x7FFF, −1 spin clockwise, 1 spin counter-clockwise).
    """
    r = int(radius_mm)
    if r not in (RADIUS_STRAIGHT, RADIUS_STRAIGHT_ALT) and not -MAX_RADIUS_MM <= r <= \
            MAX_RADIUS_MM:
        raise OIError(f"drive radius {r} mm is outside [-2000, 2000] and not a special value.")
    v = _s16(velocity_mm_s, "drive velocity [mm/s]", -MAX_WHEEL_MM_S, MAX_WHEEL_MM_S)
    return bytes([DRIVE]) + v + r.to_bytes(2, "big", signed=True)


def encode_drive_direct(right_mm_s: float, left_mm_s: float) -> bytes:
    """Drive Direct (145): **right** wheel velocity first, then left [mm/s], each −500…500.

    >>> list(encode_drive_direct(200, -200))
    [145, 0, 200, 255, 56]
    """
    return (bytes([DRIVE_DIRECT])
            + _s16(right_mm_s, "right wheel velocity [mm/s]", -MAX_WHEEL_MM_S, MAX_WHEEL_MM_S)
            + _s16(left_mm_s, "left wheel velocity [mm/s]", -MAX_WHEEL_MM_S, MAX_WHEEL_MM_S))


def encode_sensors(packet_id: int) -> bytes:
    """Sensors (142): ask once for one packet (or group)."""
    expand_ids([packet_id])
    return bytes([SENSORS, int(packet_id)])


def _id_list(opcode: int, ids) -> bytes:
    ids = [int(p) for p in ids]
    if not ids or len(ids) > 255:
        raise OIError("a packet list needs 1 to 255 ids.")
    expand_ids(ids)
    return bytes([opcode, len(ids), *ids])


def encode_query_list(ids) -> bytes:
    """Query List (149): ``[149, n, id1, …, idn]``; the reply is the data concatenated."""
    return _id_list(QUERY_LIST, ids)


def encode_stream(ids) -> bytes:
    """Stream (148): ``[148, n, id1, …, idn]``; a frame every 15 ms from then on.

    >>> list(encode_stream([29, 13]))
    [148, 2, 29, 13]
    """
    ids = [int(p) for p in ids]
    if 3 + len(ids) + reply_size(ids) > MAX_FRAME:
        raise OIError(f"a stream frame for {ids} would exceed {MAX_FRAME} bytes.")
    return _id_list(STREAM, ids)


def encode_pause_resume(resume: bool) -> bytes:
    """Pause/Resume Stream (150): ``[150, 0]`` pauses, ``[150, 1]`` resumes."""
    return bytes([PAUSE_RESUME, 1 if resume else 0])


# ------------------------------------------------------------------------- packets
def encode_packets(ids, values) -> bytes:
    """Data bytes of packets ``ids`` (groups allowed) from ``values`` (packet id -> int;
    missing packets read 0), as the robot sends them in a Sensors / Query List reply.
    """
    out = bytearray()
    for pid in expand_ids(ids):
        spec = PACKETS[pid]
        out += _int_bytes(values.get(pid, 0), spec.size, spec.signed, f"packet {pid} value")
    return bytes(out)


def decode_packets(ids, data) -> dict[int, int]:
    """Values (packet id -> int) of a Sensors / Query List reply for ``ids``. The reply has
    no header and no checksum, so its length is the only check: a wrong length is an OIError.

    >>> decode_packets([7, 43, 44], bytes([2, 0xFF, 0xFE, 0x01, 0x00]))
    {7: 2, 43: -2, 44: 256}
    """
    data = bytes(data)
    single = expand_ids(ids)
    need = sum(PACKETS[p].size for p in single)
    if len(data) != need:
        raise OIError(f"a reply for packets {list(ids)} has {need} bytes, got {len(data)}.")
    out, i = {}, 0
    for pid in single:
        spec = PACKETS[pid]
        out[pid] = int.from_bytes(data[i:i + spec.size], "big", signed=spec.signed)
        i += spec.size
    return out


def encode_stream_frame(items) -> bytes:
    """One stream frame ``19, n, id1, data1…, idk, datak…, checksum`` from (id, value) pairs
    (single packets; a group id takes a dict of its members' values).
    """
    body = bytearray()
    for pid, value in items:
        body.append(int(pid))
        if int(pid) in GROUPS:
            body += encode_packets([pid], value)
        else:
            body += encode_packets([pid], {int(pid): value})
    frame = bytearray([STREAM_HEADER, len(body)]) + body
    if len(frame) + 1 > MAX_FRAME:
        raise OIError(f"a stream frame of {len(frame) + 1} bytes exceeds {MAX_FRAME}.")
    frame.append(checksum(frame))
    return bytes(frame)


def _parse_body(body: bytes) -> dict[int, int] | None:
    """Packet values of a frame body (id, data, id, data …), or None when it does not parse."""
    out: dict[int, int] = {}
    i = 0
    while i < len(body):
        pid = body[i]
        i += 1
        if pid in GROUPS:
            members = GROUPS[pid]
        elif pid in PACKETS:
            members = (pid,)
        else:
            return None
        for m in members:
            spec = PACKETS[m]
            if i + spec.size > len(body):
                return None
            out[m] = int.from_bytes(body[i:i + spec.size], "big", signed=spec.signed)
            i += spec.size
    return out


class StreamParser:
    """Turn a byte stream from the robot into stream frames, whatever the chunking.

    A frame is accepted when it starts with 19, its length byte fits, all its bytes sum to 0
    mod 256, its body parses as (id, data) pairs and, when ``ids`` is given, it carries
    exactly those packets. Otherwise the parser drops the first byte and looks for the next 19
    (so garbage, a lost byte or a corrupted byte costs at most the frames it touches; a
    frame that happens to lie inside skipped bytes is found again, because the search
    restarts one byte after every rejected header).

    Parameters
    ----------
    ids : sequence of int, optional
        The packets the stream was asked for (groups allowed); frames with others are
        rejected.

    Attributes
    ----------
    frames : int        frames accepted so far
    skipped : int       bytes discarded while resynchronising
    bad_checksums : int candidate frames rejected by their checksum
    """

    def __init__(self, ids=None) -> None:
        self._buf = bytearray()
        self.expected = None if ids is None else frozenset(expand_ids(ids))
        self._expected_len = None if ids is None else \
            len(ids) + reply_size(ids)
        self.frames = 0
        self.skipped = 0
        self.bad_checksums = 0

    @property
    def pending(self) -> int:
        """Bytes kept for a frame that is not complete yet."""
        return len(self._buf)

    def reset(self) -> None:
        """Forget any partial frame (after flushing the port)."""
        self._buf.clear()

    def feed(self, chunk) -> list[dict[int, int]]:
        """Add bytes; return the frames completed by them (packet id -> value), in order."""
        self._buf += bytes(chunk)
        out = []
        buf = self._buf
        while True:
            start = buf.find(STREAM_HEADER)
            if start < 0:
                self.skipped += len(buf)
                buf.clear()
                break
            if start:
                self.skipped += start
                del buf[:start]
            if len(buf) < 2:
                break
            n = buf[1]
            if n == 0 or n + 3 > MAX_FRAME or (self._expected_len is not None
                                                and n != self._expected_len):
                self.skipped += 1
                del buf[0]
                continue
            if len(buf) < n + 3:
                break
            frame = bytes(buf[:n + 3])
            if sum(frame) & 0xFF:
                self.bad_checksums += 1
                self.skipped += 1
                del buf[0]
                continue
            values = _parse_body(frame[2:-1])
            if values is None or (self.expected is not None and set(values) != self.expected):
                self.skipped += 1
                del buf[0]
                continue
            del buf[:n + 3]
            self.frames += 1
            out.append(values)
        return out


class CommandParser:
    """Split the bytes the robot receives into whole commands (the emulator's side).

    ``feed`` returns a list of ``(opcode, data bytes)``; an incomplete command waits for its
    data (as on the robot, where a command with missing bytes swallows the next ones).
    Opcodes outside :data:`OPCODE_DATA` are returned with empty data, to be ignored.
    """

    def __init__(self) -> None:
        self._buf = bytearray()

    def feed(self, chunk) -> list[tuple[int, bytes]]:
        """Add received bytes; every complete (opcode, data) command so far, in order."""
        self._buf += bytes(chunk)
        out = []
        buf = self._buf
        while buf:
            op = buf[0]
            need = OPCODE_DATA.get(op, 0)
            if need is None:                       # count byte, then that many ids
                if len(buf) < 2:
                    break
                need = 1 + buf[1]
            if len(buf) < 1 + need:
                break
            out.append((op, bytes(buf[1:1 + need])))
            del buf[:1 + need]
        return out
