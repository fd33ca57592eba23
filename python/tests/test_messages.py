# SPDX-License-Identifier: MIT
"""Typed messages: layouts from the reference, both historic variants, every error path."""

from __future__ import annotations

import math
from typing import Any

import pytest

from ctrlbus import messages as m
from ctrlbus.errors import MessageFormatError, UnsupportedMessageError, UnsupportedSubcommandError

# Contract names (vectors/README.md tables).
CONTRACT_REQUESTS = {
    "SYNC",
    "ECHO",
    "BASE_CMD",
    "CONNECT_BASE",
    "GET_BASE_CONF",
    "GET_BASE_CONF_ADV",
    "GET_BASE_STATUS",
    "GET_BASE_MOTOR_DATA",
    "GET_BASE_SENSOR_DATA",
    "GET_BASE_BUMPER_DATA",
    "GET_CHARGER_DATA",
    "GET_AUXILIARY_ANCHOR",
    "SET_BASE_MOTOR",
    "SET_V_AND_GET_DEADRECKON",
    "POLL_BASE_CMD",
    "POLL_BASE_ANS_CMD",
    "SEND_EVENT",
    "HEALTH_GET_HEALTH",
    "HEALTH_GET_ERROR",
    "HEALTH_CLR_ERROR",
}


def h(text: str) -> bytes:
    return bytes.fromhex(text)


# --- codes and registry ------------------------------------------------------------------------


def test_codes_match_the_reference() -> None:
    assert (m.Cmd.SYNC, m.Cmd.ECHO, m.Cmd.CTRL_BUS, m.Cmd.BASE_CMD) == (0x00, 0x01, 0xF8, 0xF9)
    assert (m.Response.OK, m.Response.ERROR, m.Response.INVALID) == (0x02, 0x03, 0xFF)
    assert [code.value for code in m.ErrorCode] == [0x0010, 0x0020, 0x0040, 0x00C0, 0x8000, 0x8001, 0x8002]
    assert (m.Request.HEALTH_MGMT.value, m.Request.POLL_BASE_ANS_CMD.value) == (0x90, 0x5F)
    assert (m.BaseSubcommand.REBOOT.value, m.HealthSub.CLR_ERROR.value) == (0x02, 0x03)
    assert (m.ExternalCommand.GO_HOME.value, m.Event.END_VACUUM.value) == (0xA4, 0x83)


def test_the_registry_knows_every_contract_name_both_ways() -> None:
    assert set(m.REQUEST_CLASSES) == CONTRACT_REQUESTS
    for name, cls in m.REQUEST_CLASSES.items():
        assert name == cls.NAME and m.request_class(name) is cls
    assert set(m.OK_ANSWER_CLASSES) == CONTRACT_REQUESTS - {"SYNC", "ECHO", "GET_AUXILIARY_ANCHOR"}
    for to, answer in m.OK_ANSWER_CLASSES.items():
        assert answer.NAME == "OK" and m.answer_class(to, "OK") is answer
    for name in ("ERROR", "INVALID", "SYNC", "ECHO"):
        assert name == m.answer_class("GET_BASE_STATUS", name).NAME
    with pytest.raises(UnsupportedMessageError):
        m.request_class("GET_EVERYTHING")
    with pytest.raises(UnsupportedMessageError):
        m.answer_class("GET_AUXILIARY_ANCHOR", "OK")
    with pytest.raises(UnsupportedMessageError):
        m.answer_class("GET_BASE_STATUS", "MAYBE")


# --- requests ----------------------------------------------------------------------------------

