"""The byte-level Open Interface layer (bouncesim.robots.create2.oi) against the specification's
worked examples, hand-computed frames, and property tests of the stream parser's
resynchronisation.
"""

from __future__ import annotations

import doctest

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bouncesim.robots.create2 import oi

IDS = [7, 43, 44, 35]


# ---------------------------------------------------------------- the spec's examples
def test_drive_example_from_the_spec():
    # "Drive −200 mm/s at radius 500 mm": [137] [255] [56] [1] [244]
    assert list(oi.encode_drive(-200, 500)) == [137, 255, 56, 1, 244]


def test_stream_request_and_answer_from_the_spec():
    # Stream [148] [2] [29] [13] answers 19 5 29 2 25 13 0 163:
    # cliff front left signal (29) = 0x0219 = 537, virtual wall (13) = 0
    assert list(oi.encode_stream([29, 13])) == [148, 2, 29, 13]
    frame = bytes([19, 5, 29, 2, 25, 13, 0, 163])
    assert oi.encode_stream_frame([(29, 537), (13, 0)]) == frame
    assert sum(frame) % 256 == 0
    assert oi.StreamParser([29, 13]).feed(frame) == [{29: 537, 13: 0}]
    assert oi.StreamParser().feed(frame) == [{29: 537, 13: 0}]


def test_special_radii_and_drive_direct_order():
    assert list(oi.encode_drive(100, oi.RADIUS_STRAIGHT)) == [137, 0, 100, 0x80, 0x00]
    assert list(oi.encode_drive(100, oi.RADIUS_CCW)) == [137, 0, 100, 0, 1]
    assert list(oi.encode_drive(100, oi.RADIUS_CW)) == [137, 0, 100, 0xFF, 0xFF]
    # Drive Direct takes the RIGHT wheel first: right +100 = 0x0064, left -50 = 0xFFCE
    assert list(oi.encode_drive_direct(100, -50)) == [145, 0x00, 0x64, 0xFF, 0xCE]
    assert list(oi.encode_drive_direct(0, 0)) == [145, 0, 0, 0, 0]


@pytest.mark.parametrize("bad", [lambda: oi.encode_drive_direct(501, 0),
                                 lambda: oi.encode_drive_direct(0, -501),
                                 lambda: oi.encode_drive(-600, 100),
                                 lambda: oi.encode_drive(100, 2001),
                                 lambda: oi.encode_sensors(99),
                                 lambda: oi.encode_query_list([]),
                                 lambda: oi.encode_stream([100, 100, 100])])
def test_out_of_range_commands_are_refused(bad):
    with pytest.raises(oi.OIError):
        bad()


def test_query_list_and_sensors_requests():
    assert list(oi.encode_query_list(IDS)) == [149, 4, 7, 43, 44, 35]
    assert list(oi.encode_sensors(7)) == [142, 7]
    assert list(oi.encode_pause_resume(False)) == [150, 0]
    assert list(oi.encode_pause_resume(True)) == [150, 1]


def test_group_sizes_match_the_spec():
    # the spec's table: group 0 = 26 bytes, 6 = 52, 100 = 80, 101 = 28
    assert [oi.reply_size([g]) for g in (0, 6, 100, 101)] == [26, 52, 80, 28]
    assert oi.reply_size(IDS) == 1 + 2 + 2 + 1


def test_decode_hand_made_reply():
    # bumps: left + right wheel drop (0b1010 = 10); left encoder -2 (FF FE); right 300 (01 2C);
    # mode Safe (2)
    data = bytes([10, 0xFF, 0xFE, 0x01, 0x2C, 2])
    assert oi.decode_packets(IDS, data) == {7: 10, 43: -2, 44: 300, 35: 2}
    assert oi.encode_packets(IDS, {7: 10, 43: -2, 44: 300, 35: 2}) == data
    with pytest.raises(oi.OIError):
        oi.decode_packets(IDS, data[:-1])
    with pytest.raises(oi.OIError):
        oi.decode_packets(IDS, data + b"\x00")


def test_group_reply_decodes_into_members():
    vals = {p: (p % 7) for p in oi.GROUPS[101]}
    vals[43], vals[44] = -32768, 32767
    data = oi.encode_packets([101], vals)
    assert len(data) == 28
    assert oi.decode_packets([101], data) == vals


@pytest.mark.parametrize("new,old,delta", [(10, 5, 5), (5, 10, -5), (-32768, 32767, 1),
                                           (32767, -32768, -1), (-32700, 32700, 136),
                                           (0, 0, 0)])
