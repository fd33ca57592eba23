# SPDX-License-Identifier: MIT
"""The base framework (ctrlbus.base): bytes in, exact bytes out, with a fake clock.

Every behaviour of docs/base-framework.md's list is checked here on the sans-IO stack, with a
recording application; the runner is checked over an in-process link pair.
"""

from __future__ import annotations

import logging
import struct
import threading
import time
from typing import Any

import pytest
from support import vectorfiles
from support.vectorfiles import hex_bytes

from ctrlbus.base import (
    MAX_HEALTH_ERRORS,
    MAX_PENDING_COMMANDS,
    WATCHDOG_TRIPPED_CODE,
    Base,
    BaseConfig,
    BaseRunner,
    BaseStack,
    CallbackBase,
    Profile,
    VelocityLimits,
    health_code,
    serve,
)
from ctrlbus.errors import LinkError, SimConfigError, UsageError
from ctrlbus.frame import MAX_FRAME, StreamDecoder, encode
from ctrlbus.link import link_pair
from ctrlbus.messages import (
    ConnectBaseAnswer,
    GetBaseBumperDataAnswer,
    GetBaseConfAnswer,
    GetBaseMotorDataAnswer,
    GetBaseSensorDataAnswer,
    GetBaseStatusAnswer,
    GetChargerDataAnswer,
    Position,
    SetVAndGetDeadreckonAnswer,
    answer_frame,
)

CTRL_BUS = 0xF8
OK, ERROR = 0x02, 0x03


def request(payload: bytes, *, long: bool = False) -> bytes:
    return encode(CTRL_BUS, payload, long=long)


def ok(payload: bytes = b"", *, long: bool = True) -> bytes:
    return encode(OK, payload, long=long)


def error(code: int, *, long: bool = True) -> bytes:
    return encode(ERROR, struct.pack("<H", code), long=long)


def set_motor(left: int, right: int) -> bytes:
    return bytes((0x40,)) + struct.pack("<4i", left, right, 0, 0)


def set_velocity(vx_mps: float, omega_radps: float, vy_mps: float = 0.0) -> bytes:
    return bytes((0x41,)) + struct.pack(
        "<3i", round(vx_mps * 65536), round(vy_mps * 65536), round(omega_radps * 65536)
    )


CONNECT = bytes((0x10, 0x01))
GET_STATUS = bytes((0x30,))
GET_HEALTH = bytes((0x90, 0x01))
POLL = bytes((0x50,))
POLL_ANS = bytes((0x5F,))


def get_error(index: int) -> bytes:
    return bytes((0x90, 0x02, index))


def clr_error(code: int) -> bytes:
    return bytes((0x90, 0x03)) + struct.pack("<I", code)


IDENTITY = ConnectBaseAnswer("test base", 0x0102, 3, (1, 2, 3))
DEADRECKON = SetVAndGetDeadreckonAnswer(65536, -2 * 65536, 3 * 65536, 0x02)


class RecordingBase(Base):
    """Implements every request with fixed answers and records every call."""

    def __init__(self) -> None:
        self.calls: list[tuple[Any, ...]] = []
        self.bumper_answer = GetBaseBumperDataAnswer(0xFFFF_FFFE, 4)
        self.deadreckon = DEADRECKON

    def advance(self, now: float) -> None:
        self.calls.append(("advance", now))

    def connect_info(self) -> ConnectBaseAnswer:
        self.calls.append(("connect_info",))
        return IDENTITY

    def base_config(self) -> GetBaseConfAnswer:
        self.calls.append(("base_config",))
        return GetBaseConfAnswer.from_si(
            base_type=0, base_radius_mm=170, sensors=[Position.from_si(1, 2, 3, 315)]
        )

    def binary_config(self) -> bytes:
        self.calls.append(("binary_config",))
        return b"\x50\x00"

    def status(self) -> GetBaseStatusAnswer:
        self.calls.append(("status",))
        return GetBaseStatusAnswer(80, 3)

    def motor_data(self) -> GetBaseMotorDataAnswer:
        self.calls.append(("motor_data",))
        return GetBaseMotorDataAnswer(10, -20, 0)

    def sensor_data(self) -> GetBaseSensorDataAnswer:
        self.calls.append(("sensor_data",))
        return GetBaseSensorDataAnswer.from_si([1000.0, 0.5])

    def bumper_data(self) -> GetBaseBumperDataAnswer:
        self.calls.append(("bumper_data",))
        return self.bumper_answer

    def charger_data(self) -> GetChargerDataAnswer:
        self.calls.append(("charger_data",))
        return GetChargerDataAnswer(3, 3, (1, 2, 4))

    def set_wheel_speeds(self, left_mm_s: float, right_mm_s: float) -> None:
        self.calls.append(("set_wheel_speeds", left_mm_s, right_mm_s))

    def set_velocity(self, vx_mps: float, vy_mps: float, omega_radps: float) -> SetVAndGetDeadreckonAnswer:
        self.calls.append(("set_velocity", vx_mps, vy_mps, omega_radps))
        return self.deadreckon

    def stop_motors(self) -> None:
        self.calls.append(("stop_motors",))

    def on_event(self, event: int) -> None:
        self.calls.append(("on_event", event))

    def on_reboot(self) -> None:
        self.calls.append(("on_reboot",))

    def on_enter_dfu(self) -> None:
        self.calls.append(("on_enter_dfu",))

    def commands(self) -> list[tuple[Any, ...]]:
        """The calls other than time."""
        return [call for call in self.calls if call[0] != "advance"]


