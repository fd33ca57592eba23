# SPDX-License-Identifier: MIT
"""No input makes ctrlbus raise anything but its documented exceptions (hypothesis).

- The stream decoder takes any bytes in any pieces at any times: it yields frames, counts the rest,
  and its buffer stays within `max_frame`; bad settings are a UsageError.
- The base stack (with a bare application and with the simulated base) takes any bytes at any
  times: it answers only with whole, valid response frames, never lets a command past its velocity
  limits, and its application never fails; a time that is not a finite number is a UsageError.
- The message codec reads any payload as a message or raises a MessageError subclass; the binary
  configuration reader raises only BinaryConfigError; the fault spec parser only UsageError.
- The Core emulator takes any answer bytes without raising.

Hostile streams mix garbage, frames with random payloads (with correct lengths and checksums, so
that the input reaches the payload handling rather than stopping at the checksum), corrupted
frames, false headers and truncated frames.
"""

from __future__ import annotations

import math
from typing import Any

import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from ctrlbus import binconf
from ctrlbus import messages as m
from ctrlbus.base import Base, BaseConfig, BaseStack, VelocityLimits
from ctrlbus.core.session import CoreSession
from ctrlbus.errors import BinaryConfigError, MessageError, UsageError
from ctrlbus.faults import FaultSpec
from ctrlbus.frame import MAX_FRAME, Frame, StreamDecoder, encode
from ctrlbus.kinematics import wheel_speeds_from_velocity
from ctrlbus.messages import SetVAndGetDeadreckonAnswer
from ctrlbus.sim.base import SimulatedBase
from ctrlbus.sim.world import World

CTRL_BUS, BASE_CMD = 0xF8, 0xF9
RESPONSES = {int(code) for code in m.Response}
# Argument bytes each request takes (protocol.md §5), keyed by request code (and HEALTH_MGMT
# sub-command), so that fuzzed payloads mostly have the right length and reach the value checks
# and the handlers rather than stopping at the length check.
ARGUMENT_SIZES: dict[tuple[int, int | None], int] = {
    (m.Request.CONNECT_BASE, None): 1,
    (m.Request.GET_CHARGER_DATA, None): 1,
    (m.Request.SET_BASE_MOTOR, None): 16,
    (m.Request.SET_V_AND_GET_DEADRECKON, None): 12,
    (m.Request.SEND_EVENT, None): 1,
    (m.Request.HEALTH_MGMT, m.HealthSub.GET_ERROR): 1,
    (m.Request.HEALTH_MGMT, m.HealthSub.CLR_ERROR): 4,
}
REQUEST_CODES = [int(code) for code in m.Request]
HEALTH_SUBS = [int(code) for code in m.HealthSub]
# SET_V and SET_BASE_MOTOR are the ones that move wheels: weigh them up.
MOTION_CODES = [int(m.Request.SET_V_AND_GET_DEADRECKON), int(m.Request.SET_BASE_MOTOR)]


# --- hostile input -----------------------------------------------------------------------------


@st.composite
def request_payloads(draw: st.DrawFn) -> bytes:
    """A CTRL_BUS payload: a (mostly known) request code, a sub-command, random arguments of
    (mostly) the right length."""
    code = draw(st.one_of(st.sampled_from(MOTION_CODES), st.sampled_from(REQUEST_CODES), st.integers(0, 255)))
    head = bytes([code])
    sub: int | None = None
    if code == m.Request.HEALTH_MGMT and draw(st.integers(0, 9)):
        sub = draw(st.one_of(st.sampled_from(HEALTH_SUBS), st.integers(0, 255)))
        head += bytes([sub])
    right_length = draw(st.integers(0, 3)) > 0
    size = ARGUMENT_SIZES.get((code, sub), 0) if right_length else draw(st.integers(0, 40))
    return head + draw(st.binary(min_size=size, max_size=size))


