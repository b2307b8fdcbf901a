"""The Create 3 packet layer (bouncesim.robots.create3.packets) against iRobot's SDK
(``irobot-edu-sdk``, extra ``create3``): the same bytes on random packets and for every
command built here, and a stream reader that survives pieces and a corrupted byte.
"""

from __future__ import annotations

import struct

import numpy as np
import pytest

from bouncesim.robots.create3 import Packet, PacketReader, bump_event, crc8, pose_of
from envs import UserError

sdk = pytest.importorskip("irobot_edu_sdk.packet")


def _random_packets(n: int, seed: int = 0):
    rng = np.random.default_rng(seed)
    for _ in range(n):
        dev, cmd, inc = (int(v) for v in rng.integers(0, 256, 3))
        payload = bytes(rng.integers(0, 256, int(rng.integers(0, 17))).astype(np.uint8))
        yield dev, cmd, inc, payload


def test_random_packets_are_the_sdks_bytes_and_read_back():
    for dev, cmd, inc, payload in _random_packets(2000):
        ours = Packet(dev, cmd, inc, payload)
        theirs = sdk.Packet(dev, cmd, inc, payload)
        assert ours.to_bytes() == theirs.to_bytes()
        back = sdk.Packet.from_bytes(ours.to_bytes())
        assert back.check_crc() and Packet.from_bytes(theirs.to_bytes()) == ours


def test_crc_is_the_catalogued_crc8_and_a_flipped_bit_is_caught():
    assert crc8(b"123456789") == 0xF4                      # CRC-8/SMBus check value
    raw = bytearray(Packet(1, 4, 7, b"\x00\x00\x00\x64").to_bytes())
    for byte in range(19):
        for bit in range(8):
            bad = bytearray(raw)
            bad[byte] ^= 1 << bit
            with pytest.raises(UserError, match="fails its CRC"):
                Packet.from_bytes(bytes(bad))
    with pytest.raises(UserError, match="is 20 bytes"):
        Packet.from_bytes(bytes(19))
    with pytest.raises(UserError, match="at most 16 bytes"):
        Packet(1, 1, 1, bytes(17))


@pytest.mark.parametrize("ours, dev_cmd, payload", [
    (Packet.wheel_speeds(10.0, -5.55, inc=9), (1, 4), struct.pack(">ii", 100, -55)),
    (Packet.wheel_speeds(100.0, -100.0), (1, 4), struct.pack(">ii", 306, -306)),
    (Packet.move(-12.34, inc=2), (1, 8), struct.pack(">i", -123)),
    (Packet.turn(90.0, inc=3, left=True), (1, 12), struct.pack(">i", -900)),
    (Packet.turn(45.5, inc=4), (1, 12), struct.pack(">i", 455)),
    (Packet.simple(1, 16, 5), (1, 16), b""),
], ids=["speeds", "speeds capped", "move", "turn left", "turn right", "get_position"])
def test_commands_are_what_the_sdk_sends(ours, dev_cmd, payload):
    """The payloads the SDK's robot.py packs for set_wheel_speeds (cm/s -> mm/s, capped at
    the Create 3's 306 mm/s), move (cm -> mm), turn_left/right (decidegrees, positive
    clockwise) and get_position, built with the SDK's Packet.
    """
    theirs = sdk.Packet(*dev_cmd, ours.inc, payload)
    assert ours.to_bytes() == theirs.to_bytes()


def test_bump_events_and_poses_are_read_as_the_sdk_reads_them():
    for state, left, right in ((0x80, True, False), (0x40, False, True), (0xC0, True, True),
                               (0x00, False, False)):
        p = Packet(12, 0, 1, struct.pack(">IB", 123456, state))
        assert bump_event(p) == (123456, left, right)
    assert bump_event(Packet(1, 4, 0)) is None
    answer = Packet(1, 16, 8, struct.pack(">Iiih", 99, -1234, 567, -1795))
    from irobot_edu_sdk.getter_types import Pose
    pose = Pose().set_from_packet(sdk.Packet.from_bytes(answer.to_bytes()))
    assert pose_of(answer) == (pose.x, pose.y, pose.heading) == (-123.4, 56.7, -179.5)


def test_the_stream_reader_takes_pieces_and_skips_a_corrupted_packet():
    packets = [Packet(d, c, i, p) for d, c, i, p in _random_packets(40, seed=1)]
    stream = bytearray(b"".join(p.to_bytes() for p in packets))
    stream[20 * 7 + 5] ^= 0x10                             # corrupt the eighth packet
    reader, got = PacketReader(), []
    rng = np.random.default_rng(2)
    pos = 0
    while pos < len(stream):
        size = int(rng.integers(1, 45))
        got += reader.feed(bytes(stream[pos:pos + size]))
        pos += size
    assert got == packets[:7] + packets[8:]
    assert reader.dropped == 20
