# SPDX-License-Identifier: MIT
"""Every shared vector (vectors/frames.json, invalid.json, streams.json) against the Python codec.

The vectors are the contract with the C library (vectors/README.md). Every file and list is
required: a missing one stops the collection of this module with an error naming it.
"""

from __future__ import annotations

from typing import Any

import pytest
from support import vectorfiles
from support.vectorfiles import hex_bytes

from ctrlbus import messages as m
from ctrlbus.errors import MessageFormatError, UnsupportedMessageError
from ctrlbus.frame import MAX_FRAME, DecoderEvent, Frame, StreamDecoder, encode

# What a base with default settings answers to each decoder event (vectors/README.md, last
# paragraph); the base layer owns this policy, the test only uses it to check `base_answer`.
EVENT_ERROR_CODES = {"garbage": 0x0010, "checksum_error": 0x0040, "oversize": 0x0020, "empty_frame": 0x8001}


def cases(filename: str, key: str) -> list[Any]:
    """pytest parameters for the entries of one vector list, named by the vectors' names."""
    entries = vectorfiles.section(filename, key)
    if not entries:
        raise FileNotFoundError(f"vectors/{filename} is missing or has no {key!r} entries")
    return [pytest.param(entry, id=str(entry.get("name", index))) for index, entry in enumerate(entries)]


def frame_tuples(items: list[Frame | DecoderEvent]) -> list[tuple[bool, int, bytes]]:
    return [(item.long, item.cmd, item.payload) for item in items if isinstance(item, Frame)]


def expected_frame_tuples(expected: list[dict[str, Any]]) -> list[tuple[bool, int, bytes]]:
    return [(bool(frame["long"]), int(frame["cmd"]), hex_bytes(frame["payload"])) for frame in expected]


def event_names(items: list[Frame | DecoderEvent]) -> list[str]:
    return [item.kind.value for item in items if isinstance(item, DecoderEvent)]


def check_counters(decoder: StreamDecoder, expected: dict[str, int]) -> None:
    stats = decoder.stats
    got = {name: getattr(stats, name) for name in expected}
    assert got == expected, f"counters {got}, expected {expected} (all: {stats})"


def decoder_for(vector: dict[str, Any]) -> StreamDecoder:
    """A fresh decoder with the vector's settings. Time runs in milliseconds (the vectors' unit),
    so comparisons with the timeout are exact."""
    return StreamDecoder(max_frame=vector.get("max_frame", MAX_FRAME), timeout=vector.get("timeout_ms", 0))


# --- frames.json -------------------------------------------------------------------------------


@pytest.mark.parametrize("vector", cases("frames.json", "frames"))
def test_frame_vector(vector: dict[str, Any]) -> None:
    wire = hex_bytes(vector["hex"])
    long, cmd, payload = bool(vector["long"]), int(vector["cmd"]), hex_bytes(vector["payload"])
    decoder = StreamDecoder(timeout=0)
    items = decoder.feed_items(wire)
    assert frame_tuples(items) == [(long, cmd, payload)] and event_names(items) == []
    assert decoder.buffered == 0
    assert encode(cmd, payload, long=long) == wire

    message = vector.get("message")
    if message is None:
        return
    name, values = message["name"], message.get("fields", {})
    if message["kind"] == "request":
        expected: m.Message = m.from_fields(name, values)
        decoded: m.Message = m.decode_request(cmd, payload)
        assert isinstance(expected, m.RequestMessage)
        assert m.request_frame(expected, long=long) == wire
    else:
        assert message["kind"] == "answer", f"unknown message kind {message['kind']!r}"
        to = message["to"]
        expected = m.from_fields(name, values, to=to)
        decoded = m.decode_answer(to, cmd, payload)
        assert isinstance(expected, m.AnswerMessage)
        assert m.answer_frame(expected, long=long) == wire
    assert decoded == expected
    assert name == decoded.NAME
    # The vector lists every field, in the same JSON form fields() gives.
    assert m.fields(m.from_fields(name, values, to=message.get("to"))) == m.fields(decoded)
    assert sorted(values) == sorted(m.fields(decoded)), (
        "the vector does not list exactly the message's fields"
    )


# --- invalid.json ------------------------------------------------------------------------------