REQUEST_LAYOUTS: list[tuple[m.RequestMessage, int, str]] = [
    (m.Sync(), 0x00, ""),
    (m.Sync(h("00 00 00")), 0x00, "00 00 00"),
    (m.Echo(h("AA 55")), 0x01, "AA 55"),
    (m.BaseCommand(m.BaseSubcommand.REBOOT), 0xF9, "02"),
    (m.ConnectBase(), 0xF8, "10 01"),
    (m.GetBaseConf(), 0xF8, "20"),
    (m.GetBaseConfAdv(), 0xF8, "21"),
    (m.GetBaseStatus(), 0xF8, "30"),
    (m.GetBaseMotorData(), 0xF8, "31"),
    (m.GetBaseSensorData(), 0xF8, "32"),
    (m.GetBaseBumperData(), 0xF8, "33"),
    (m.GetChargerData(), 0xF8, "34 00"),
    (m.GetAuxiliaryAnchor(), 0xF8, "35"),
    (m.SetBaseMotor.from_wheels(100, -100), 0xF8, "40 64 00 00 00 9C FF FF FF 00 00 00 00 00 00 00 00"),
    (m.SetVAndGetDeadreckon(13107, 0, 32768), 0xF8, "41 33 33 00 00 00 00 00 00 00 80 00 00"),
    (m.PollBaseCmd(), 0xF8, "50"),
    (m.PollBaseAnsCmd(), 0xF8, "5F"),
    (m.SendEvent(m.Event.SYSTEM_UP_OK), 0xF8, "60 63"),
    (m.HealthGetHealth(), 0xF8, "90 01"),
    (m.HealthGetError(3), 0xF8, "90 02 03"),
    (m.HealthClrError(0x01020100), 0xF8, "90 03 00 01 02 01"),
]


@pytest.mark.parametrize(
    ("request_msg", "cmd", "payload"), REQUEST_LAYOUTS, ids=lambda v: getattr(v, "NAME", None)
)
def test_request_layouts(request_msg: m.RequestMessage, cmd: int, payload: str) -> None:
    assert m.encode_request(request_msg) == (cmd, h(payload))
    assert m.decode_request(cmd, h(payload)) == request_msg


def test_request_frames_are_the_reference_examples() -> None:
    assert m.request_frame(m.Sync()) == h("10 01 00 11")
    assert m.request_frame(m.Echo(h("AA 55")), long=True) == h("50 03 00 01 AA 55 AD")
    assert m.request_frame(m.ConnectBase(1)) == h("10 03 F8 10 01 FA")
    assert m.request_frame(m.GetBaseStatus(), long=True) == h("50 02 00 F8 30 9A")
    setv = m.SetVAndGetDeadreckon.from_si(vx_mps=0.2, omega_radps=0.5)
    assert m.request_frame(setv) == h("10 0E F8 41 33 33 00 00 00 00 00 00 00 80 00 00 27")


@pytest.mark.parametrize(
    ("request_msg", "cmd", "payload"), REQUEST_LAYOUTS, ids=lambda v: getattr(v, "NAME", None)
)
def test_a_request_one_byte_too_long_or_short_is_a_format_error(
    request_msg: m.RequestMessage, cmd: int, payload: str
) -> None:
    if cmd in (m.Cmd.SYNC, m.Cmd.ECHO):
        return  # any length is valid
    with pytest.raises(MessageFormatError) as longer:
        m.decode_request(cmd, h(payload) + b"\x00")
    assert longer.value.error_code == 0x8001
    minimum = 1 if request_msg.SUB is None else 2  # the request code (and sub-command) must be there
    if cmd != m.Cmd.CTRL_BUS or len(h(payload)) > minimum:
        with pytest.raises(MessageFormatError):
            m.decode_request(cmd, h(payload)[:-1])