def make(config: BaseConfig | None = None, **kwargs: Any) -> tuple[BaseStack, RecordingBase]:
    app = RecordingBase()
    return BaseStack(app, config, **kwargs), app


# --- SYNC and ECHO -----------------------------------------------------------------------------


@pytest.mark.parametrize(
    "frame",
    [
        bytes.fromhex("10 01 00 11"),  # SYNC, no filler (reference §6)
        bytes.fromhex("10 03 01 AA 55 ED"),  # ECHO AA 55
        bytes.fromhex("50 03 00 01 AA 55 AD"),  # the same as a long frame keeps its flag
        encode(0x00, b"\x55" * 200),
        encode(0x00, b"\x00" * 40, long=True),
        encode(0x01, bytes(range(256)) + bytes(range(44))),  # 300 bytes: a long frame
    ],
)
def test_sync_and_echo_come_back_verbatim(frame: bytes) -> None:
    stack, app = make()
    assert stack.receive(frame, 0.0) == frame
    assert app.commands() == []


def test_default_max_frame_is_the_reference_receive_buffer() -> None:
    stack, _ = make()
    flushing_sync = encode(0x00, b"\x00" * 507, long=True)  # the Core emulator's 512-byte SYNC
    assert stack.receive(flushing_sync, 0.0) == flushing_sync
    assert stack.receive(encode(0x00, b"\x00" * 508, long=True), 0.1) == error(0x0020)


def test_echo_of_exactly_max_frame_is_echoed_and_one_more_byte_is_oversize() -> None:
    stack, _ = make(BaseConfig(max_frame=300))
    largest = encode(0x01, b"\xaa" * 295, long=True)  # 5 + 295 = 300 bytes
    assert stack.receive(largest, 0.0) == largest
    assert stack.receive(encode(0x01, b"\xaa" * 296, long=True), 0.1) == error(0x0020)


# --- frame-level errors ------------------------------------------------------------------------


def test_checksum_mismatch_is_answered_0x0040_and_reference_option_0x00c0() -> None:
    stack, _ = make()
    assert stack.receive(bytes.fromhex("10 02 F8 30 DB"), 0.0) == bytes.fromhex("50 03 00 03 40 00 10")
    reference, _ = make(BaseConfig(reference_checksum_code=True))
    assert reference.receive(bytes.fromhex("10 02 F8 30 DB"), 0.0) == error(0x00C0)


def test_a_checksum_failed_set_base_motor_is_not_executed() -> None:
    stack, app = make()
    frame = bytearray(request(set_motor(300, 300)))
    frame[-1] ^= 0xFF
    assert stack.receive(bytes(frame), 0.0) == error(0x0040)
    stack.tick(5.0)  # nothing was moving: the watchdog's idle expiry is no trip
    assert app.commands() == [("stop_motors",)]
    assert stack.counters().watchdog_trips == 0


def test_garbage_is_answered_once_per_gap() -> None:
    stack, _ = make()
    data = b"\xaa" * 20 + request(GET_STATUS) + b"\xbb\xcc\xdd"
    assert stack.receive(data, 0.0) == error(0x0010) + ok(b"\x50\x03") + error(0x0010)
    # More garbage in the same gap, in a later chunk: no second error.
    assert stack.receive(b"\xee" * 5, 0.1) == b""
    assert stack.counters().errors_sent == {0x0010: 2}


def test_oversize_request_is_refused_as_soon_as_its_header_is_in() -> None:
    stack, _ = make()
    assert stack.receive(bytes.fromhex("50 FF FF"), 0.0) == error(0x0020)
    # The rest of the bogus frame is silent (inside the failed candidate's fault), and the next
    # request is answered.
    assert stack.receive(b"\x00" * 50 + request(GET_STATUS), 0.01) == ok(b"\x50\x03")


def test_empty_frame_is_a_format_error() -> None:
    stack, app = make()
    assert stack.receive(bytes.fromhex("10 00 10"), 0.0) == error(0x8001)
    assert stack.receive(bytes.fromhex("50 00 00 50"), 0.0) == error(0x8001)
    assert app.commands() == []


def test_answers_come_in_stream_order() -> None:
    stack, _ = make()
    bad = bytearray(request(GET_STATUS))
    bad[-1] ^= 1
    data = bytes.fromhex("10 01 00 11") + bytes(bad) + request(GET_HEALTH) + encode(0x07, b"")
    assert stack.receive(data, 0.0) == (
        bytes.fromhex("10 01 00 11") + error(0x0040) + ok(b"\x00\x00") + error(0x8000)
    )


def test_byte_by_byte_input_gives_the_same_answers() -> None:
    whole, _ = make()
    data = b"\x01\x02" + request(GET_STATUS) + request(CONNECT) + bytes.fromhex("10 01 00 11")
    expected = whole.receive(data, 0.0)
    split, _ = make()
    answers = b"".join(split.receive(data[i : i + 1], 0.0) for i in range(len(data)))
    assert answers == expected


