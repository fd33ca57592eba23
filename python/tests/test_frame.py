# SPDX-License-Identifier: MIT
"""Frame layer: encoder, checksum and the stream decoder's rules (vectors/README.md), one by one."""

from __future__ import annotations

import dataclasses
import functools
import itertools
import operator
import random

import pytest

from ctrlbus.errors import FrameError, UsageError
from ctrlbus.frame import (
    FLAG_LONG,
    FLAG_STANDARD,
    MAX_FRAME,
    MAX_LONG_PAYLOAD,
    MAX_STANDARD_PAYLOAD,
    DecoderEvent,
    DecoderStats,
    EventKind,
    Frame,
    StreamDecoder,
    _prefix_xor,
    checksum,
    encode,
)

STATUS = bytes.fromhex("10 02 F8 30 DA")  # GET_BASE_STATUS, reference section 6
STATUS_LONG = bytes.fromhex("50 02 00 F8 30 9A")
SET_V = bytes.fromhex("10 0E F8 41 33 33 00 00 00 00 00 00 00 80 00 00 27")


def xor_all(data: bytes) -> int:
    """The checksum the slow, obvious way."""
    return functools.reduce(operator.xor, data, 0)


def kinds(items: list[Frame | DecoderEvent]) -> list[str]:
    return [item.kind.value if isinstance(item, DecoderEvent) else "frame" for item in items]


# --- encoder and checksum ----------------------------------------------------------------------


@pytest.mark.parametrize(
    ("cmd", "payload", "long", "wire"),
    [
        (0x00, "", None, "10 01 00 11"),
        (0x01, "AA 55", None, "10 03 01 AA 55 ED"),
        (0x01, "AA 55", True, "50 03 00 01 AA 55 AD"),
        (0xF8, "10 01", None, "10 03 F8 10 01 FA"),
        (0xF8, "30", None, "10 02 F8 30 DA"),
        (0xF8, "30", True, "50 02 00 F8 30 9A"),
        (0xF8, "41 33 33 00 00 00 00 00 00 00 80 00 00", None, SET_V.hex()),
        (0x02, "", True, "50 01 00 02 53"),
        (0x02, "50 03", True, "50 03 00 02 50 03 02"),
        (0x02, "FF 00", True, "50 03 00 02 FF 00 AE"),
        (0x03, "00 80", True, "50 03 00 03 00 80 D0"),
        (0x03, "20 00", True, "50 03 00 03 20 00 70"),
    ],
)
def test_encode_gives_the_reference_example_frames(
    cmd: int, payload: str, long: bool | None, wire: str
) -> None:
    assert encode(cmd, bytes.fromhex(payload), long=long) == bytes.fromhex(wire)


def test_encode_picks_the_frame_type_by_size() -> None:
    fits = encode(0x01, bytes(MAX_STANDARD_PAYLOAD))
    assert fits[0] == FLAG_STANDARD and fits[1] == 255 and len(fits) == MAX_STANDARD_PAYLOAD + 4
    too_big = encode(0x01, bytes(MAX_STANDARD_PAYLOAD + 1))
    assert too_big[:3] == bytes((FLAG_LONG, 0x00, 0x01)) and len(too_big) == MAX_STANDARD_PAYLOAD + 6
    assert encode(0x01, b"", long=True) == bytes((0x50, 0x01, 0x00, 0x01, 0x50 ^ 0x01 ^ 0x01))
    biggest = encode(0x01, bytes(MAX_LONG_PAYLOAD))
    assert len(biggest) == MAX_FRAME and biggest[1:3] == b"\xff\xff"


def test_encode_refuses_what_cannot_be_framed() -> None:
    with pytest.raises(FrameError, match="standard"):
        encode(0x01, bytes(MAX_STANDARD_PAYLOAD + 1), long=False)
    with pytest.raises(FrameError, match="long"):
        encode(0x01, bytes(MAX_LONG_PAYLOAD + 1))
    for cmd in (-1, 256):
        with pytest.raises(FrameError, match="CMD"):
            encode(cmd, b"")