def test_unknown_commands_requests_and_sub_commands() -> None:
    for cmd in (0x02, 0x0F, 0x10, 0xF7, 0xFA, 0xFF):
        with pytest.raises(UnsupportedMessageError) as error:
            m.decode_request(cmd, b"")
        assert error.value.error_code == 0x8000
    with pytest.raises(UnsupportedMessageError) as request_error:
        m.decode_request(0xF8, h("11"))
    assert type(request_error.value) is UnsupportedMessageError and request_error.value.error_code == 0x8000
    for sub in (0x00, 0x04, 0xFF):
        with pytest.raises(UnsupportedSubcommandError) as sub_error:
            m.decode_request(0xF8, bytes((0x90, sub)))
        assert sub_error.value.error_code == 0x8002
    with pytest.raises(MessageFormatError):
        m.decode_request(0xF8, b"")  # no request code at all
    with pytest.raises(MessageFormatError):
        m.decode_request(0xF8, h("90"))  # HEALTH_MGMT without its sub-command


def test_unsupported_argument_values_are_refused_both_ways() -> None:
    # Right layout, value the protocol does not support: unsupported (0x8000), not a format error.
    for payload in ("10 02", "10 00", "34 01"):
        with pytest.raises(UnsupportedMessageError) as error:
            m.decode_request(0xF8, h(payload))
        assert error.value.error_code == 0x8000
    for subcommand in (0x00, 0x03, 0xFF):
        with pytest.raises(UnsupportedMessageError):
            m.decode_request(0xF9, bytes((subcommand,)))
    for build in (lambda: m.ConnectBase(2), lambda: m.GetChargerData(1), lambda: m.BaseCommand(3)):
        with pytest.raises(UnsupportedMessageError):
            build()
    # Any event code is legal: a base answers OK to unknown ones.
    assert m.decode_request(0xF8, h("60 FE")) == m.SendEvent(0xFE)


def test_set_v_float_helpers() -> None:
    request = m.SetVAndGetDeadreckon.from_si(vx_mps=0.2, omega_radps=0.5)
    assert (request.vx_mps_q16, request.vy_mps_q16, request.omega_radps_q16) == (13107, 0, 32768)
    assert request.omega_radps == 0.5 and abs(request.vx_mps - 0.2) < 1 / 65536
    backwards = m.SetVAndGetDeadreckon.from_si(vx_mps=-0.2, omega_radps=-1.0)
    assert m.decode_request(*m.encode_request(backwards)) == backwards
    assert backwards.vx_mps_q16 == -13107 and backwards.omega_radps_q16 == -65536


def test_wheel_speed_helpers() -> None:
    motor = m.SetBaseMotor.from_wheels(250, -250)
    assert motor.speeds_mm_s == (250, -250, 0, 0) and (motor.left_mm_s, motor.right_mm_s) == (250, -250)
    assert m.SetBaseMotor([1, 2, 3, 4]).speeds_mm_s == (1, 2, 3, 4)  # type: ignore[arg-type]


# --- fixed point -------------------------------------------------------------------------------


def test_fixed_point_helpers_round_and_check_ranges() -> None:
    assert m.to_q16(0.2) == 13107 and m.to_q16(0.5) == 32768 and m.to_q16(-0.5) == -32768
    assert m.to_q8(170.5, signed=False) == 43648 and m.from_q8(43648) == 170.5
    assert m.to_q16(1 / 131072) == 0  # half a step rounds to even
    assert m.to_q16(3 / 131072) == 2
    assert m.from_q16(-65536) == -1.0
    assert m.to_q16(32767.99998) == 0x7FFF_FFFF
    with pytest.raises(MessageFormatError, match="s32"):
        m.to_q16(32768.0)
    with pytest.raises(MessageFormatError, match="s32"):
        m.to_q16(-32768.00001)
    assert m.to_q16(-32768.0) == -(1 << 31)
    with pytest.raises(MessageFormatError, match="u32"):
        m.to_q8(-1.0, signed=False)
    for bad in (math.nan, math.inf, -math.inf):
        with pytest.raises(MessageFormatError, match="finite"):
            m.to_q16(bad)
    with pytest.raises(MessageFormatError):
        m.SetVAndGetDeadreckon.from_si(vx_mps=40000.0)