def expected_error_codes(items: list[Frame | DecoderEvent]) -> list[int]:
    """The ERROR codes a base gives, in order, for what the decoder produced: one per answered
    event, and one per frame whose request does not decode."""
    codes: list[int] = []
    for item in items:
        if isinstance(item, DecoderEvent):
            if item.kind.value in EVENT_ERROR_CODES:
                codes.append(EVENT_ERROR_CODES[item.kind.value])
            continue
        try:
            m.decode_request(item.cmd, item.payload)
        except MessageFormatError as error:
            codes.append(error.error_code)
        except UnsupportedMessageError as error:
            codes.append(error.error_code)
    return codes


def error_codes_in(answer: bytes) -> list[int]:
    """The ERROR codes in a base's answer bytes (which must be nothing but whole frames)."""
    decoder = StreamDecoder(timeout=0)
    items = decoder.feed_items(answer)
    assert event_names(items) == [] and decoder.buffered == 0, f"base_answer is not whole frames: {items}"
    codes = []
    for frame in items:
        assert isinstance(frame, Frame)
        if frame.cmd == m.Response.ERROR:
            decoded = m.decode_answer("SYNC", frame.cmd, frame.payload)
            assert isinstance(decoded, m.ErrorAnswer)
            assert frame.long, "a base with default settings answers ERROR in long frames"
            codes.append(decoded.error_code)
    return codes


@pytest.mark.parametrize("vector", cases("invalid.json", "frame_level"))
def test_invalid_frame_vector(vector: dict[str, Any]) -> None:
    decoder = decoder_for(vector)
    items = decoder.feed_items(hex_bytes(vector["hex"]), 0)
    if "timeout_ms" in vector:
        items += decoder.feed_items(b"", vector["timeout_ms"] + 1)  # an idle gap longer than the timeout
    expect = vector["expect"]
    if "frames" in expect:
        assert frame_tuples(items) == expected_frame_tuples(expect["frames"])
    if "events" in expect:
        assert event_names(items) == expect["events"]
    check_counters(decoder, expect.get("counters", {}))
    if "base_answer" in vector:
        assert error_codes_in(hex_bytes(vector["base_answer"])) == expected_error_codes(items)


@pytest.mark.parametrize("vector", cases("invalid.json", "message_level"))
def test_invalid_message_vector(vector: dict[str, Any]) -> None:
    cmd, payload = int(vector["cmd"]), hex_bytes(vector["payload"])
    error_type = {"format": MessageFormatError, "unsupported": UnsupportedMessageError}[
        vector["expect_error"]
    ]
    with pytest.raises(error_type) as error:
        if vector["direction"] == "request":
            m.decode_request(cmd, payload)
        else:
            assert vector["direction"] == "answer", f"unknown direction {vector['direction']!r}"
            m.decode_answer(vector["to"], cmd, payload)
    raised = error.value
    assert isinstance(raised, MessageFormatError | UnsupportedMessageError)
    if vector["expect_error"] == "format":
        assert not isinstance(raised, UnsupportedMessageError)
    if "base_answer" in vector:
        assert vector["direction"] == "request", "only a base answers, and it answers requests"
        expected = m.answer_frame(m.ErrorAnswer(raised.error_code), long=True)
        assert hex_bytes(vector["base_answer"]) == expected


# --- streams.json ------------------------------------------------------------------------------


def run_stream(vector: dict[str, Any], bytewise: bool) -> tuple[StreamDecoder, list[Frame | DecoderEvent]]:
    decoder = decoder_for(vector)
    items: list[Frame | DecoderEvent] = []
    now = 0
    for chunk in vector["chunks"]:
        now = chunk.get("t_ms", now)
        data = hex_bytes(chunk["hex"])
        if bytewise:
            for index in range(len(data)):
                items += decoder.feed_items(data[index : index + 1], now)
        else:
            items += decoder.feed_items(data, now)
    if "final_idle_ms" in vector:
        items += decoder.feed_items(b"", now + vector["final_idle_ms"])
    return decoder, items


@pytest.mark.parametrize("bytewise", [False, True], ids=["chunks", "bytewise"])
@pytest.mark.parametrize("vector", cases("streams.json", "streams"))
def test_stream_vector(vector: dict[str, Any], bytewise: bool) -> None:
    decoder, items = run_stream(vector, bytewise)
    assert frame_tuples(items) == expected_frame_tuples(vector["expect_frames"])
    if "expect_events" in vector:
        assert event_names(items) == vector["expect_events"]
    check_counters(decoder, vector.get("expect_counters", {}))