@st.composite
def frames(draw: st.DrawFn) -> bytes:
    """A well-formed frame with any command: mostly CTRL_BUS with a fuzzed payload."""
    kind = draw(st.sampled_from(["ctrl", "ctrl", "ctrl", "base_cmd", "sync_echo", "any"]))
    if kind == "ctrl":
        cmd, payload = CTRL_BUS, draw(request_payloads())
    elif kind == "base_cmd":
        cmd, payload = BASE_CMD, draw(st.binary(max_size=3))
    elif kind == "sync_echo":
        cmd, payload = draw(st.sampled_from([0x00, 0x01])), draw(st.binary(max_size=60))
    else:
        cmd, payload = draw(st.integers(0, 255)), draw(st.binary(max_size=30))
    return encode(cmd, payload, long=draw(st.booleans()))


@st.composite
def hostile_pieces(draw: st.DrawFn) -> bytes:
    faults = ["garbage", "corrupt", "truncated", "false_header", "empty"]
    kind = draw(st.sampled_from(["frame"] * 4 + faults))
    if kind == "frame":
        return draw(frames())
    if kind == "garbage":
        return draw(st.binary(min_size=1, max_size=16))
    if kind == "corrupt":
        corrupt = bytearray(draw(frames()))
        corrupt[draw(st.integers(0, len(corrupt) - 1))] ^= draw(st.integers(1, 255))
        return bytes(corrupt)
    if kind == "truncated":
        wire = draw(frames())
        return wire[: draw(st.integers(1, len(wire) - 1))]
    if kind == "false_header":
        if draw(st.booleans()):
            return bytes([0x10, draw(st.integers(0, 255))])
        return bytes([0x50]) + draw(st.integers(0, 0xFFFF)).to_bytes(2, "little")
    return draw(st.sampled_from([bytes.fromhex("10 00 10"), bytes.fromhex("50 00 00 50")]))


# Steps between feeds: mostly small, sometimes beyond the inter-byte timeout or the watchdog.
time_steps = st.one_of(
    st.just(0.0),
    st.floats(0.0, 0.05),
    st.floats(0.05, 0.3),
    st.floats(0.9, 2.5),
)


@st.composite
def timed_feeds(draw: st.DrawFn) -> list[tuple[float, bytes]]:
    """(time, bytes) pieces of a hostile stream; times never run backwards."""
    pieces = draw(st.lists(hostile_pieces(), min_size=4, max_size=40))
    now = draw(st.floats(0.0, 1e6))
    feeds: list[tuple[float, bytes]] = []
    for piece in pieces:
        # Cut some pieces further: a frame may arrive over several feeds.
        if len(piece) > 1 and draw(st.booleans()):
            at = draw(st.integers(1, len(piece) - 1))
            parts = [piece[:at], piece[at:]]
        else:
            parts = [piece]
        for part in parts:
            now += draw(time_steps)
            feeds.append((now, part))
    return feeds


# --- the stream decoder ------------------------------------------------------------------------


@settings(max_examples=400, deadline=None)
@given(
    feeds=timed_feeds(),
    max_frame=st.sampled_from([5, 7, 20, 64, 512, MAX_FRAME]),
    timeout=st.sampled_from([0.0, 0.01, 0.1]),
    timeless=st.booleans(),
)
def test_the_decoder_accounts_for_every_byte_and_stays_bounded(
    feeds: list[tuple[float, bytes]], max_frame: int, timeout: float, timeless: bool
) -> None:
    decoder = StreamDecoder(max_frame=max_frame, timeout=timeout)
    yielded = 0
    fed = 0
    for now, data in feeds:
        for item in decoder.feed_items(data, None if timeless else now):
            if isinstance(item, Frame):
                assert item.size <= max_frame
                yielded += item.size
        fed += len(data)
        assert decoder.buffered < max_frame
        # Every byte is in a frame, discarded, or waiting in the one buffer.
        assert yielded + decoder.stats.bytes_discarded + decoder.buffered == fed
    stats = decoder.stats
    assert stats.resyncs == stats.checksum_errors + stats.oversize + stats.timeouts