def test_position_helpers() -> None:
    position = m.Position.from_si(x_mm=100, y_mm=-20.5, z_mm=30, angle_deg=315)
    assert position == m.Position(25600, -5248, 7680, 80640)
    assert (position.x_mm, position.y_mm, position.z_mm, position.angle_deg) == (100, -20.5, 30, 315)
    with pytest.raises(MessageFormatError):
        m.Position.from_si(angle_deg=-45)  # the reference wants 315, not -45


# --- answers -----------------------------------------------------------------------------------


def test_answer_frames_are_the_reference_examples() -> None:
    assert m.answer_frame(m.EmptyAnswer(), long=True) == h("50 01 00 02 53")
    assert m.answer_frame(m.GetBaseStatusAnswer(80, 3), long=True) == h("50 03 00 02 50 03 02")
    assert m.answer_frame(m.PollBaseCmdAnswer(None, 2, 0), long=True) == h("50 03 00 02 FF 00 AE")
    assert m.answer_frame(m.HealthGetHealthAnswer(0, 0), long=True) == h("50 03 00 02 00 00 51")
    assert m.answer_frame(m.ErrorAnswer(m.ErrorCode.UNSUPPORTED), long=True) == h("50 03 00 03 00 80 D0")
    assert m.answer_frame(m.ErrorAnswer(m.ErrorCode.TOO_LONG), long=True) == h("50 03 00 03 20 00 70")


def test_connect_answer_in_both_sizes() -> None:
    short = m.ConnectBaseAnswer("ref base", 0x0114, 0x0001, (0x11111111, 0x22222222, 0x33333333))
    cmd, payload = m.encode_answer(short)
    assert cmd == m.Response.OK and len(payload) == 28
    assert payload[:12] == b"ref base\0\0\0\0" and payload[12:16] == h("14 01 01 00")
    assert payload[16:] == h("11 11 11 11 22 22 22 22 33 33 33 33")
    assert m.decode_answer("CONNECT_BASE", cmd, payload) == short
    assert short.firmware_version_text == "1.20"
    full = m.ConnectBaseAnswer("ref base", 0x0114, 1, (1, 2, 3), firmware_version_suffix="-rc1")
    payload = m.encode_answer(full)[1]
    assert len(payload) == 39 and payload[28:] == b"-rc1" + bytes(7)
    assert m.decode_answer(m.ConnectBase(), 0x02, payload) == full
    # Text stops at the first NUL; what follows it is not kept.
    odd = b"ref\0junk\0\0\0\0" + payload[12:28]
    assert m.decode_answer("CONNECT_BASE", 0x02, odd).model == "ref"  # type: ignore[attr-defined]
    for size in (27, 29, 38, 40):
        with pytest.raises(MessageFormatError):
            m.decode_answer("CONNECT_BASE", 0x02, bytes(size))
    with pytest.raises(MessageFormatError):
        m.ConnectBaseAnswer("a model name too long", 0, 0, (0, 0, 0))
    with pytest.raises(MessageFormatError):
        m.decode_answer("CONNECT_BASE", 0x02, "modèle".encode().ljust(12, b"\0") + bytes(16))


def test_base_conf_answer_is_264_bytes_with_zero_padded_slots() -> None:
    sensor = m.Position.from_si(x_mm=100, angle_deg=90)
    conf = m.GetBaseConfAnswer.from_si(base_type=0, base_radius_mm=170.5, sensors=[sensor])
    assert conf.sensor_num == 1 and conf.bumper_num == 0 and len(conf.sensors) == 8
    assert conf.base_radius_mm == 170.5
    payload = m.encode_answer(conf)[1]
    assert len(payload) == 264
    assert payload[:7] == h("00 80 AA 00 00 00 01")
    assert payload[7:23] == h("00 64 00 00 00 00 00 00 00 00 00 00 00 5A 00 00")
    assert payload[23:135] == bytes(112) and payload[135] == 0 and payload[136:] == bytes(128)
    assert m.decode_answer("GET_BASE_CONF", 0x02, payload) == conf
    with pytest.raises(MessageFormatError):
        m.decode_answer("GET_BASE_CONF", 0x02, payload[:-1])
    with pytest.raises(MessageFormatError):
        m.GetBaseConfAnswer(0, 0, 0, 9, (), 0, ())  # at most 8 sensors
    with pytest.raises(MessageFormatError):
        m.GetBaseConfAnswer(0, 0, 0, 0, (sensor,) * 9, 0, ())