@pytest.mark.parametrize("size", [0, 1, 2, 7, 8, 9, 255, 8191, 8192, 8193, 20000])
def test_checksum_and_prefix_xor_match_the_plain_xor(size: int) -> None:
    data = random.Random(size).randbytes(size)
    assert checksum(data) == xor_all(data)
    assert _prefix_xor(data) == bytes(itertools.accumulate(data, operator.xor))
    assert _prefix_xor(data, 0x5A) == bytes(
        value ^ 0x5A for value in itertools.accumulate(data, operator.xor)
    )


def test_every_encoded_frame_xors_to_zero() -> None:
    rng = random.Random(7)
    for size in (0, 1, 100, 254, 255, 3000):
        frame = encode(rng.randrange(256), rng.randbytes(size))
        assert xor_all(frame) == 0


# --- Frame -------------------------------------------------------------------------------------


def test_decoded_frames_are_genuine_immutable_frames() -> None:
    (frame,) = StreamDecoder().feed(b"\xaa" + STATUS)
    assert type(frame) is Frame
    assert (frame.cmd, frame.payload, frame.long, frame.offset) == (0xF8, b"\x30", False, 1)
    assert frame == Frame(0xF8, b"\x30", False)  # the offset does not take part in equality
    assert hash(frame) == hash(Frame(0xF8, b"\x30"))
    assert frame.raw == STATUS and frame.size == len(STATUS)
    assert repr(frame) == "Frame(cmd=248, payload=b'0', long=False, offset=1)"
    with pytest.raises(dataclasses.FrozenInstanceError):
        frame.cmd = 1  # type: ignore[misc]
    assert dataclasses.replace(frame, long=True).raw == STATUS_LONG


def test_frame_refuses_impossible_values() -> None:
    with pytest.raises(FrameError):
        Frame(256, b"")
    with pytest.raises(FrameError):
        Frame(1, bytes(MAX_STANDARD_PAYLOAD + 1), long=False)
    with pytest.raises(FrameError):
        Frame(1, bytearray(b"x"))  # type: ignore[arg-type]


# --- decoder: the happy path -------------------------------------------------------------------


def test_back_to_back_frames_of_both_types_in_one_chunk() -> None:
    decoder = StreamDecoder()
    frames = decoder.feed(STATUS + STATUS_LONG + SET_V)
    assert [(f.cmd, f.payload, f.long, f.offset) for f in frames] == [
        (0xF8, b"\x30", False, 0),
        (0xF8, b"\x30", True, 5),
        (0xF8, SET_V[3:-1], False, 11),
    ]
    assert decoder.stats == DecoderStats(frames=3)
    assert decoder.buffered == 0


def test_a_frame_split_anywhere_is_decoded_once_complete() -> None:
    for cut in range(1, len(SET_V)):
        decoder = StreamDecoder()
        assert decoder.feed(SET_V[:cut]) == []
        assert decoder.buffered == cut
        assert decoder.feed(SET_V[cut:]) == [Frame(0xF8, SET_V[3:-1])]


def test_the_largest_long_frame_fed_one_byte_at_a_time() -> None:
    wire = encode(0x21, bytes(range(256)) * 255 + bytes(range(254)))
    assert len(wire) == MAX_FRAME
    decoder = StreamDecoder()
    frames: list[Frame] = []
    for index in range(len(wire)):
        frames += decoder.feed(wire[index : index + 1])
    assert len(frames) == 1 and frames[0].raw == wire and frames[0].long


def test_input_may_be_bytearray_or_memoryview() -> None:
    decoder = StreamDecoder()
    assert decoder.feed(bytearray(STATUS)) == [Frame(0xF8, b"\x30")]
    assert decoder.feed(memoryview(STATUS)) == [Frame(0xF8, b"\x30")]
    assert isinstance(decoder.feed(bytearray(STATUS))[0].payload, bytes)


# --- decoder: rejections -----------------------------------------------------------------------


def test_a_garbage_burst_raises_one_event_and_counts_every_byte() -> None:
    decoder = StreamDecoder()
    items = decoder.feed_items(b"\x01\x02\x03" + STATUS + b"\x04\x05" + b"\x06" + STATUS)
    assert kinds(items) == ["garbage", "frame", "garbage", "frame"]
    assert [item.offset for item in items] == [0, 3, 8, 11]
    assert decoder.stats.bytes_discarded == 6