def test_encoder_delta_wraps(new, old, delta):
    assert oi.encoder_delta(new, old) == delta


def test_command_parser_waits_for_data_bytes():
    p = oi.CommandParser()
    assert p.feed(bytes([128, 131, 145, 0])) == [(128, b""), (131, b"")]
    assert p.feed(bytes([100, 255])) == []
    assert p.feed(bytes([156, 149, 2])) == [(145, bytes([0, 100, 255, 156]))]
    assert p.feed(bytes([7, 35])) == [(149, bytes([2, 7, 35]))]
    assert p.feed(bytes([99, 173])) == [(99, b""), (173, b"")]


def test_doctests():
    result = doctest.testmod(oi)
    assert result.attempted > 5 and result.failed == 0


# ---------------------------------------------------------------- stream parser properties
values = st.fixed_dictionaries({7: st.integers(0, 15), 43: st.integers(-32768, 32767),
                                44: st.integers(-32768, 32767), 35: st.integers(0, 3)})


def _frame(v):
    return oi.encode_stream_frame([(p, v[p]) for p in IDS])


def _chunks(data: bytes, cuts) -> list[bytes]:
    cuts = sorted({c % (len(data) + 1) for c in cuts})
    edges = [0, *cuts, len(data)]
    return [data[a:b] for a, b in zip(edges, edges[1:])]


@settings(max_examples=150, deadline=None)
@given(st.lists(values, min_size=1, max_size=12), st.lists(st.integers(0, 10_000)))
def test_parser_is_independent_of_chunking(frames, cuts):
    data = b"".join(_frame(v) for v in frames)
    p = oi.StreamParser(IDS)
    out = [f for c in _chunks(data, cuts) for f in p.feed(c)]
    assert out == frames
    assert p.skipped == 0 and p.pending == 0


@settings(max_examples=150, deadline=None)
@given(st.lists(st.tuples(values, st.binary(max_size=30)), min_size=1, max_size=10),
       st.lists(st.integers(0, 10_000), max_size=8), st.binary(max_size=20))
def test_parser_resynchronises_after_garbage(items, cuts, lead):
    # Garbage (random bytes, many of them 19, the frame header) before and between frames.
    # Every real frame comes out, in order, and nothing else: a spurious frame would need a
    # 19, the right length byte, the ids 7, 43, 44, 35 at their offsets and a zero checksum
    # inside the garbage, about 1 chance in 256**6 per header byte.
    junk = [bytes(19 if b % 3 == 0 else b for b in g) for _, g in items]
    data = bytes(19 if b % 3 == 0 else b for b in lead)
    for (v, _), j in zip(items, junk):
        data += _frame(v) + j
    p = oi.StreamParser(IDS)
    out = [f for c in _chunks(data, cuts) for f in p.feed(c)]
    assert out == [v for v, _ in items]
    assert p.skipped == len(data) - sum(len(_frame(v)) for v, _ in items) - p.pending


@settings(max_examples=150, deadline=None)
@given(st.lists(values, min_size=3, max_size=10), st.data())
def test_parser_loses_at_most_two_frames_to_a_dropped_byte(frames, data):
    k = data.draw(st.integers(0, len(frames) - 1))
    raw = [_frame(v) for v in frames]
    i = data.draw(st.integers(0, len(raw[k]) - 1))
    raw[k] = raw[k][:i] + raw[k][i + 1:]
    p = oi.StreamParser(IDS)
    out = p.feed(b"".join(raw))
    # what comes out is real frames, in order; all but frame k (and perhaps k + 1, whose
    # header a damaged frame k may swallow) survive
    it = iter(frames)
    assert all(any(f == g for g in it) for f in out), "a spurious or reordered frame"
    kept = [f for j, f in enumerate(frames) if j not in (k, k + 1)]
    for f in kept:
        assert f in out


def test_parser_rejects_bad_checksum_and_recovers():
    good = _frame({7: 1, 43: 5, 44: -5, 35: 2})
    bad = bytearray(good)
    bad[5] ^= 0x40                               # corrupt a data byte
    p = oi.StreamParser(IDS)
    assert p.feed(bytes(bad) + good) == [{7: 1, 43: 5, 44: -5, 35: 2}]
    assert p.bad_checksums >= 1


def test_parser_rejects_frames_with_other_packets():
    other = oi.encode_stream_frame([(7, 0), (43, 1), (44, 2), (36, 0)])   # same length
    good = _frame({7: 0, 43: 1, 44: 2, 35: 2})
    p = oi.StreamParser(IDS)
    assert p.feed(other + good) == [{7: 0, 43: 1, 44: 2, 35: 2}]