def test_fixed_size_answers_refuse_other_lengths() -> None:
    cases: list[tuple[str, int]] = [
        ("GET_BASE_STATUS", 2),
        ("GET_BASE_MOTOR_DATA", 9),
        ("GET_BASE_SENSOR_DATA", 64),
        ("HEALTH_GET_HEALTH", 2),
        ("HEALTH_GET_ERROR", 36),
    ]
    for to, size in cases:
        good = bytes(size - 1) + b"\0"
        m.decode_answer(to, 0x02, good)
        for wrong in (size - 1, size + 1):
            with pytest.raises(MessageFormatError):
                m.decode_answer(to, 0x02, bytes(wrong))
    for to in ("SET_BASE_MOTOR", "POLL_BASE_ANS_CMD", "SEND_EVENT", "HEALTH_CLR_ERROR", "BASE_CMD"):
        assert m.decode_answer(to, 0x02, b"") == m.EmptyAnswer()
        with pytest.raises(MessageFormatError):
            m.decode_answer(to, 0x02, b"\x00")


def test_status_and_motor_answers() -> None:
    assert m.decode_answer("GET_BASE_STATUS", 0x02, h("50 03")) == m.GetBaseStatusAnswer(80, 3)
    with pytest.raises(MessageFormatError):
        m.GetBaseStatusAnswer(300, 0)
    # Above 100 % is kept as sent (the checker flags it); above 255 cannot be encoded.
    assert m.decode_answer("GET_BASE_STATUS", 0x02, h("65 00")) == m.GetBaseStatusAnswer(101, 0)
    motor = m.GetBaseMotorDataAnswer(-5, 1234567, 0x02)
    assert m.encode_answer(motor)[1] == h("FB FF FF FF 87 D6 12 00 02")
    assert m.decode_answer("GET_BASE_MOTOR_DATA", 0x02, h("FB FF FF FF 87 D6 12 00 02")) == motor


def test_sensor_answer_and_its_float_view() -> None:
    sensors = m.GetBaseSensorDataAnswer.from_si([100.0, 0.5])
    assert sensors.distances_mm_q16 == (6553600, 32768) + (0,) * 14
    assert sensors.distances_mm[:3] == (100.0, 0.5, 0.0)
    assert m.encode_answer(sensors)[1][:8] == h("00 00 64 00 00 80 00 00")
    with pytest.raises(MessageFormatError):
        m.GetBaseSensorDataAnswer((0,) * 15)
    with pytest.raises(MessageFormatError):
        m.GetBaseSensorDataAnswer.from_si([-1.0])


def test_bumper_answer_accepts_one_to_four_bytes() -> None:
    assert m.decode_answer("GET_BASE_BUMPER_DATA", 0x02, h("FF FF FF FF")) == m.GetBaseBumperDataAnswer(
        0xFFFF_FFFF
    )
    short = m.decode_answer("GET_BASE_BUMPER_DATA", 0x02, h("FC"))
    assert short == m.GetBaseBumperDataAnswer(0xFC, 1)  # zero-padded to 32 bits
    assert m.encode_answer(short)[1] == h("FC")
    assert m.decode_answer("GET_BASE_BUMPER_DATA", 0x02, h("01 02 03")) == m.GetBaseBumperDataAnswer(
        0x030201, 3
    )
    for wrong in (b"", bytes(5)):
        with pytest.raises(MessageFormatError):
            m.decode_answer("GET_BASE_BUMPER_DATA", 0x02, wrong)
    with pytest.raises(MessageFormatError):
        m.GetBaseBumperDataAnswer(0x100, 1)