def test_garbage_is_raised_once_per_gap_even_across_chunks() -> None:
    decoder = StreamDecoder()
    items = decoder.feed_items(b"\x01\x02") + decoder.feed_items(b"\x03") + decoder.feed_items(STATUS)
    assert kinds(items) == ["garbage", "frame"]


def test_checksum_error_reports_expected_and_found_and_rescans_its_span() -> None:
    # A false flag whose "frame" swallows a real one: 10 08 + 9 bytes fail the checksum, and the
    # real STATUS frame inside is found by the rescan. The garbage inside the failed span stays
    # silent, even after the frame; garbage after the span is reported again.
    bogus = bytes.fromhex("10 08") + STATUS + bytes.fromhex("AA BB CC DD")
    assert xor_all(bogus[:-1]) != bogus[-1]
    decoder = StreamDecoder()
    items = decoder.feed_items(bogus + b"\xee")
    assert kinds(items) == ["checksum_error", "frame", "garbage"]
    error, frame, garbage = items
    assert isinstance(error, DecoderEvent) and isinstance(frame, Frame)
    assert (error.offset, error.expected_checksum, error.found_checksum) == (0, xor_all(bogus[:-1]), 0xDD)
    assert frame.offset == 2
    assert garbage.offset == len(bogus)
    assert decoder.stats == DecoderStats(
        frames=1, bytes_discarded=1 + 1 + 4 + 1, checksum_errors=1, resyncs=1
    )


def test_an_event_silences_the_garbage_of_its_gap() -> None:
    decoder = StreamDecoder()
    items = decoder.feed_items(bytes.fromhex("10 02 F8 30 DB") + b"\x01\x02" + STATUS)
    assert kinds(items) == ["checksum_error", "frame"]


def test_oversize_fails_as_soon_as_the_length_is_known() -> None:
    decoder = StreamDecoder(max_frame=512)
    # 50 FF 01: a long frame of 0x1FF + 4 = 515 bytes announced; the bytes behind it are scanned
    # right away (no waiting for 515 bytes) and the frame among them is found.
    items = decoder.feed_items(bytes.fromhex("50 FF 01") + STATUS)
    assert kinds(items) == ["oversize", "frame"]
    assert isinstance(items[0], DecoderEvent) and items[0].declared_size == 515
    assert decoder.stats == DecoderStats(frames=1, bytes_discarded=3, oversize=1, resyncs=1)
    # max_frame applies to standard frames too.
    small = StreamDecoder(max_frame=5)
    assert kinds(small.feed_items(bytes.fromhex("10 03") + STATUS)) == ["oversize", "frame"]


def test_an_oversize_span_is_only_its_length_bytes() -> None:
    # The garbage after the failed header lies outside its span; a frame resets "event raised".
    decoder = StreamDecoder(max_frame=512)
    items = decoder.feed_items(bytes.fromhex("50 FF 01") + STATUS + b"\x01")
    assert kinds(items) == ["oversize", "frame", "garbage"]


def test_empty_frames_are_reported_not_yielded() -> None:
    decoder = StreamDecoder()
    items = decoder.feed_items(bytes.fromhex("10 00 10") + bytes.fromhex("50 00 00 50") + STATUS)
    assert kinds(items) == ["empty_frame", "empty_frame", "frame"]
    assert [item.offset for item in items] == [0, 3, 7]
    assert decoder.stats == DecoderStats(frames=1, bytes_discarded=7, empty_frames=2)
    wrong = StreamDecoder()
    assert kinds(wrong.feed_items(bytes.fromhex("10 00 11"))) == ["checksum_error"]
    assert wrong.stats.checksum_errors == 1 and wrong.stats.empty_frames == 0


# --- decoder: time -----------------------------------------------------------------------------


def test_a_stale_partial_frame_times_out_and_the_next_frame_decodes() -> None:
    # Times and timeout are binary fractions so that the boundary is exact in floating point.
    decoder = StreamDecoder(timeout=0.25)
    assert decoder.feed_items(SET_V[:6], now=1.0) == []
    assert decoder.feed_items(b"", now=1.25) == []  # exactly the timeout: not yet
    items = decoder.feed_items(b"", now=1.2500001)
    assert kinds(items) == ["timeout"] and items[0].offset == 0
    assert decoder.buffered == 0
    assert decoder.feed(SET_V, now=2.0) == [Frame(0xF8, SET_V[3:-1])]
    assert decoder.stats == DecoderStats(frames=1, bytes_discarded=6, timeouts=1, resyncs=1)