@settings(max_examples=200, deadline=None)
@given(
    data=st.binary(max_size=300), times=st.lists(st.floats(allow_nan=True, allow_infinity=True), max_size=5)
)
def test_the_decoder_takes_any_time_value_without_raising(data: bytes, times: list[float]) -> None:
    decoder = StreamDecoder(timeout=0.01)
    for now in times:
        decoder.feed(data, now)
        decoder.feed(b"", now)


@given(max_frame=st.integers(-10, 70_000), timeout=st.floats(allow_nan=True, allow_infinity=True))
def test_decoder_settings_are_accepted_or_refused_with_usage_error(max_frame: int, timeout: float) -> None:
    try:
        decoder = StreamDecoder(max_frame=max_frame, timeout=timeout)
    except UsageError:
        assert not 5 <= max_frame <= MAX_FRAME or not timeout >= 0
    else:
        assert decoder.max_frame == max_frame


# --- the base stack ----------------------------------------------------------------------------

LIMITS = VelocityLimits(max_wheel_mm_s=400.0, max_vx_mps=0.3, max_omega_radps=1.5, wheel_track_mm=240.0)


class RecordingSimulatedBase(SimulatedBase):
    """The simulated base, noting every motion command the stack passes on."""

    def __init__(self) -> None:
        super().__init__(World(seed=1))
        self.velocities: list[tuple[float, float]] = []
        self.wheels: list[tuple[float, float]] = []

    def set_velocity(self, vx_mps: float, vy_mps: float, omega_radps: float) -> SetVAndGetDeadreckonAnswer:
        self.velocities.append((vx_mps, omega_radps))
        return super().set_velocity(vx_mps, vy_mps, omega_radps)

    def set_wheel_speeds(self, left_mm_s: float, right_mm_s: float) -> None:
        self.wheels.append((left_mm_s, right_mm_s))
        super().set_wheel_speeds(left_mm_s, right_mm_s)


def check_answers(out: bytes) -> list[Frame]:
    """The base's output is whole, valid response frames and nothing else."""
    decoder = StreamDecoder(timeout=0)
    answers = decoder.feed(out)
    assert decoder.buffered == 0 and decoder.stats.bytes_discarded == 0, out.hex(" ")
    for answer in answers:
        assert answer.cmd in RESPONSES
        if answer.cmd == m.Response.ERROR:
            assert len(answer.payload) == 2
    return answers


def within(value: float, limit: float) -> bool:
    return abs(value) <= limit * (1 + 1e-9)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(feeds=timed_feeds(), reference_code=st.booleans(), long_answers=st.booleans())
def test_the_simulated_base_answers_any_input_with_valid_frames_within_its_limits(
    feeds: list[tuple[float, bytes]], reference_code: bool, long_answers: bool
) -> None:
    app = RecordingSimulatedBase()
    config = BaseConfig(limits=LIMITS, reference_checksum_code=reference_code, long_answers=long_answers)
    stack = BaseStack(app, config)
    for now, data in feeds:
        check_answers(stack.receive(data, now))
        check_answers(stack.tick(now + 0.001))
        assert stack.counters().decoder.frames >= 0
    assert stack.counters().handler_errors == 0, stack.last_handler_error
    for vx, omega in app.velocities:
        assert within(vx, 0.3) and within(omega, 1.5)
        assert all(within(w, 400.0) for w in wheel_speeds_from_velocity(vx, omega, 240.0))
    for left, right in app.wheels:
        assert within(left, 400.0) and within(right, 400.0)