def test_charger_answer_carries_probe_count_probes() -> None:
    answer = m.GetChargerDataAnswer(3, 3, (0b001, 0b010, 0b100))
    assert m.encode_answer(answer)[1] == h("03 03 01 02 04")
    assert m.decode_answer("GET_CHARGER_DATA", 0x02, h("03 03 01 02 04")) == answer
    for wrong in ("", "03", "03 03 01 02", "03 02 01 02 04"):
        with pytest.raises(MessageFormatError):
            m.decode_answer("GET_CHARGER_DATA", 0x02, h(wrong))
    with pytest.raises(MessageFormatError):
        m.GetChargerDataAnswer(3, 2, (1, 2, 3))


def test_deadreckon_answer_in_both_sizes() -> None:
    short = m.SetVAndGetDeadreckonAnswer.from_si(dx_mm=10.0, dy_mm=0.0, dtheta_deg=-1.5, status=0x02)
    payload = m.encode_answer(short)[1]
    assert payload == h("00 00 0A 00 00 00 00 00 00 80 FE FF 02")
    assert m.decode_answer("SET_V_AND_GET_DEADRECKON", 0x02, payload) == short
    assert (short.dx_mm, short.dy_mm, short.dtheta_deg) == (10.0, 0.0, -1.5)
    full = m.SetVAndGetDeadreckonAnswer(1, 2, 3, 0, timestamp_ms=0x01020304)
    payload = m.encode_answer(full)[1]
    assert len(payload) == 17 and payload[13:] == h("04 03 02 01")
    assert m.decode_answer("SET_V_AND_GET_DEADRECKON", 0x02, payload) == full
    for size in (0, 2, 12, 14, 16, 18):
        with pytest.raises(MessageFormatError):
            m.decode_answer("SET_V_AND_GET_DEADRECKON", 0x02, bytes(size))


def test_poll_answer_forms() -> None:
    assert m.decode_answer("POLL_BASE_CMD", 0x02, b"") == m.PollBaseCmdAnswer(None, 0, 0)
    assert m.decode_answer("POLL_BASE_CMD", 0x02, h("FF 5A")) == m.PollBaseCmdAnswer(None, 2, 0x5A)
    pending = m.decode_answer("POLL_BASE_CMD", 0x02, h("A4 00"))
    assert pending == m.PollBaseCmdAnswer.pending(m.ExternalCommand.GO_HOME)
    for answer, wire in (
        (m.PollBaseCmdAnswer(), ""),
        (m.PollBaseCmdAnswer(None, 2, 0x5A), "FF 5A"),
        (m.PollBaseCmdAnswer(0x80, 2, 0x01), "80 01"),
    ):
        assert m.encode_answer(answer)[1] == h(wire)
    with pytest.raises(MessageFormatError):
        m.decode_answer("POLL_BASE_CMD", 0x02, h("A4"))
    with pytest.raises(MessageFormatError):
        m.PollBaseCmdAnswer(0xA4, 0, 0)  # a command needs the 2-byte form
    with pytest.raises(MessageFormatError):
        m.PollBaseCmdAnswer(0xFF, 2, 0)  # 0xFF means "nothing pending": use None
    with pytest.raises(MessageFormatError):
        m.PollBaseCmdAnswer(None, 1, 0)


def test_health_answers() -> None:
    answer = m.HealthGetErrorAnswer(0x01020100, "low battery")
    payload = m.encode_answer(answer)[1]
    assert len(payload) == 36 and payload[:4] == h("00 01 02 01") and payload[4:16] == b"low battery\0"
    assert m.decode_answer("HEALTH_GET_ERROR", 0x02, payload) == answer
    after_nul = payload[:16] + b"garbage after the NUL"[:20]
    assert m.decode_answer("HEALTH_GET_ERROR", 0x02, after_nul) == answer
    with pytest.raises(MessageFormatError, match="NUL"):
        m.decode_answer("HEALTH_GET_ERROR", 0x02, payload[:4] + b"x" * 32)
    with pytest.raises(MessageFormatError):
        m.HealthGetErrorAnswer(1, "x" * 32)  # 31 characters and the NUL fill the 32 bytes
    assert m.decode_answer("HEALTH_GET_HEALTH", 0x02, h("03 02")) == m.HealthGetHealthAnswer(3, 2)