def test_inter_byte_timeout_answers_nothing_and_frees_the_frames_behind_a_false_start() -> None:
    stack, _ = make(BaseConfig(frame_timeout_s=0.05))
    # A false flag with a plausible length swallows the real request that follows...
    assert stack.receive(bytes.fromhex("50 40 00") + request(GET_STATUS), 0.0) == b""
    assert stack.tick(0.05) == b""  # not yet: the timeout is "more than 50 ms"
    # ...until the timeout, when the request is found again and answered, and nothing else is.
    assert stack.tick(0.06) == ok(b"\x50\x03")
    assert stack.counters().decoder.timeouts == 1


# --- request-level errors ----------------------------------------------------------------------


@pytest.mark.parametrize(
    ("cmd", "payload", "code"),
    [
        (0x05, b"", 0x8000),  # reserved CMD
        (0x02, b"", 0x8000),  # a response code is no request
        (CTRL_BUS, b"\x77", 0x8000),  # unknown control-bus request
        (CTRL_BUS, b"", 0x8001),  # CTRL_BUS without a request code
        (CTRL_BUS, b"\x30\x00", 0x8001),  # status with an extra byte
        (CTRL_BUS, b"\x10", 0x8001),  # CONNECT without its version
        (CTRL_BUS, set_motor(1, 2)[:-1], 0x8001),
        (CTRL_BUS, set_velocity(0.1, 0.0) + b"\x00", 0x8001),
        (CTRL_BUS, b"\x90", 0x8001),  # HEALTH without a sub-command
        (CTRL_BUS, b"\x90\x07", 0x8002),  # unknown HEALTH sub-command
        (CTRL_BUS, b"\x90\x02", 0x8001),  # GET_ERROR without its index
        (CTRL_BUS, b"\x90\x03\x00", 0x8001),  # CLR_ERROR with a short code
        (0xF9, b"", 0x8001),  # BASE_CMD without a sub-command
        (0xF9, b"\x33", 0x8000),  # unknown BASE_CMD sub-command
        (CTRL_BUS, b"\x10\x02", 0x8000),  # CONNECT with protocol version 2
        (CTRL_BUS, b"\x34\x01", 0x8000),  # GET_CHARGER_DATA of an unknown data type
        (CTRL_BUS, b"\x35", 0x8000),  # GET_AUXILIARY_ANCHOR: no layout defined
    ],
)
def test_bad_requests_get_their_error_and_run_nothing(cmd: int, payload: bytes, code: int) -> None:
    stack, app = make()
    assert stack.receive(encode(cmd, payload), 0.0) == error(code)
    assert app.commands() == []
    assert stack.counters().errors_sent == {code: 1}


@pytest.mark.parametrize(
    "payload",
    [
        CONNECT,
        b"\x20",
        b"\x21",
        b"\x30",
        b"\x31",
        b"\x32",
        b"\x33",
        b"\x34\x00",
        set_motor(0, 0),
        set_velocity(0.0, 0.0),
    ],
)
def test_a_request_the_application_leaves_unimplemented_is_0x8000(payload: bytes) -> None:
    stack = BaseStack(Base())
    assert stack.receive(request(payload), 0.0) == error(0x8000)


def test_requests_the_stack_answers_itself_need_nothing_from_the_application() -> None:
    stack = BaseStack(Base())
    assert stack.receive(request(b"\x60\x63"), 0.0) == ok()  # SEND_EVENT: always OK
    assert stack.receive(request(POLL), 0.0) == ok()
    assert stack.receive(request(POLL_ANS), 0.0) == ok()
    assert stack.receive(request(GET_HEALTH), 0.0) == ok(b"\x00\x00")
    assert stack.receive(encode(0xF9, b"\x02"), 0.0) == error(0x8000)  # no reboot hook


class Failing(Base):
    def __init__(self, exc: BaseException) -> None:
        self.exc = exc

    def status(self) -> GetBaseStatusAnswer:
        raise self.exc

    def motor_data(self) -> GetBaseMotorDataAnswer:
        return GetBaseStatusAnswer(1, 2)  # type: ignore[return-value]  # deliberately wrong


def test_handler_errors_answer_0x8002_and_the_stack_goes_on(caplog: pytest.LogCaptureFixture) -> None:
    operation = BaseStack(Failing(SimConfigError("sensor bus down")))
    assert operation.receive(request(GET_STATUS), 0.0) == error(0x8002)
    assert operation.counters().handler_errors == 0  # a CtrlbusError is an operation error, not a bug
    assert operation.last_handler_error is not None and "sensor bus down" in operation.last_handler_error

    buggy = BaseStack(Failing(ZeroDivisionError("oops")))
    with caplog.at_level(logging.ERROR, logger="ctrlbus.base"):
        assert buggy.receive(request(GET_STATUS), 0.0) == error(0x8002)
        assert buggy.receive(request(b"\x31"), 0.0) == error(0x8002)  # wrong answer type
    assert buggy.counters().handler_errors == 2
    assert "GET_BASE_STATUS" in caplog.text and "ZeroDivisionError" in caplog.text
    assert buggy.receive(bytes.fromhex("10 01 00 11"), 0.0) == bytes.fromhex("10 01 00 11")


# --- answers -----------------------------------------------------------------------------------


