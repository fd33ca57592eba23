# SPDX-License-Identifier: MIT
"""Property tests (hypothesis): the decoder against a literal model of the contract, chunking
invariance, recovery after garbage, and encode -> decode round trips for every message."""

from __future__ import annotations

import functools
import itertools
import operator
from dataclasses import dataclass, field
from typing import Any

from hypothesis import given, settings
from hypothesis import strategies as st

from ctrlbus import messages as m
from ctrlbus.frame import MAX_FRAME, MAX_STANDARD_PAYLOAD, DecoderEvent, Frame, StreamDecoder, encode

# --- a literal model of "The stream decoder, precisely" ----------------------------------------

COUNTER_OF_FAILURE = {"checksum_error": "checksum_errors", "oversize": "oversize", "timeout": "timeouts"}


@dataclass
class ModelDecoder:
    """The contract's decoder, one byte at a time, written for obviousness, not speed.

    After every byte it scans the buffer as docs/protocol.md §7 words it: hunting, the candidate's
    size after its header, the checksum when complete, and on failure dropping the flag and
    rescanning what is buffered. The silent region is kept literally, as a set of stream offsets,
    and in both wordings of a span: docs/protocol.md D4 (checksum: the rest of the declared frame;
    oversize: the length bytes; timeout: everything received) and vectors/README.md rule 4 ("every
    byte that was buffered after its flag when it failed"). Every silence check asserts that the
    two agree.
    """

    max_frame: int = MAX_FRAME
    timeout: float = 0
    buffer: list[int] = field(default_factory=list)
    start: int = 0  # stream offset of buffer[0]
    received: int = 0  # stream offset of the next byte
    silent_declared: set[int] = field(default_factory=set)
    silent_received: set[int] = field(default_factory=set)
    event_since_frame: bool = False
    last_time: float | None = None
    items: list[tuple[Any, ...]] = field(default_factory=list)
    counters: dict[str, int] = field(
        default_factory=lambda: dict.fromkeys(
            (
                "frames",
                "bytes_discarded",
                "checksum_errors",
                "oversize",
                "timeouts",
                "empty_frames",
                "resyncs",
            ),
            0,
        )
    )

    def feed(self, data: bytes, now: float) -> None:
        if self.timeout and self.buffer:
            if self.last_time is None:
                self.last_time = now
            elif now - self.last_time > self.timeout:
                self.scan(stale=True)
        for byte in data:
            self.buffer.append(byte)
            self.received += 1
            self.scan(stale=False)
        if data:
            self.last_time = now

    def raise_event(self, kind: str, offset: int) -> None:
        self.items.append(("event", kind, offset))
        self.event_since_frame = True

    def drop(self, count: int) -> None:
        del self.buffer[:count]
        self.start += count

    def silent(self, offset: int) -> bool:
        declared, received = offset in self.silent_declared, offset in self.silent_received
        assert declared == received, f"the two span wordings disagree at offset {offset}"
        return declared

    def fail(self, kind: str, span_end: int) -> None:
        self.counters[COUNTER_OF_FAILURE[kind]] += 1
        self.counters["resyncs"] += 1
        self.counters["bytes_discarded"] += 1
        if not self.silent(self.start):
            self.raise_event(kind, self.start)
        self.silent_declared.update(range(self.start + 1, span_end))
        self.silent_received.update(range(self.start + 1, self.received))
        self.drop(1)

    def scan(self, stale: bool) -> None:
        while self.buffer:
            flag = self.buffer[0]
            if flag not in (0x10, 0x50):
                self.counters["bytes_discarded"] += 1
                if not self.silent(self.start) and not self.event_since_frame:
                    self.raise_event("garbage", self.start)
                self.drop(1)
                continue
            header = 2 if flag == 0x10 else 3
            if len(self.buffer) < header:
                if stale:
                    self.fail("timeout", self.received)
                    continue
                return
            length = self.buffer[1] if flag == 0x10 else self.buffer[1] | self.buffer[2] << 8
            size = header + length + 1
            if size > self.max_frame:
                self.fail("oversize", self.start + header)
                continue
            if len(self.buffer) < size:
                if stale:
                    self.fail("timeout", self.received)
                    continue
                return
            if functools.reduce(operator.xor, self.buffer[: size - 1], 0) != self.buffer[size - 1]:
                self.fail("checksum_error", self.start + size)
                continue
            if length == 0:
                self.counters["empty_frames"] += 1
                self.counters["bytes_discarded"] += size
                if not self.silent(self.start):
                    self.raise_event("empty_frame", self.start)
                self.drop(size)
                continue
            payload = bytes(self.buffer[header + 1 : size - 1])
            self.items.append(("frame", self.start, flag == 0x50, self.buffer[header], payload))
            self.counters["frames"] += 1
            self.event_since_frame = False
            self.drop(size)