def test_answers_that_do_not_depend_on_the_request() -> None:
    for to in ("GET_BASE_STATUS", "SYNC", "HEALTH_GET_ERROR"):
        assert m.decode_answer(to, 0x03, h("01 80")) == m.ErrorAnswer(0x8001)
        assert m.decode_answer(to, 0xFF, b"") == m.InvalidAnswer()
    assert m.decode_answer("SYNC", 0x00, h("00 00")) == m.SyncAnswer(h("00 00"))
    assert m.decode_answer(m.Echo(h("AA")), 0x01, h("AA")) == m.EchoAnswer(h("AA"))
    for cmd, payload in ((0x03, "01"), (0x03, "01 80 00"), (0xFF, "00")):
        with pytest.raises(MessageFormatError):
            m.decode_answer("GET_BASE_STATUS", cmd, h(payload))
    with pytest.raises(UnsupportedMessageError):
        m.decode_answer("GET_BASE_STATUS", 0x04, b"")
    with pytest.raises(UnsupportedMessageError):
        m.decode_answer("GET_AUXILIARY_ANCHOR", 0x02, b"")  # no OK layout is defined
    with pytest.raises(UnsupportedMessageError):
        m.decode_answer("SYNC", 0x02, b"")
    with pytest.raises(UnsupportedMessageError):
        m.decode_answer("NOT_A_REQUEST", 0x03, h("01 80"))
    with pytest.raises(MessageFormatError):
        m.ErrorAnswer(0x10000)


# --- construction checks -----------------------------------------------------------------------


@pytest.mark.parametrize(
    ("build", "values"),
    [
        (m.ConnectBase, {"protocol_version": 256}),
        (m.SendEvent, {"event": -1}),
        (m.SendEvent, {"event": True}),
        (m.HealthClrError, {"error_code": 1 << 32}),
        (m.SetVAndGetDeadreckon, {"vx_mps_q16": 1 << 31, "vy_mps_q16": 0, "omega_radps_q16": 0}),
        (m.SetBaseMotor, {"speeds_mm_s": (1, 2, 3)}),
        (m.SetBaseMotor, {"speeds_mm_s": (1, 2, 3, 1 << 31)}),
        (m.Echo, {"data": "AA"}),
        (m.GetBaseMotorDataAnswer, {"left_distance_mm": 0, "right_distance_mm": 0, "status": 256}),
        (
            m.SetVAndGetDeadreckonAnswer,
            {"dx_mm_q16": 0, "dy_mm_q16": 0, "dtheta_deg_q16": 0, "timestamp_ms": -1},
        ),
        (m.HealthGetErrorAnswer, {"error_code": 0, "message": "nul\0inside"}),
    ],
)
def test_out_of_range_values_are_format_errors(build: Any, values: dict[str, Any]) -> None:
    with pytest.raises(MessageFormatError):
        build(**values)


def test_bytes_like_fields_are_stored_as_bytes() -> None:
    assert m.Echo(bytearray(b"ab")).data == b"ab"  # type: ignore[arg-type]
    echo = m.decode_request(0x01, bytearray(b"xy"))  # type: ignore[arg-type]
    assert isinstance(echo, m.Echo) and echo == m.Echo(b"xy") and type(echo.data) is bytes
    status = m.decode_answer("GET_BASE_STATUS", 0x02, memoryview(b"\x50\x03"))  # type: ignore[arg-type]
    assert status == m.GetBaseStatusAnswer(80, 3)