def test_every_request_is_answered_with_its_message() -> None:
    stack, app = make()
    conf = app.base_config()
    cases = [
        (CONNECT, IDENTITY),
        (b"\x20", conf),
        (b"\x30", GetBaseStatusAnswer(80, 3)),
        (b"\x31", GetBaseMotorDataAnswer(10, -20, 0)),
        (b"\x32", GetBaseSensorDataAnswer.from_si([1000.0, 0.5])),
        (b"\x33", app.bumper_answer),
        (b"\x34\x00", GetChargerDataAnswer(3, 3, (1, 2, 4))),
    ]
    for payload, answer in cases:
        assert stack.receive(request(payload), 0.0) == answer_frame(answer, long=True), payload.hex()
    assert stack.receive(request(b"\x21"), 0.0) == ok(b"\x50\x00")
    assert stack.receive(request(set_motor(-100, 250)), 0.0) == ok()
    assert ("set_wheel_speeds", -100, 250) in app.calls
    assert stack.receive(request(set_velocity(0.25, -0.5, 0.125)), 0.0) == ok(
        struct.pack("<iiiB", 65536, -2 * 65536, 3 * 65536, 2)
    )
    assert ("set_velocity", 0.25, 0.125, -0.5) in app.calls
    assert stack.receive(request(b"\x60\x99"), 0.0) == ok()
    assert ("on_event", 0x99) in app.calls


def test_answers_are_long_by_default_and_standard_when_configured() -> None:
    stack, _ = make(BaseConfig(long_answers=False))
    assert stack.receive(request(GET_STATUS), 0.0) == bytes.fromhex("10 03 02 50 03 42")
    assert stack.receive(request(b"\x77"), 0.0) == error(0x8000, long=False)
    conf = stack.receive(request(b"\x20"), 0.0)
    assert conf[0] == 0x50 and len(conf) == 5 + 264  # too big for a standard frame
    default, _ = make()
    assert default.receive(request(GET_STATUS), 0.0) == bytes.fromhex("50 03 00 02 50 03 02")


def test_reference_profile_sizes() -> None:
    stack, app = make(BaseConfig(profile=Profile.REFERENCE))
    app.deadreckon = SetVAndGetDeadreckonAnswer(1, 2, 3, 0, timestamp_ms=77)
    assert len(stack.receive(request(CONNECT), 0.0)) == 5 + 28
    assert stack.receive(request(set_velocity(0, 0)), 0.0) == ok(struct.pack("<iiiB", 1, 2, 3, 0))
    assert stack.receive(request(POLL), 0.0) == ok()  # nothing pending: OK 0 (base_ref v4)
    app.bumper_answer = GetBaseBumperDataAnswer(0xFE, 1)
    assert stack.receive(request(b"\x33"), 0.0) == ok(b"\xfe")  # as the application gave it


def test_sdk2020_profile_sizes() -> None:
    stack, app = make(BaseConfig(profile="sdk2020"))  # type: ignore[arg-type]  # names are accepted
    assert stack.config.profile is Profile.SDK2020
    connect = stack.receive(request(CONNECT), 10.0)
    assert connect[:4] == bytes.fromhex("50 28 00 02") and len(connect) == 5 + 39
    assert connect[4 + 28 : 4 + 39] == b"\0" * 11  # empty suffix
    # The stack fills in the milliseconds since it started.
    assert stack.receive(request(set_velocity(0, 0)), 12.5) == ok(
        struct.pack("<iiiBI", 65536, -2 * 65536, 3 * 65536, 2, 2500)
    )
    app.deadreckon = SetVAndGetDeadreckonAnswer(0, 0, 0, 0, timestamp_ms=42)  # the application's own
    assert stack.receive(request(set_velocity(0, 0)), 13.0) == ok(struct.pack("<iiiBI", 0, 0, 0, 0, 42))
    assert stack.receive(request(POLL), 13.0) == ok(b"\xff\x00")
    app.bumper_answer = GetBaseBumperDataAnswer(0xFE, 1)
    assert stack.receive(request(b"\x33"), 13.0) == ok(b"\xfe\x00\x00\x00")
    with pytest.raises(UsageError, match="long answers"):
        BaseConfig(profile=Profile.SDK2020, long_answers=False)
    with pytest.raises(UsageError, match="unknown profile 'fancy'"):
        BaseConfig(profile="fancy")  # type: ignore[arg-type]


def test_connect_suffix_is_dropped_in_the_reference_profile() -> None:
    with_suffix = ConnectBaseAnswer("x", 1, 2, (3, 4, 5), "beta")
    reference = BaseStack(CallbackBase(connect_info=lambda: with_suffix))
    assert len(reference.receive(request(CONNECT), 0.0)) == 5 + 28
    sdk = BaseStack(CallbackBase(connect_info=lambda: with_suffix), BaseConfig(profile=Profile.SDK2020))
    answer = sdk.receive(request(CONNECT), 0.0)
    assert answer[4 + 28 : 4 + 32] == b"beta"


# --- motor watchdog ----------------------------------------------------------------------------


def health(stack: BaseStack, now: float) -> tuple[int, int]:
    answer = stack.receive(request(GET_HEALTH), now)
    assert answer[:4] == bytes.fromhex("50 03 00 02"), answer.hex(" ")
    return answer[4], answer[5]