def observed(items: list[Frame | DecoderEvent]) -> list[tuple[Any, ...]]:
    return [
        ("frame", item.offset, item.long, item.cmd, item.payload)
        if isinstance(item, Frame)
        else ("event", item.kind.value, item.offset)
        for item in items
    ]


def counters(decoder: StreamDecoder) -> dict[str, int]:
    stats = decoder.stats
    return {name: getattr(stats, name) for name in ModelDecoder().counters}


# --- stream strategies -------------------------------------------------------------------------


@st.composite
def wire_frames(draw: st.DrawFn, max_payload: int = 40) -> bytes:
    payload = draw(st.binary(max_size=max_payload))
    return encode(draw(st.integers(0, 255)), payload, long=draw(st.booleans()))


@st.composite
def stream_pieces(draw: st.DrawFn) -> bytes:
    """A piece of a hostile stream: a frame, garbage, or a broken frame."""
    kind = draw(st.sampled_from(["frame", "frame", "garbage", "corrupt", "truncated", "false_flag", "empty"]))
    if kind == "frame":
        return draw(wire_frames())
    if kind == "garbage":
        return draw(st.binary(min_size=1, max_size=12))
    if kind == "corrupt":
        corrupt = bytearray(draw(wire_frames()))
        corrupt[draw(st.integers(0, len(corrupt) - 1))] ^= draw(st.integers(1, 255))
        return bytes(corrupt)
    if kind == "truncated":
        wire = draw(wire_frames())
        return wire[: draw(st.integers(1, len(wire) - 1))]
    if kind == "false_flag":
        flag = draw(st.sampled_from([0x10, 0x50]))
        return bytes([flag]) + draw(st.binary(min_size=1, max_size=2))
    return draw(st.sampled_from([bytes.fromhex("10 00 10"), bytes.fromhex("50 00 00 50")]))


@st.composite
def chunked(draw: st.DrawFn, data: bytes) -> list[bytes]:
    cuts = sorted(draw(st.lists(st.integers(0, len(data)), max_size=12)))
    bounds = [0, *cuts, len(data)]
    return [data[a:b] for a, b in itertools.pairwise(bounds)]


# --- decoder properties ------------------------------------------------------------------------


@settings(max_examples=300)
@given(
    pieces=st.lists(stream_pieces(), max_size=25),
    max_frame=st.sampled_from([5, 6, 12, 40, 300, MAX_FRAME]),
    timeout_ms=st.sampled_from([0, 10]),
    data=st.data(),
)
def test_decoder_matches_the_literal_model_of_the_contract(
    pieces: list[bytes], max_frame: int, timeout_ms: int, data: st.DataObject
) -> None:
    stream = b"".join(pieces)
    chunks = data.draw(chunked(stream))
    gaps = data.draw(
        st.lists(st.sampled_from([0, 3, 10, 11, 50]), min_size=len(chunks), max_size=len(chunks))
    )
    model = ModelDecoder(max_frame=max_frame, timeout=timeout_ms)
    decoder = StreamDecoder(max_frame=max_frame, timeout=timeout_ms)  # time in ms: exact arithmetic
    items: list[Frame | DecoderEvent] = []
    now = 0
    for chunk, gap in zip(chunks, gaps, strict=True):
        now += gap
        model.feed(chunk, now)
        items += decoder.feed_items(chunk, now)
    model.feed(b"", now + 1000)
    items += decoder.feed_items(b"", now + 1000)
    assert observed(items) == model.items
    assert counters(decoder) == model.counters
    assert decoder.buffered == len(model.buffer)