# --- JSON form ---------------------------------------------------------------------------------


def test_fields_use_the_contract_json_form() -> None:
    assert m.fields(m.Echo(h("AA 55"))) == {"data": "AA 55"}
    assert m.fields(m.SetVAndGetDeadreckon(13107, 0, 32768)) == {
        "vx_mps_q16": 13107,
        "vy_mps_q16": 0,
        "omega_radps_q16": 32768,
    }
    connect = m.ConnectBaseAnswer("ref base", 0x0114, 1, (1, 2, 3))
    assert m.fields(connect) == {
        "model": "ref base",
        "firmware_version": 0x0114,
        "hardware_version": 1,
        "serial": [1, 2, 3],
        "firmware_version_suffix": None,
    }
    conf = m.fields(m.GetBaseConfAnswer.from_si(base_type=1, base_radius_mm=1.0))
    assert conf["sensors"][0] == {"x_mm_q8": 0, "y_mm_q8": 0, "z_mm_q8": 0, "angle_deg_q8": 0}
    assert len(conf["bumpers"]) == 8
    assert m.fields(m.PollBaseCmdAnswer()) == {"command": None, "payload_size": 0, "pad": 0}


def test_from_fields_builds_requests_and_answers() -> None:
    assert m.from_fields("ECHO", {"data": "aa55"}) == m.Echo(h("AA 55"))
    assert m.from_fields("SYNC", {"filler": "00 00"}, to="SYNC") == m.SyncAnswer(h("00 00"))
    assert m.from_fields("GET_BASE_STATUS", {}) == m.GetBaseStatus()
    assert m.from_fields("OK", {"battery_percent": 80, "power_status": 3}, to="GET_BASE_STATUS") == (
        m.GetBaseStatusAnswer(80, 3)
    )
    assert m.from_fields("ERROR", {"error_code": 0x8000}, to="GET_AUXILIARY_ANCHOR") == m.ErrorAnswer(0x8000)
    conf = m.GetBaseConfAnswer.from_si(base_type=0, base_radius_mm=170.0, bumpers=[m.Position(1, 2, 3, 4)])
    assert m.from_fields("OK", m.fields(conf), to="GET_BASE_CONF") == conf


@pytest.mark.parametrize(
    ("name", "values", "to"),
    [
        ("ECHO", {"data": "not hex"}, None),
        ("ECHO", {"data": 5}, None),
        ("ECHO", {"payload": "AA"}, None),
        ("SET_V_AND_GET_DEADRECKON", {"vx_mps_q16": 1}, None),
        ("SET_BASE_MOTOR", {"speeds_mm_s": 5}, None),
        ("OK", {"base_type": 0, "sensors": [5]}, "GET_BASE_CONF"),
        ("OK", {"battery_percent": "80", "power_status": 3}, "GET_BASE_STATUS"),
    ],
)
def test_from_fields_rejects_bad_json(name: str, values: dict[str, Any], to: str | None) -> None:
    with pytest.raises(MessageFormatError):
        m.from_fields(name, values, to=to)


def test_encode_and_decode_take_either_kind() -> None:
    request = m.SetVAndGetDeadreckon.from_si(0.2, 0.0, 0.5)
    cmd, payload = m.encode(request)
    assert (cmd, payload) == m.encode_request(request)
    assert m.decode(cmd, payload) == request
    answer = m.SetVAndGetDeadreckonAnswer(1, 2, 3)
    cmd, payload = m.encode(answer)
    assert (cmd, payload) == m.encode_answer(answer)
    assert m.decode(cmd, payload, answer_to=request) == answer
    assert m.decode(cmd, payload, answer_to="SET_V_AND_GET_DEADRECKON") == answer
    # An OK payload alone is not a request; an unknown kind is refused.
    with pytest.raises(UnsupportedMessageError):
        m.decode(cmd, payload)
    with pytest.raises(UnsupportedMessageError):
        m.encode(m.Message())