def test_new_bytes_after_a_long_gap_do_not_complete_a_stale_candidate() -> None:
    decoder = StreamDecoder(timeout=0.010)
    decoder.feed(SET_V[:6], now=0.0)
    items = decoder.feed_items(SET_V[6:] + STATUS, now=0.5)
    assert kinds(items) == ["timeout", "frame"]  # only STATUS: SET_V was cut by the gap


def test_a_timeout_rescan_yields_complete_frames_and_drops_every_partial_one() -> None:
    # 50 FF 00 announces 259 bytes; behind it a complete frame and two partial candidates.
    stale = bytes.fromhex("50 FF 00") + STATUS + bytes.fromhex("10 05 50 03")
    decoder = StreamDecoder(timeout=0.010)
    assert decoder.feed_items(stale, now=0.0) == []
    items = decoder.feed_items(b"", now=0.1)
    assert kinds(items) == ["timeout", "frame"]
    # Outer 50 FF 00 + 10 05 + 50 03 time out; the lone 05 after 10 is silent garbage.
    assert decoder.stats == DecoderStats(frames=1, bytes_discarded=3 + 4, timeouts=3, resyncs=3)
    assert decoder.buffered == 0


def test_no_timeout_when_off_or_without_time() -> None:
    off = StreamDecoder(timeout=0)
    off.feed(SET_V[:6], now=0.0)
    assert off.feed_items(b"", now=1e9) == [] and off.buffered == 6
    untimed = StreamDecoder(timeout=0.010)
    untimed.feed(SET_V[:6])
    assert untimed.feed_items(b"") == [] and untimed.buffered == 6
    # Bytes fed without a time: the timeout counts from the first call that gives one.
    assert untimed.feed_items(b"", now=5.0) == []
    assert kinds(untimed.feed_items(b"", now=5.02)) == ["timeout"]


# --- decoder: interface ------------------------------------------------------------------------


def test_feed_returns_frames_only_and_passes_events_to_the_callback() -> None:
    seen: list[DecoderEvent] = []
    decoder = StreamDecoder(on_event=seen.append)
    frames = decoder.feed(b"\x01" + bytes.fromhex("10 02 F8 30 DB") + STATUS)
    assert frames == [Frame(0xF8, b"\x30")]
    # Only garbage is silenced by an earlier event; a failed candidate outside any span is not.
    assert [event.kind for event in seen] == [EventKind.GARBAGE, EventKind.CHECKSUM_ERROR]
    items = decoder.feed_items(bytes.fromhex("10 02 F8 30 DB"))
    assert items == seen[2:] and [event.kind for event in seen[2:]] == [EventKind.CHECKSUM_ERROR]


def test_event_text_names_what_went_wrong() -> None:
    event = DecoderEvent(EventKind.CHECKSUM_ERROR, 7, expected_checksum=0xDA, found_checksum=0xDB)
    assert str(event) == "checksum_error at offset 7: checksum 0xDB, expected 0xDA"
    assert "515" in str(DecoderEvent(EventKind.OVERSIZE, 0, declared_size=515))


def test_reset_forgets_everything() -> None:
    decoder = StreamDecoder()
    decoder.feed(b"\x01" + SET_V[:5])
    decoder.reset()
    assert decoder.stats == DecoderStats() and decoder.buffered == 0
    (frame,) = decoder.feed(STATUS)
    assert frame.offset == 0


def test_bad_settings_are_refused() -> None:
    with pytest.raises(UsageError):
        StreamDecoder(max_frame=4)
    with pytest.raises(UsageError):
        StreamDecoder(timeout=-1)
    with pytest.raises(UsageError):
        StreamDecoder(timeout=float("nan"))
    decoder = StreamDecoder(max_frame=5, timeout=0.05)
    assert (decoder.max_frame, decoder.timeout) == (5, 0.05)