@given(pieces=st.lists(stream_pieces(), max_size=25), data=st.data())
def test_the_split_into_chunks_does_not_matter(pieces: list[bytes], data: st.DataObject) -> None:
    stream = b"".join(pieces)
    whole = StreamDecoder(max_frame=300)
    expected = observed(whole.feed_items(stream))
    split = StreamDecoder(max_frame=300)
    items: list[Frame | DecoderEvent] = []
    for chunk in data.draw(chunked(stream)):
        items += split.feed_items(chunk)
    assert observed(items) == expected
    assert split.stats == whole.stats
    bytewise = StreamDecoder(max_frame=300)
    frames: list[Frame] = []
    for index in range(len(stream)):
        frames += bytewise.feed(stream[index : index + 1])
    assert [("frame", f.offset, f.long, f.cmd, f.payload) for f in frames] == [
        item for item in expected if item[0] == "frame"
    ]


def is_valid_frame(data: bytes) -> bool:
    """Independent check that `data` is exactly one valid frame (LEN = 0 included)."""
    if len(data) < 3 or data[0] not in (0x10, 0x50):
        return False
    header = 2 if data[0] == 0x10 else 3
    length = data[1] if data[0] == 0x10 else data[1] | data[2] << 8
    return len(data) == header + length + 1 and functools.reduce(operator.xor, data, 0) == 0


@settings(max_examples=150)
@given(
    garbage=st.one_of(
        st.binary(max_size=300),
        st.lists(stream_pieces(), max_size=30).map(lambda pieces: b"".join(pieces)[:300]),
    ),
    wire=wire_frames(max_payload=300),
)
def test_a_frame_after_garbage_is_still_decoded(garbage: bytes, wire: bytes) -> None:
    """Up to 300 bytes of garbage never hide a valid frame, with one unavoidable exception.

    The exception: some bytes of the garbage plus the first bytes of the frame are themselves a
    valid frame G that ends inside our frame F (G covers F's flag). A decoder yields a frame as
    soon as it is complete and valid, and G completes first; it is byte for byte a real frame,
    so no decoder can tell it is not one. Once G is taken, F's flag belongs to it, and taking F as
    well would mean yielding overlapping frames. G may also be an empty frame (LEN = 0: 10 00 10
    or 50 00 00 50, whose checksum byte is F's flag), which is consumed without being yielded.

    The timeout (checked after an idle gap) flushes a false candidate still waiting for bytes, so
    every candidate is settled by the end.
    """
    decoder = StreamDecoder(timeout=0.010)
    frames = decoder.feed(garbage + wire, now=0.0) + decoder.feed(b"", now=1.0)
    start, end = len(garbage), len(garbage) + len(wire)
    stream = garbage + wire
    if any(frame.offset == start and frame.raw == wire for frame in frames):
        return
    # F is missing: it must be the unavoidable case, and G must really be a valid frame.
    covering = [frame for frame in frames if frame.offset < start < frame.offset + frame.size]
    if covering:
        (taken,) = covering
        assert taken.offset + taken.size <= end
        assert is_valid_frame(stream[taken.offset : taken.offset + taken.size])
        return
    empty_before = [
        size
        for size in (3, 4)
        if start + 1 - size >= 0 and is_valid_frame(stream[start + 1 - size : start + 1])
    ]
    assert empty_before and decoder.stats.empty_frames >= 1, (
        f"frame at {start} lost after garbage {garbage.hex(' ')}: got {frames}, stats {decoder.stats}"
    )


# --- message round trips -----------------------------------------------------------------------