def test_watchdog_trips_after_one_second_without_ctrl_bus_and_shows_in_health() -> None:
    stack, app = make()
    assert stack.receive(request(set_motor(200, 200)), 0.0) == ok()
    trip_time = None
    now = 0.0
    for step in range(1, 200):
        now = step * 0.01
        # SYNC does not feed the watchdog.
        assert stack.receive(bytes.fromhex("10 01 00 11"), now) == bytes.fromhex("10 01 00 11")
        if ("stop_motors",) in app.calls:
            trip_time = now
            break
    assert trip_time is not None
    assert 1.0 < trip_time <= 1.0 + 0.01 + 1e-9  # 1.0 s, within one tick
    # The application's time was brought to the deadline itself before the stop.
    stop_index = app.calls.index(("stop_motors",))
    assert app.calls[stop_index - 1] == ("advance", 1.0)
    assert stack.counters().watchdog_trips == 1
    flags, count = health(stack, now)
    assert flags & 0x01 and count == 1
    code_and_text = stack.receive(request(get_error(0)), now)
    assert code_and_text[4:8] == struct.pack("<I", 0x01038000) == struct.pack("<I", WATCHDOG_TRIPPED_CODE)
    assert code_and_text[8:].split(b"\0")[0] == b"motor watchdog tripped"
    # The Core clears it; clearing it again is an operation error.
    assert stack.receive(request(clr_error(WATCHDOG_TRIPPED_CODE)), now) == ok()
    assert health(stack, now) == (0, 0)
    assert stack.receive(request(clr_error(WATCHDOG_TRIPPED_CODE)), now) == error(0x8002)
    assert stack.receive(request(get_error(0)), now) == error(0x8002)


def test_watchdog_stops_once_per_silence_and_trips_only_when_something_moved() -> None:
    stack, app = make()
    stack.tick(0.0)
    stack.tick(5.0)  # idle from power-up: zero speed is commanded once, but it is no trip
    stack.tick(6.0)
    assert app.commands() == [("stop_motors",)]
    assert stack.counters().watchdog_trips == 0 and health(stack, 6.0) == (0, 0)
    stack.receive(request(set_velocity(0.2, 0.0)), 6.0)
    for step in range(1, 40):
        stack.tick(6.0 + step * 0.1)
    assert app.commands().count(("stop_motors",)) == 2
    assert stack.counters().watchdog_trips == 1 and health(stack, 10.0) == (1, 1)
    # A zero command means nothing is moving: the silence after it is no trip.
    stack.receive(request(set_velocity(0.0, 0.0)), 10.0)
    stack.tick(20.0)
    assert app.commands().count(("stop_motors",)) == 3
    assert stack.counters().watchdog_trips == 1
    # A second trip while the warning is registered counts, but adds no second entry.
    stack.receive(request(set_motor(10, 10)), 20.0)
    stack.tick(22.0)
    assert stack.counters().watchdog_trips == 2 and health(stack, 22.0) == (1, 1)


def test_any_ctrl_bus_frame_feeds_the_watchdog_even_a_refused_one() -> None:
    stack, app = make()
    stack.receive(request(set_motor(100, 100)), 0.0)
    for step in range(1, 10):
        payload = GET_STATUS if step % 2 else b"\x77"  # unknown requests count too
        stack.receive(request(payload), step * 0.6)
    assert ("stop_motors",) not in app.calls
    last = 9 * 0.6
    stack.tick(last + 1.0)
    assert ("stop_motors",) not in app.calls
    stack.tick(last + 1.01)
    assert ("stop_motors",) in app.calls


def test_watchdog_can_be_configured_or_switched_off() -> None:
    fast, fast_app = make(BaseConfig(watchdog_s=0.2))
    fast.receive(request(set_motor(1, 1)), 0.0)
    fast.tick(0.2)
    assert ("stop_motors",) not in fast_app.calls
    fast.tick(0.21)
    assert ("stop_motors",) in fast_app.calls
    off, off_app = make(BaseConfig(watchdog_s=None))
    off.receive(request(set_motor(1, 1)), 0.0)
    off.tick(100.0)
    assert ("stop_motors",) not in off_app.calls


def test_default_stop_motors_sets_zero_wheel_speeds() -> None:
    speeds: list[tuple[float, float]] = []
    stack = BaseStack(CallbackBase(set_wheel_speeds=lambda left, right: speeds.append((left, right))))
    stack.receive(request(set_motor(50, 60)), 0.0)
    stack.tick(2.0)
    assert speeds == [(50, 60), (0.0, 0.0)]


# --- velocity limits ---------------------------------------------------------------------------


def test_wheel_speeds_beyond_the_limit_are_scaled_down_together_and_counted() -> None:
    stack, app = make(BaseConfig(limits=VelocityLimits(max_wheel_mm_s=300)))
    stack.receive(request(set_motor(600, 300)), 0.0)
    stack.receive(request(set_motor(-300, 299)), 0.0)
    stack.receive(request(set_motor(-900, 0)), 0.0)
    assert [call for call in app.calls if call[0] == "set_wheel_speeds"] == [
        ("set_wheel_speeds", 300.0, 150.0),
        ("set_wheel_speeds", -300, 299),
        ("set_wheel_speeds", -300.0, 0.0),
    ]
    assert stack.counters().clamped_commands == 2