@settings(max_examples=150, deadline=None)
@given(feeds=timed_feeds(), max_frame=st.sampled_from([5, 64, 512, 4096]))
def test_a_bare_base_answers_any_input_with_valid_frames(
    feeds: list[tuple[float, bytes]], max_frame: int
) -> None:
    stack = BaseStack(Base(), BaseConfig(max_frame=max_frame, watchdog_s=0.5))
    answers: list[Frame] = []
    for now, data in feeds:
        answers += check_answers(stack.receive(data, now))
        answers += check_answers(stack.tick(now))
    counters = stack.counters()
    assert counters.answers == len(answers)
    decoder = counters.decoder
    # One answer per request frame and per reported fault (protocol.md §8.4), and garbage is
    # reported at most once per gap, so never more than once per discarded byte.
    not_synced = sum(1 for a in answers if a.cmd == m.Response.ERROR and a.payload == b"\x10\x00")
    assert not_synced <= decoder.bytes_discarded
    faults = decoder.checksum_errors + decoder.oversize + decoder.empty_frames
    assert len(answers) - not_synced <= decoder.frames + faults


@given(now=st.one_of(st.just(math.nan), st.just(math.inf), st.just(-math.inf), st.booleans()))
def test_a_time_that_is_not_a_number_is_a_usage_error(now: Any) -> None:
    stack = BaseStack(Base(), BaseConfig())
    with pytest.raises(UsageError, match="time"):
        stack.receive(b"\x10", now)
    with pytest.raises(UsageError, match="time"):
        stack.tick(now)


# --- the message codec, binary configuration and fault specs -----------------------------------


@settings(max_examples=1000)
@given(cmd=st.one_of(st.sampled_from([CTRL_BUS, BASE_CMD, 0, 1]), st.integers(0, 255)), data=st.data())
def test_decode_request_returns_a_request_or_raises_a_message_error(cmd: int, data: st.DataObject) -> None:
    payload = data.draw(request_payloads()) if cmd == CTRL_BUS else data.draw(st.binary(max_size=40))
    try:
        request = m.decode_request(cmd, payload)
    except MessageError:
        return
    assert isinstance(request, m.RequestMessage)
    assert m.encode_request(request) == (cmd, payload) or cmd in (0, 1)


ANSWER_SIZES = [0, 1, 2, 4, 5, 13, 17, 28, 39, 64, 69, 264]


@settings(max_examples=1000)
@given(
    to=st.sampled_from(sorted(m.REQUEST_CLASSES)),
    cmd=st.one_of(st.sampled_from(sorted(RESPONSES)), st.integers(0, 255)),
    size=st.one_of(st.sampled_from(ANSWER_SIZES), st.integers(0, 300)),
    data=st.data(),
)
def test_decode_answer_returns_an_answer_or_raises_a_message_error(
    to: str, cmd: int, size: int, data: st.DataObject
) -> None:
    payload = data.draw(st.binary(min_size=size, max_size=size))
    try:
        answer = m.decode_answer(to, cmd, payload)
    except MessageError:
        return
    assert isinstance(answer, m.AnswerMessage)


@settings(max_examples=500)
@given(blob=st.one_of(st.binary(max_size=200), st.binary(max_size=100).map(lambda b: b"\x50" + b)))
def test_the_binary_configuration_reader_raises_only_its_error(blob: bytes) -> None:
    try:
        tree = binconf.decode(blob)
    except BinaryConfigError:
        return
    assert binconf.encode(tree) == blob


SPEC_ALPHABET = "abcdeiklmnoprstuxy=.,:@/-0123456789"


@settings(max_examples=500)
@given(text=st.one_of(st.text(max_size=40), st.text(SPEC_ALPHABET, max_size=40)))
def test_the_fault_spec_parser_raises_only_usage_error(text: str) -> None:
    try:
        spec = FaultSpec.parse(text)
    except UsageError:
        return
    assert FaultSpec.parse(str(spec)) == spec


# --- the Core emulator -------------------------------------------------------------------------


@settings(max_examples=100, deadline=None)
@given(feeds=timed_feeds())
def test_the_core_takes_any_answer_bytes(feeds: list[tuple[float, bytes]]) -> None:
    assume(feeds)
    core = CoreSession()
    start = feeds[0][0]
    core.poll(start)
    for now, data in feeds:
        core.receive(data, now)
        core.poll(now)