u8 = st.integers(0, 0xFF)
u16 = st.integers(0, 0xFFFF)
u32 = st.integers(0, 0xFFFF_FFFF)
s32 = st.integers(-(1 << 31), (1 << 31) - 1)
ascii_text = st.text(st.characters(min_codepoint=1, max_codepoint=127), max_size=12)
positions = st.builds(m.Position, s32, s32, s32, u32)


@st.composite
def conf_answers(draw: st.DrawFn) -> m.GetBaseConfAnswer:
    sensors = draw(st.lists(positions, max_size=8))
    bumpers = draw(st.lists(positions, max_size=8))
    return m.GetBaseConfAnswer(
        draw(u8),
        draw(u32),
        draw(u8),
        draw(st.integers(0, 8)),
        tuple(sensors),
        draw(st.integers(0, 8)),
        tuple(bumpers),
    )


@st.composite
def bumper_answers(draw: st.DrawFn) -> m.GetBaseBumperDataAnswer:
    size = draw(st.integers(1, 4))
    return m.GetBaseBumperDataAnswer(draw(st.integers(0, (1 << (8 * size)) - 1)), size)


@st.composite
def charger_answers(draw: st.DrawFn) -> m.GetChargerDataAnswer:
    probes = draw(st.lists(u8, max_size=8))
    return m.GetChargerDataAnswer(draw(u8), len(probes), tuple(probes))


poll_answers = st.one_of(
    st.just(m.PollBaseCmdAnswer()),
    st.builds(m.PollBaseCmdAnswer, st.none(), st.just(2), u8),
    st.builds(m.PollBaseCmdAnswer, st.integers(0, 0xFE), st.just(2), u8),
)

REQUESTS: dict[str, st.SearchStrategy[m.RequestMessage]] = {
    "SYNC": st.builds(m.Sync, st.binary(max_size=40)),
    "ECHO": st.builds(m.Echo, st.binary(max_size=40)),
    "BASE_CMD": st.builds(m.BaseCommand, st.sampled_from(m.BaseSubcommand)),
    "CONNECT_BASE": st.just(m.ConnectBase()),
    "GET_BASE_CONF": st.just(m.GetBaseConf()),
    "GET_BASE_CONF_ADV": st.just(m.GetBaseConfAdv()),
    "GET_BASE_STATUS": st.just(m.GetBaseStatus()),
    "GET_BASE_MOTOR_DATA": st.just(m.GetBaseMotorData()),
    "GET_BASE_SENSOR_DATA": st.just(m.GetBaseSensorData()),
    "GET_BASE_BUMPER_DATA": st.just(m.GetBaseBumperData()),
    "GET_CHARGER_DATA": st.just(m.GetChargerData()),
    "GET_AUXILIARY_ANCHOR": st.just(m.GetAuxiliaryAnchor()),
    "SET_BASE_MOTOR": st.builds(m.SetBaseMotor, st.tuples(s32, s32, s32, s32)),
    "SET_V_AND_GET_DEADRECKON": st.builds(m.SetVAndGetDeadreckon, s32, s32, s32),
    "POLL_BASE_CMD": st.just(m.PollBaseCmd()),
    "POLL_BASE_ANS_CMD": st.just(m.PollBaseAnsCmd()),
    "SEND_EVENT": st.builds(m.SendEvent, u8),
    "HEALTH_GET_HEALTH": st.just(m.HealthGetHealth()),
    "HEALTH_GET_ERROR": st.builds(m.HealthGetError, u8),
    "HEALTH_CLR_ERROR": st.builds(m.HealthClrError, u32),
}