def test_velocity_beyond_the_limits_is_clamped_and_counted() -> None:
    limits = VelocityLimits(max_vx_mps=0.5, max_omega_radps=1.0, max_wheel_mm_s=550, wheel_track_mm=200)
    stack, app = make(BaseConfig(limits=limits))
    stack.receive(request(set_velocity(0.25, 0.5)), 0.0)  # within: left 200, right 300
    stack.receive(request(set_velocity(-2.0, 0.0)), 0.0)  # vx clamped to -0.5
    stack.receive(request(set_velocity(0.0, -4.0)), 0.0)  # omega clamped to -1
    stack.receive(request(set_velocity(0.5, 1.0)), 0.0)  # wheels 400 / 600: scaled by 550/600
    calls = [call for call in app.calls if call[0] == "set_velocity"]
    assert calls[:3] == [
        ("set_velocity", 0.25, 0.0, 0.5),
        ("set_velocity", -0.5, 0.0, 0.0),
        ("set_velocity", 0.0, 0.0, -1.0),
    ]
    _, vx, _, omega = calls[3]
    assert vx == pytest.approx(0.5 * 550 / 600) and omega == pytest.approx(550 / 600)
    assert stack.counters().clamped_commands == 3


def test_zero_means_no_limit() -> None:
    stack, app = make(BaseConfig(limits=VelocityLimits(max_wheel_mm_s=0, max_vx_mps=0, max_omega_radps=0)))
    assert stack.config.limits == VelocityLimits()
    stack.receive(request(set_motor(5000, -5000)) + request(set_velocity(3.0, -9.0)), 0.0)
    assert app.commands() == [("set_wheel_speeds", 5000, -5000), ("set_velocity", 3.0, 0.0, -9.0)]
    assert stack.counters().clamped_commands == 0


def test_limits_reject_nonsense() -> None:
    with pytest.raises(UsageError, match="max_wheel_mm_s"):
        VelocityLimits(max_wheel_mm_s=-1)
    with pytest.raises(UsageError, match="max_vx_mps"):
        VelocityLimits(max_vx_mps=float("nan"))
    for bad in ({"watchdog_s": 0}, {"max_frame": 4}, {"frame_timeout_s": -1}, {"limits": "fast"}):
        with pytest.raises(UsageError):
            BaseConfig(**bad)


# --- external commands: POLL_BASE_CMD / POLL_BASE_ANS_CMD ------------------------------------


def test_poll_and_answer_flow_with_the_command_line() -> None:
    line: list[bool] = []
    stack, _ = make(on_command_line=line.append)
    assert stack.receive(request(POLL), 0.0) == ok()
    stack.queue_external_command(0xA0)
    stack.queue_external_command(0xA2)
    assert line == [True]
    assert stack.pending_commands == (0xA0, 0xA2)
    # POLL offers the oldest command until the Core says it has taken it.
    assert stack.receive(request(POLL), 0.0) == ok(b"\xa0\x00")
    assert stack.receive(request(POLL), 0.0) == ok(b"\xa0\x00")
    assert stack.receive(request(POLL_ANS), 0.0) == ok()
    assert stack.receive(request(POLL), 0.0) == ok(b"\xa2\x00")
    assert line == [True]
    assert stack.receive(request(POLL_ANS), 0.0) == ok()
    assert line == [True, False]
    assert stack.receive(request(POLL), 0.0) == ok()
    assert stack.receive(request(POLL_ANS), 0.0) == ok()  # nothing to take: still OK
    counters = stack.counters()
    assert (counters.external_commands_queued, counters.external_commands_taken) == (2, 2)


def test_external_command_queue_refuses_unknown_codes_and_overflow() -> None:
    stack, _ = make()
    for bad in (0xFF, 0x00, 0x54, -1, 256, True, "A0"):
        with pytest.raises(UsageError, match="not an external command"):
            stack.queue_external_command(bad)  # type: ignore[arg-type]
    for _ in range(MAX_PENDING_COMMANDS):
        stack.queue_external_command(0xAF)
    with pytest.raises(UsageError, match="full"):
        stack.queue_external_command(0xAF)
    stack.clear_external_commands()
    assert stack.pending_commands == ()


def test_queueing_from_another_thread_while_receiving() -> None:
    stack, _ = make()
    offered: list[bytes] = []

    def queue() -> None:
        for _ in range(200):
            if len(stack.pending_commands) < MAX_PENDING_COMMANDS:
                stack.queue_external_command(0xA1)

    worker = threading.Thread(target=queue)
    worker.start()
    for step in range(400):
        offered.append(stack.receive(request(POLL) + request(POLL_ANS), step * 0.001))
    worker.join()
    while stack.pending_commands:
        offered.append(stack.receive(request(POLL) + request(POLL_ANS), 1.0))
    taken = sum(answer.startswith(ok(b"\xa1\x00")) for answer in offered)
    assert taken == stack.counters().external_commands_queued


# --- health ------------------------------------------------------------------------------------