OK_ANSWERS: dict[str, st.SearchStrategy[m.AnswerMessage]] = {
    "BASE_CMD": st.just(m.EmptyAnswer()),
    "CONNECT_BASE": st.builds(
        m.ConnectBaseAnswer,
        ascii_text,
        u16,
        u16,
        st.tuples(u32, u32, u32),
        st.none() | ascii_text.map(lambda t: t[:11]),
    ),
    "GET_BASE_CONF": conf_answers(),
    "GET_BASE_CONF_ADV": st.builds(m.GetBaseConfAdvAnswer, st.binary(max_size=400)),
    "GET_BASE_STATUS": st.builds(m.GetBaseStatusAnswer, u8, u8),
    "GET_BASE_MOTOR_DATA": st.builds(m.GetBaseMotorDataAnswer, s32, s32, u8),
    "GET_BASE_SENSOR_DATA": st.builds(m.GetBaseSensorDataAnswer, st.tuples(*[u32] * 16)),
    "GET_BASE_BUMPER_DATA": bumper_answers(),
    "GET_CHARGER_DATA": charger_answers(),
    "SET_BASE_MOTOR": st.just(m.EmptyAnswer()),
    "SET_V_AND_GET_DEADRECKON": st.builds(m.SetVAndGetDeadreckonAnswer, s32, s32, s32, u8, st.none() | u32),
    "POLL_BASE_CMD": poll_answers,
    "POLL_BASE_ANS_CMD": st.just(m.EmptyAnswer()),
    "SEND_EVENT": st.just(m.EmptyAnswer()),
    "HEALTH_GET_HEALTH": st.builds(m.HealthGetHealthAnswer, u8, u8),
    "HEALTH_GET_ERROR": st.builds(
        m.HealthGetErrorAnswer, u32, st.text(st.characters(min_codepoint=1, max_codepoint=127), max_size=31)
    ),
    "HEALTH_CLR_ERROR": st.just(m.EmptyAnswer()),
}

RESPONSE_ANSWERS: st.SearchStrategy[m.AnswerMessage] = st.one_of(
    st.builds(m.SyncAnswer, st.binary(max_size=40)),
    st.builds(m.EchoAnswer, st.binary(max_size=40)),
    st.builds(m.ErrorAnswer, u16),
    st.just(m.InvalidAnswer()),
)


def test_the_strategies_cover_every_message() -> None:
    assert set(REQUESTS) == set(m.REQUEST_CLASSES)
    assert set(OK_ANSWERS) == set(m.OK_ANSWER_CLASSES)


def through_the_wire(frame_bytes: bytes) -> Frame:
    (frame,) = StreamDecoder().feed(frame_bytes)
    return frame


@given(request=st.one_of(*REQUESTS.values()), long=st.none() | st.booleans())
def test_every_request_survives_encode_frame_decode(request: m.RequestMessage, long: bool | None) -> None:
    frame = through_the_wire(m.request_frame(request, long=long))
    decoded = m.decode_request(frame.cmd, frame.payload)
    assert decoded == request and type(decoded) is type(request)
    assert m.from_fields(request.NAME, m.fields(request)) == request


@given(data=st.data(), to=st.sampled_from(sorted(OK_ANSWERS)), long=st.none() | st.booleans())
def test_every_answer_survives_encode_frame_decode(data: st.DataObject, to: str, long: bool | None) -> None:
    answer = data.draw(st.one_of(OK_ANSWERS[to], RESPONSE_ANSWERS))
    if len(m.encode_answer(answer)[1]) > MAX_STANDARD_PAYLOAD:
        long = None  # only a long frame can carry it
    frame = through_the_wire(m.answer_frame(answer, long=long))
    decoded = m.decode_answer(to, frame.cmd, frame.payload)
    assert decoded == answer and type(decoded) is type(answer)
    assert m.from_fields(answer.NAME, m.fields(answer), to=to) == answer


@given(vx=st.floats(-100, 100), vy=st.floats(-100, 100), omega=st.floats(-100, 100))
def test_si_values_round_trip_within_half_a_q16_step(vx: float, vy: float, omega: float) -> None:
    request = m.SetVAndGetDeadreckon.from_si(vx_mps=vx, vy_mps=vy, omega_radps=omega)
    for value, back in ((vx, request.vx_mps), (vy, request.vy_mps), (omega, request.omega_radps)):
        assert abs(back - value) <= 0.5 / 65536