def test_health_registry_flags_order_and_limits() -> None:
    stack, _ = make()
    warning = health_code(1, 2, 0x01, 0)
    error_code = health_code(2, 4, 0x03, 1)
    fatal = health_code(4, 1, 0x01, 0)
    assert warning == 0x01020100 and error_code == 0x02040301
    stack.health.add(warning, "battery low")
    stack.health.add(error_code, "sonar down")
    assert health(stack, 0.0) == (0x03, 2)
    assert not stack.health.add(warning, "battery still low")  # same code: nothing changes
    answer = stack.receive(request(get_error(0)), 0.0)
    assert answer == ok(struct.pack("<I", warning) + b"battery low".ljust(32, b"\0"))
    assert stack.receive(request(get_error(2)), 0.0) == error(0x8002)
    stack.health.add(fatal, "")
    assert health(stack, 0.0) == (0x07, 3)
    assert stack.receive(request(clr_error(error_code)), 0.0) == ok()
    assert [entry.code for entry in stack.health.entries] == [warning, fatal]
    assert health(stack, 0.0) == (0x05, 2)
    with pytest.raises(UsageError, match="31"):
        stack.health.add(0x01000001, "x" * 32)
    with pytest.raises(UsageError):
        stack.health.add(1 << 32, "too big")
    for index in range(MAX_HEALTH_ERRORS - 2):
        stack.health.add(0x01000000 + index + 10, "filler")
    with pytest.raises(UsageError, match="full"):
        stack.health.add(0x01FFFFFF, "one more")
    with pytest.raises(UsageError, match="level"):
        health_code(256, 0, 0, 0)


# --- BASE_CMD REBOOT and events ----------------------------------------------------------------


def test_reboot_answers_ok_then_resets_after_the_answer_was_handed_over() -> None:
    line: list[bool] = []
    stack, app = make(on_command_line=line.append)
    stack.tick(0.0)
    stack.queue_external_command(0xA0)
    stack.health.add(0x01020100, "battery low")
    # What follows the REBOOT in the same input is not heard: the base is resetting.
    data = encode(0xF9, b"\x02") + request(GET_STATUS) + bytes.fromhex("10 05 F8")
    assert stack.receive(data, 0.5) == ok()
    assert ("on_reboot",) not in app.calls and ("status",) not in app.calls
    assert stack.pending_commands == (0xA0,)  # nothing reset before the answer has gone out
    # The next call (the runner's next read, after it wrote the answer) does the reset.
    assert stack.receive(request(GET_STATUS), 0.8) == ok(b"\x50\x03")  # no stale "10 05 F8" prefix
    assert app.commands() == [("on_reboot",), ("status",)]
    assert not stack.pending_commands and len(stack.health) == 0
    assert line == [True, False]
    assert stack.uptime_s == 0.0
    counters = stack.counters()
    assert counters.reboots == 1 and counters.requests["BASE_CMD"] == 1
    assert counters.decoder.frames == 3  # the decoder read the status request nobody heard
    # A REBOOT that ends its input: the next input is heard (by the rebooted base).
    assert stack.receive(encode(0xF9, b"\x02"), 0.9) == ok()
    assert stack.receive(request(GET_STATUS), 0.95) == ok(b"\x50\x03")
    assert stack.counters().reboots == 2


def test_enter_dfu_runs_the_application_hook_after_its_answer() -> None:
    stack, app = make()
    assert stack.receive(encode(0xF9, b"\x01") + request(GET_STATUS), 0.0) == ok() + ok(b"\x50\x03")
    assert ("on_enter_dfu",) not in app.calls
    stack.tick(0.1)
    assert ("on_enter_dfu",) in app.calls
    assert stack.counters().reboots == 0
    assert BaseStack(CallbackBase()).receive(encode(0xF9, b"\x01"), 0.0) == error(0x8000)
    with_hook = BaseStack(CallbackBase(on_enter_dfu=lambda: None))
    assert with_hook.receive(encode(0xF9, b"\x01"), 0.0) == ok()


def test_reboot_without_a_hook_changes_nothing() -> None:
    stack = BaseStack(Base())
    stack.queue_external_command(0xA0)
    assert stack.receive(encode(0xF9, b"\x02"), 0.0) == error(0x8000)
    assert stack.pending_commands == (0xA0,)


# --- time, counters, construction --------------------------------------------------------------


def test_time_must_be_finite_and_never_runs_backwards() -> None:
    stack, app = make()
    for bad in (float("nan"), float("inf"), None, "1"):
        with pytest.raises(UsageError, match="time"):
            stack.receive(b"", bad)  # type: ignore[arg-type]
    stack.tick(5.0)
    stack.tick(4.0)
    assert [call for call in app.calls if call[0] == "advance"] == [("advance", 5.0), ("advance", 5.0)]


def test_counters_count_everything() -> None:
    stack, _ = make()
    data = (
        b"\xaa" + request(GET_STATUS) + request(GET_STATUS) + bytes.fromhex("10 01 00 11") + request(b"\x77")
    )
    answers = stack.receive(data, 0.0)
    counters = stack.counters()
    assert counters.bytes_received == len(data) and counters.bytes_sent == len(answers)
    assert counters.answers == 5
    assert dict(counters.requests) == {"GET_BASE_STATUS": 2, "SYNC": 1}
    assert counters.as_dict()["errors_sent"] == {"0x0010": 1, "0x8000": 1}
    assert counters.decoder.frames == 4 and counters.decoder.bytes_discarded == 1


def test_callback_base_checks_its_handlers() -> None:
    with pytest.raises(UsageError, match="unknown base handler"):
        CallbackBase(stauts=lambda: None)
    with pytest.raises(UsageError, match="callable"):
        CallbackBase(status=42)  # type: ignore[arg-type]
    app = CallbackBase()
    BaseStack(app)
    with pytest.raises(UsageError, match="already attached"):
        BaseStack(app)
    with pytest.raises(UsageError, match="not attached"):
        _ = Base().stack


def test_implements_tells_which_hooks_the_application_provides() -> None:
    assert RecordingBase().implements("on_reboot") and not Base().implements("on_reboot")
    assert not CallbackBase().implements("on_reboot")
    assert CallbackBase(on_reboot=lambda: None).implements("on_reboot")

    class Sub(CallbackBase):
        def on_enter_dfu(self) -> None:
            pass

    assert Sub().implements("on_enter_dfu") and not Sub().implements("on_reboot")
    assert not Base().implements("no_such_method")


# --- shared vectors ----------------------------------------------------------------------------


def vector_cases(key: str) -> list[Any]:
    entries = vectorfiles.section("invalid.json", key) or []
    with_answer = [entry for entry in entries if "base_answer" in entry]
    if not with_answer:
        raise FileNotFoundError(f"vectors/invalid.json is missing or no {key} vector has a base_answer")
    return [pytest.param(entry, id=str(entry.get("name"))) for entry in with_answer]


@pytest.mark.parametrize("vector", vector_cases("frame_level"))
def test_frame_level_vectors_get_their_base_answer(vector: dict[str, Any]) -> None:
    # The vector's decoder settings: max_frame as given (else the decoder's default) and its
    # timeout, if any, followed by an idle gap longer than it.
    timeout_s = vector.get("timeout_ms", 0) / 1000.0
    config = BaseConfig(max_frame=vector.get("max_frame", MAX_FRAME), frame_timeout_s=timeout_s)
    stack, _ = make(config)
    answer = stack.receive(hex_bytes(vector["hex"]), 0.0)
    if timeout_s:
        answer += stack.tick(2.0 * timeout_s + 0.001)
    assert answer == hex_bytes(vector["base_answer"])


@pytest.mark.parametrize("vector", vector_cases("message_level"))
def test_message_level_vectors_get_their_base_answer(vector: dict[str, Any]) -> None:
    assert vector["direction"] == "request"
    stack, app = make()
    frame = encode(vector["cmd"], hex_bytes(vector["payload"]), long=vector.get("long", False))
    assert stack.receive(frame, 0.0) == hex_bytes(vector["base_answer"])
    assert app.commands() == []


def test_readme_examples_of_base_answers() -> None:
    """The two examples in vectors/README.md, so the rule is checked before invalid.json exists."""
    stack, _ = make()
    assert stack.receive(bytes.fromhex("10 02 F8 30 DB"), 0.0) == bytes.fromhex("50 03 00 03 40 00 10")
    assert stack.receive(encode(CTRL_BUS, b"\x30\x00"), 0.0) == bytes.fromhex("50 03 00 03 01 80 D1")


# --- the real-time runner ----------------------------------------------------------------------


def exchange(link: Any, data: bytes, expected_size: int, limit_s: float = 5.0) -> bytes:
    link.write(data)
    received = b""
    deadline = time.monotonic() + limit_s
    while len(received) < expected_size and time.monotonic() < deadline:
        received += link.read(0.05)
    return received


def test_runner_serves_a_link_and_stops_cleanly() -> None:
    core_end, base_end = link_pair()
    stack, app = make()
    with BaseRunner(stack, base_end) as runner:
        assert runner.running
        assert exchange(core_end, request(GET_STATUS), 7) == ok(b"\x50\x03")
        assert exchange(core_end, bytes.fromhex("10 01 00 11"), 4) == bytes.fromhex("10 01 00 11")
    assert not runner.running and runner.failure is None
    assert any(call[0] == "advance" for call in app.calls)  # it ticks while idle
    core_end.close()


def test_runner_reports_a_failed_link() -> None:
    core_end, base_end = link_pair()
    stack, _ = make()
    runner = BaseRunner(stack, base_end).start()
    core_end.close()  # the pipe is gone: the base's read fails
    assert runner.wait(5.0)
    assert isinstance(runner.failure, LinkError)


def test_serve_uses_the_given_clock_and_stop_event() -> None:
    core_end, base_end = link_pair()
    stack, app = make()
    stop = threading.Event()
    ticks = iter(range(1_000_000))

    def clock() -> float:
        return float(next(ticks)) * 10.0  # 10 s per read: the watchdog trips on the second tick

    core_end.write(request(set_motor(5, 5)))
    thread = threading.Thread(
        target=serve, args=(stack, base_end), kwargs={"clock": clock, "stop_event": stop}
    )
    thread.start()
    try:
        deadline = time.monotonic() + 5.0
        while ("stop_motors",) not in app.calls and time.monotonic() < deadline:
            time.sleep(0.01)
    finally:
        stop.set()
        thread.join(5.0)
    assert not thread.is_alive()
    assert ("stop_motors",) in app.calls
    assert StreamDecoder().feed(core_end.read(0.1))[0].cmd == OK
    with pytest.raises(UsageError):
        serve(stack, base_end, poll_s=0)
