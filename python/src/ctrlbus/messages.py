# SPDX-License-Identifier: MIT
"""Typed Control Bus messages: every request and answer of the contract, and their codec.

Each message is a frozen dataclass whose fields carry the contract's names (``vectors/README.md``),
as the raw integers of the wire; fixed-point fields (``_q8`` / ``_q16``) also have float
properties without the suffix and ``from_si`` constructors. Messages check their values when they
are built, so an out-of-range value raises MessageFormatError before anything is encoded.

- `encode(msg) -> (cmd, payload)` / `decode(cmd, payload, answer_to=None)`: either kind, by the
  message's type or by whether `answer_to` names the request being answered; the same as
- `encode_request(msg) -> (cmd, payload)` / `decode_request(cmd, payload)`
- `encode_answer(msg) -> (cmd, payload)` / `decode_answer(request, cmd, payload)`: an OK payload
  can only be read knowing the request it answers.
- `request_frame(msg)` / `answer_frame(msg)`: the whole frame.
- `fields(msg)` / `from_fields(name, values, to=...)`: the contract's JSON form (bytes as hex).

Errors: a payload of the wrong length or with values out of range raises MessageFormatError
(a base answers ERROR 0x8001); an unknown command or request code raises UnsupportedMessageError
(0x8000); an unknown HEALTH_MGMT sub-command raises UnsupportedSubcommandError (0x8002). Each
exception's `error_code` is that answer code.

An argument value the protocol does not support (a CONNECT_BASE protocol version other than 1, a
charger data type other than 0, a BASE_CMD sub-command other than ENTER_DFU / REBOOT) has the right
layout but is refused as unsupported (docs/protocol.md [connect-version], §8.3), on decoding and on
construction alike. To send such a request on purpose (a conformance test), build the frame with
ctrlbus.frame.encode.
"""

from __future__ import annotations

import enum
import math
import struct
import typing
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from dataclasses import fields as dataclass_fields
from typing import TYPE_CHECKING, Any, ClassVar

from ctrlbus import protocol_tables
from ctrlbus.errors import MessageFormatError, UnsupportedMessageError, UnsupportedSubcommandError
from ctrlbus.frame import encode as encode_frame
from ctrlbus.protocol_tables import (
    ConnectBaseAnswerFields,
    GetBaseBumperDataAnswerFields,
    GetBaseConfAdvAnswerFields,
    GetBaseConfAnswerFields,
    GetBaseMotorDataAnswerFields,
    GetBaseSensorDataAnswerFields,
    GetBaseStatusAnswerFields,
    GetChargerDataAnswerFields,
    HealthGetErrorAnswerFields,
    HealthGetHealthAnswerFields,
    PositionFields,
    SetVAndGetDeadreckonAnswerFields,
)

if TYPE_CHECKING:
    from typing_extensions import Self  # typing.Self from Python 3.11; annotations only

__all__ = [
    "CHARGER_BEACON_DATA",
    "HEALTH_MESSAGE_SIZE",
    "OK_ANSWER_CLASSES",
    "POLL_NOTHING_PENDING",
    "PROTOCOL_VERSION",
    "REQUEST_CLASSES",
    "RESPONSE_ANSWER_CLASSES",
    "S32",
    "SENSOR_CHANNELS",
    "U8",
    "U16",
    "U32",
    "AnswerMessage",
    "BaseCommand",
    "BaseSubcommand",
    "Cmd",
    "ConnectBase",
    "ConnectBaseAnswer",
    "Echo",
    "EchoAnswer",
    "EmptyAnswer",
    "ErrorAnswer",
    "ErrorCode",
    "Event",
    "ExternalCommand",
    "GetAuxiliaryAnchor",
    "GetBaseBumperData",
    "GetBaseBumperDataAnswer",
    "GetBaseConf",
    "GetBaseConfAdv",
    "GetBaseConfAdvAnswer",
    "GetBaseConfAnswer",
    "GetBaseMotorData",
    "GetBaseMotorDataAnswer",
    "GetBaseSensorData",
    "GetBaseSensorDataAnswer",
    "GetBaseStatus",
    "GetBaseStatusAnswer",
    "GetChargerData",
    "GetChargerDataAnswer",
    "HealthClrError",
    "HealthGetError",
    "HealthGetErrorAnswer",
    "HealthGetHealth",
    "HealthGetHealthAnswer",
    "HealthSub",
    "InvalidAnswer",
    "Message",
    "OkAnswer",
    "PollBaseAnsCmd",
    "PollBaseCmd",
    "PollBaseCmdAnswer",
    "Position",
    "Request",
    "RequestMessage",
    "Response",
    "SendEvent",
    "SetBaseMotor",
    "SetVAndGetDeadreckon",
    "SetVAndGetDeadreckonAnswer",
    "Sync",
    "SyncAnswer",
    "answer_class",
    "answer_frame",
    "decode",
    "decode_answer",
    "decode_request",
    "encode",
    "encode_answer",
    "encode_request",
    "fields",
    "from_fields",
    "from_q8",
    "from_q16",
    "hex_text",
    "parse_hex",
    "request_class",
    "request_frame",
    "to_q8",
    "to_q16",
]

# --- codes -------------------------------------------------------------------------------------


class Cmd(enum.IntEnum):
    """CMD byte of a request."""

    SYNC = 0x00
    ECHO = 0x01
    CTRL_BUS = 0xF8
    BASE_CMD = 0xF9


class Response(enum.IntEnum):
    """CMD byte of an answer."""

    SYNC = 0x00
    ECHO = 0x01
    OK = 0x02
    ERROR = 0x03
    INVALID = 0xFF


class Request(enum.IntEnum):
    """Control-bus request code: the first payload byte of a CTRL_BUS frame."""

    CONNECT_BASE = 0x10
    GET_BASE_CONF = 0x20
    GET_BASE_CONF_ADV = 0x21
    GET_BASE_STATUS = 0x30
    GET_BASE_MOTOR_DATA = 0x31
    GET_BASE_SENSOR_DATA = 0x32
    GET_BASE_BUMPER_DATA = 0x33
    GET_CHARGER_DATA = 0x34
    GET_AUXILIARY_ANCHOR = 0x35
    SET_BASE_MOTOR = 0x40
    SET_V_AND_GET_DEADRECKON = 0x41
    POLL_BASE_CMD = 0x50
    POLL_BASE_ANS_CMD = 0x5F
    SEND_EVENT = 0x60
    HEALTH_MGMT = 0x90


class HealthSub(enum.IntEnum):
    """HEALTH_MGMT sub-command: the second payload byte."""

    GET_HEALTH = 0x01
    GET_ERROR = 0x02
    CLR_ERROR = 0x03


class ErrorCode(enum.IntEnum):
    """`error_code` of an ERROR answer."""

    NOT_SYNCED = 0x0010  # a byte where a frame should start was neither 0x10 nor 0x50
    TOO_LONG = 0x0020  # request longer than the receive buffer
    CHECKSUM = 0x0040
    REFERENCE_CHECKSUM = 0x00C0  # what the reference firmware sends for a checksum mismatch
    UNSUPPORTED = 0x8000
    FORMAT = 0x8001
    OPERATION = 0x8002


class ExternalCommand(enum.IntEnum):
    """Commands a base offers the Core through POLL_BASE_CMD."""

    GET_INFO = 0x51
    RESET_WIFI = 0x52
    FW_UPGRADING = 0x53
    START_SWEEP = 0x80
    STOP_SWEEP = 0x81
    SPOT_SWEEP = 0x82
    GET_HEALTH = 0x90
    MOVE_FORWARD = 0xA0
    MOVE_BACKWARD = 0xA1
    TURN_LEFT = 0xA2
    TURN_RIGHT = 0xA3
    GO_HOME = 0xA4
    CANCEL_ACTION = 0xAF
    GET_AUXILIARY_ANCHOR = 0xB0


class Event(enum.IntEnum):
    """SEND_EVENT codes (any other value is answered OK as well)."""

    LIDAR_CONN_FAIL = 0x61
    LIDAR_RAMPUP_FAIL = 0x62
    SYSTEM_UP_OK = 0x63
    FIRMWARE_UPDATE = 0x64
    CORE_DISCONNECT = 0x65
    FIRMWARE_UPDATE_OK = 0x66
    START_SWEEP = 0x80
    END_SWEEP = 0x81
    START_VACUUM = 0x82
    END_VACUUM = 0x83


class BaseSubcommand(enum.IntEnum):
    """BASE_CMD sub-command."""

    ENTER_DFU = 0x01
    REBOOT = 0x02


POLL_NOTHING_PENDING = 0xFF  # first byte of the 2-byte "nothing pending" POLL_BASE_CMD answer

# --- fixed point and value checks --------------------------------------------------------------

U8 = (0, 0xFF)
U16 = (0, 0xFFFF)
U32 = (0, 0xFFFF_FFFF)
S32 = (-(1 << 31), (1 << 31) - 1)


def _to_fixed(value: float, frac_bits: int, signed: bool) -> int:
    low, high = S32 if signed else U32
    if not isinstance(value, int | float) or isinstance(value, bool) or not math.isfinite(value):
        raise MessageFormatError(f"not a finite number: {value!r}")
    raw = round(value * (1 << frac_bits))
    if not low <= raw <= high:
        kind = "s32" if signed else "u32"
        raise MessageFormatError(f"{value} does not fit a Q{frac_bits} {kind} ({low}..{high} on the wire)")
    return raw


def to_q8(value: float, *, signed: bool = True) -> int:
    """Wire integer of `value` in Q8 (value x 256, rounded); checked against s32 or u32."""
    return _to_fixed(value, 8, signed)


def from_q8(raw: int) -> float:
    """Value of a Q8 wire integer."""
    return raw / 256


def to_q16(value: float, *, signed: bool = True) -> int:
    """Wire integer of `value` in Q16 (value x 65536, rounded); checked against s32 or u32."""
    return _to_fixed(value, 16, signed)


def from_q16(raw: int) -> float:
    """Value of a Q16 wire integer."""
    return raw / 65536


def _check_int(owner: str, name: str, value: object, limits: tuple[int, int]) -> None:
    low, high = limits
    if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
        raise MessageFormatError(f"{owner}.{name} must be an integer in {low}..{high}, got {value!r}")


def _check_text(owner: str, name: str, value: object, size: int) -> None:
    if not isinstance(value, str):
        raise MessageFormatError(f"{owner}.{name} must be text, got {value!r}")
    if not value.isascii() or "\0" in value or len(value) > size:
        raise MessageFormatError(
            f"{owner}.{name} must be at most {size} ASCII characters without NUL, got {value!r}"
        )


def _pack_text(value: str, size: int) -> bytes:
    return value.encode("ascii").ljust(size, b"\0")


def _unpack_text(owner: str, name: str, raw: bytes, *, nul_required: bool = False) -> str:
    text, nul, _ = raw.partition(b"\0")
    if nul_required and not nul:
        raise MessageFormatError(f"{owner}.{name} is not NUL-terminated within {len(raw)} bytes")
    try:
        return text.decode("ascii")
    except UnicodeDecodeError:
        raise MessageFormatError(f"{owner}.{name} is not ASCII text: {text.hex(' ')}") from None


def _check_length(owner: str, data: bytes, *sizes: int, what: str = "payload") -> None:
    if len(data) not in sizes:
        expected = " or ".join(str(size) for size in sizes)
        raise MessageFormatError(f"{owner}: {len(data)} {what} bytes, expected {expected}")


# --- message base classes ----------------------------------------------------------------------


@dataclass(frozen=True)
class Message:
    """Base of every message. NAME is the contract name."""

    NAME: ClassVar[str]
    # Fields whose layout is fixed: packed and unpacked in field order with this struct.
    _LAYOUT: ClassVar[struct.Struct | None] = None
    # Or a layout whose last field, _TAIL, is optional (None: not sent): the form without it and
    # the form with it (docs/protocol.md [profiles]).
    _FORMS: ClassVar[tuple[struct.Struct, struct.Struct] | None] = None
    _TAIL: ClassVar[str | None] = None
    # Integer fields and their allowed ranges, checked on construction.
    _RANGES: ClassVar[Mapping[str, tuple[int, int]]] = {}
    # Fields holding bytes; bytearray/memoryview given for them are stored as bytes.
    _BYTES: ClassVar[tuple[str, ...]] = ()
    # Fields holding sequences: (item range, count); lists are stored as tuples.
    _ARRAYS: ClassVar[Mapping[str, tuple[tuple[int, int], int]]] = {}
    # What _unpack reads: the arguments after a request's code, or an answer's whole payload.
    _PART: ClassVar[str] = "payload"

    def __post_init__(self) -> None:
        owner = type(self).__name__
        for name in self._BYTES:
            value = getattr(self, name)
            if not isinstance(value, bytes | bytearray | memoryview):
                raise MessageFormatError(f"{owner}.{name} must be bytes, got {value!r}")
            object.__setattr__(self, name, bytes(value))
        for name, (limits, count) in self._ARRAYS.items():
            value = getattr(self, name)
            if isinstance(value, str | bytes) or not isinstance(value, Sequence) or len(value) != count:
                raise MessageFormatError(
                    f"{owner}.{name} must be a sequence of {count} integers, got {value!r}"
                )
            for item in value:
                _check_int(owner, name, item, limits)
            object.__setattr__(self, name, tuple(value))
        tail = self._TAIL
        for name, limits in self._RANGES.items():
            value = getattr(self, name)
            if tail is None or value is not None or name != tail:  # a tail not sent is None
                _check_int(owner, name, value, limits)
        self._check()

    def _check(self) -> None:
        """Checks beyond _RANGES / _ARRAYS / _BYTES (subclasses override)."""

    def _pack(self) -> bytes:
        """The message's own bytes (after the request code / sub-command for control-bus requests)."""
        layout = self._LAYOUT or (self._FORMS[1] if self._FORMS else None)
        if layout is None:  # no fields, or one bytes field: the whole payload
            return bytes(getattr(self, self._BYTES[0])) if self._BYTES else b""
        values: list[Any] = []
        for item in dataclass_fields(self):
            value = getattr(self, item.name)
            if value is None and item.name == self._TAIL:
                layout = self._FORMS[0] if self._FORMS else layout
                continue
            values.extend(value if isinstance(value, tuple) else (value,))
        return layout.pack(*values)

    @classmethod
    def _label(cls) -> str:
        """How errors name the message: the contract name, or the class for the OK answers."""
        return cls.__name__ if cls.NAME == "OK" else cls.NAME

    @classmethod
    def _unpack(cls, data: bytes) -> Self:
        """Inverse of _pack; raises MessageFormatError on a wrong length or value."""
        layout = cls._LAYOUT
        if layout is None and cls._FORMS is not None:
            short, long = cls._FORMS
            _check_length(cls._label(), data, short.size, long.size, what=cls._PART)
            layout = long if len(data) == long.size else short
        elif layout is None and cls._BYTES:
            return cls(**{cls._BYTES[0]: data})
        elif layout is None:
            _check_length(cls._label(), data, 0, what=cls._PART)
            return cls()
        else:
            _check_length(cls._label(), data, layout.size, what=cls._PART)
        if not cls._ARRAYS:  # one value a field, in order; a tail not sent keeps its None
            return cls(*layout.unpack(data))
        values = list(layout.unpack(data))
        arguments: list[Any] = []
        for item in dataclass_fields(cls):
            if item.name in cls._ARRAYS:
                count = cls._ARRAYS[item.name][1]
                arguments.append(tuple(values[:count]))
                del values[:count]
            elif values:
                arguments.append(values.pop(0))
        return cls(*arguments)


@dataclass(frozen=True)
class RequestMessage(Message):
    """A request (master to base). CODE / SUB: control-bus request code and HEALTH sub-command."""

    CMD: ClassVar[int] = Cmd.CTRL_BUS
    CODE: ClassVar[int | None] = None
    SUB: ClassVar[int | None] = None
    _PART: ClassVar[str] = "argument"


@dataclass(frozen=True)
class AnswerMessage(Message):
    """An answer (base to master). RESPONSE is its CMD byte."""

    RESPONSE: ClassVar[int]


@dataclass(frozen=True)
class OkAnswer(AnswerMessage):
    """An OK answer; its payload layout depends on the request it answers."""

    NAME: ClassVar[str] = "OK"
    RESPONSE: ClassVar[int] = Response.OK


# --- requests ----------------------------------------------------------------------------------


@dataclass(frozen=True)
class Sync(RequestMessage):
    """SYNC with any amount of filler; the answer copies the request verbatim."""

    NAME: ClassVar[str] = "SYNC"
    CMD: ClassVar[int] = Cmd.SYNC
    _BYTES: ClassVar[tuple[str, ...]] = ("filler",)

    filler: bytes = b""


@dataclass(frozen=True)
class Echo(RequestMessage):
    """ECHO with any data; the answer copies the request verbatim."""

    NAME: ClassVar[str] = "ECHO"
    CMD: ClassVar[int] = Cmd.ECHO
    _BYTES: ClassVar[tuple[str, ...]] = ("data",)

    data: bytes = b""


@dataclass(frozen=True)
class BaseCommand(RequestMessage):
    """BASE_CMD (0xF9): `subcommand` is a BaseSubcommand value."""

    NAME: ClassVar[str] = "BASE_CMD"
    CMD: ClassVar[int] = Cmd.BASE_CMD
    _LAYOUT: ClassVar[struct.Struct | None] = struct.Struct("<B")
    _RANGES: ClassVar[Mapping[str, tuple[int, int]]] = {"subcommand": U8}

    subcommand: int

    def _check(self) -> None:
        if self.subcommand not in tuple(BaseSubcommand):
            raise UnsupportedMessageError(f"unknown BASE_CMD sub-command 0x{self.subcommand:02X}")


PROTOCOL_VERSION = 1  # the only CONNECT_BASE protocol version
CHARGER_BEACON_DATA = 0x00  # the only GET_CHARGER_DATA data type


@dataclass(frozen=True)
class ConnectBase(RequestMessage):
    NAME: ClassVar[str] = "CONNECT_BASE"
    CODE: ClassVar[int | None] = Request.CONNECT_BASE
    _LAYOUT: ClassVar[struct.Struct | None] = struct.Struct("<B")
    _RANGES: ClassVar[Mapping[str, tuple[int, int]]] = {"protocol_version": U8}

    protocol_version: int = PROTOCOL_VERSION

    def _check(self) -> None:
        if self.protocol_version != PROTOCOL_VERSION:
            raise UnsupportedMessageError(
                f"unsupported CONNECT_BASE protocol version {self.protocol_version}"
            )


@dataclass(frozen=True)
class GetBaseConf(RequestMessage):
    NAME: ClassVar[str] = "GET_BASE_CONF"
    CODE: ClassVar[int | None] = Request.GET_BASE_CONF


@dataclass(frozen=True)
class GetBaseConfAdv(RequestMessage):
    NAME: ClassVar[str] = "GET_BASE_CONF_ADV"
    CODE: ClassVar[int | None] = Request.GET_BASE_CONF_ADV


@dataclass(frozen=True)
class GetBaseStatus(RequestMessage):
    NAME: ClassVar[str] = "GET_BASE_STATUS"
    CODE: ClassVar[int | None] = Request.GET_BASE_STATUS


@dataclass(frozen=True)
class GetBaseMotorData(RequestMessage):
    NAME: ClassVar[str] = "GET_BASE_MOTOR_DATA"
    CODE: ClassVar[int | None] = Request.GET_BASE_MOTOR_DATA


@dataclass(frozen=True)
class GetBaseSensorData(RequestMessage):
    NAME: ClassVar[str] = "GET_BASE_SENSOR_DATA"
    CODE: ClassVar[int | None] = Request.GET_BASE_SENSOR_DATA


@dataclass(frozen=True)
class GetBaseBumperData(RequestMessage):
    NAME: ClassVar[str] = "GET_BASE_BUMPER_DATA"
    CODE: ClassVar[int | None] = Request.GET_BASE_BUMPER_DATA


@dataclass(frozen=True)
class GetChargerData(RequestMessage):
    NAME: ClassVar[str] = "GET_CHARGER_DATA"
    CODE: ClassVar[int | None] = Request.GET_CHARGER_DATA
    _LAYOUT: ClassVar[struct.Struct | None] = struct.Struct("<B")
    _RANGES: ClassVar[Mapping[str, tuple[int, int]]] = {"data_type": U8}

    data_type: int = CHARGER_BEACON_DATA

    def _check(self) -> None:
        if self.data_type != CHARGER_BEACON_DATA:
            raise UnsupportedMessageError(f"unsupported GET_CHARGER_DATA data type 0x{self.data_type:02X}")


@dataclass(frozen=True)
class GetAuxiliaryAnchor(RequestMessage):
    """Listed by the vendor without a layout: a base answers ERROR 0x8000."""

    NAME: ClassVar[str] = "GET_AUXILIARY_ANCHOR"
    CODE: ClassVar[int | None] = Request.GET_AUXILIARY_ANCHOR


@dataclass(frozen=True)
class SetBaseMotor(RequestMessage):
    """Wheel speeds in mm/s: left, right, then two ignored values."""

    NAME: ClassVar[str] = "SET_BASE_MOTOR"
    CODE: ClassVar[int | None] = Request.SET_BASE_MOTOR
    _LAYOUT: ClassVar[struct.Struct | None] = struct.Struct("<4i")
    _ARRAYS: ClassVar[Mapping[str, tuple[tuple[int, int], int]]] = {"speeds_mm_s": (S32, 4)}

    speeds_mm_s: tuple[int, int, int, int]

    @classmethod
    def from_wheels(cls, left_mm_s: int, right_mm_s: int) -> Self:
        return cls((left_mm_s, right_mm_s, 0, 0))

    @property
    def left_mm_s(self) -> int:
        return self.speeds_mm_s[0]

    @property
    def right_mm_s(self) -> int:
        return self.speeds_mm_s[1]


@dataclass(frozen=True)
class SetVAndGetDeadreckon(RequestMessage):
    """Body velocity in Q16: vx, vy (m/s), omega (rad/s, anticlockwise positive)."""

    NAME: ClassVar[str] = "SET_V_AND_GET_DEADRECKON"
    CODE: ClassVar[int | None] = Request.SET_V_AND_GET_DEADRECKON
    _LAYOUT: ClassVar[struct.Struct | None] = struct.Struct("<3i")
    _RANGES: ClassVar[Mapping[str, tuple[int, int]]] = {
        "vx_mps_q16": S32,
        "vy_mps_q16": S32,
        "omega_radps_q16": S32,
    }

    vx_mps_q16: int
    vy_mps_q16: int
    omega_radps_q16: int

    @classmethod
    def from_si(cls, vx_mps: float = 0.0, vy_mps: float = 0.0, omega_radps: float = 0.0) -> Self:
        return cls(to_q16(vx_mps), to_q16(vy_mps), to_q16(omega_radps))

    @property
    def vx_mps(self) -> float:
        return from_q16(self.vx_mps_q16)

    @property
    def vy_mps(self) -> float:
        return from_q16(self.vy_mps_q16)

    @property
    def omega_radps(self) -> float:
        return from_q16(self.omega_radps_q16)


@dataclass(frozen=True)
class PollBaseCmd(RequestMessage):
    NAME: ClassVar[str] = "POLL_BASE_CMD"
    CODE: ClassVar[int | None] = Request.POLL_BASE_CMD


@dataclass(frozen=True)
class PollBaseAnsCmd(RequestMessage):
    NAME: ClassVar[str] = "POLL_BASE_ANS_CMD"
    CODE: ClassVar[int | None] = Request.POLL_BASE_ANS_CMD


@dataclass(frozen=True)
class SendEvent(RequestMessage):
    """`event` is an Event value (other values are legal and answered OK)."""

    NAME: ClassVar[str] = "SEND_EVENT"
    CODE: ClassVar[int | None] = Request.SEND_EVENT
    _LAYOUT: ClassVar[struct.Struct | None] = struct.Struct("<B")
    _RANGES: ClassVar[Mapping[str, tuple[int, int]]] = {"event": U8}

    event: int


@dataclass(frozen=True)
class HealthGetHealth(RequestMessage):
    NAME: ClassVar[str] = "HEALTH_GET_HEALTH"
    CODE: ClassVar[int | None] = Request.HEALTH_MGMT
    SUB: ClassVar[int | None] = HealthSub.GET_HEALTH


@dataclass(frozen=True)
class HealthGetError(RequestMessage):
    NAME: ClassVar[str] = "HEALTH_GET_ERROR"
    CODE: ClassVar[int | None] = Request.HEALTH_MGMT
    SUB: ClassVar[int | None] = HealthSub.GET_ERROR
    _LAYOUT: ClassVar[struct.Struct | None] = struct.Struct("<B")
    _RANGES: ClassVar[Mapping[str, tuple[int, int]]] = {"index": U8}

    index: int


@dataclass(frozen=True)
class HealthClrError(RequestMessage):
    NAME: ClassVar[str] = "HEALTH_CLR_ERROR"
    CODE: ClassVar[int | None] = Request.HEALTH_MGMT
    SUB: ClassVar[int | None] = HealthSub.CLR_ERROR
    _LAYOUT: ClassVar[struct.Struct | None] = struct.Struct("<I")
    _RANGES: ClassVar[Mapping[str, tuple[int, int]]] = {"error_code": U32}

    error_code: int


# --- answers -----------------------------------------------------------------------------------


@dataclass(frozen=True)
class SyncAnswer(AnswerMessage):
    """Answer to SYNC: the request frame copied verbatim (same flag, same filler)."""

    NAME: ClassVar[str] = "SYNC"
    RESPONSE: ClassVar[int] = Response.SYNC
    _BYTES: ClassVar[tuple[str, ...]] = ("filler",)

    filler: bytes = b""


@dataclass(frozen=True)
class EchoAnswer(AnswerMessage):
    """Answer to ECHO: the request frame copied verbatim."""

    NAME: ClassVar[str] = "ECHO"
    RESPONSE: ClassVar[int] = Response.ECHO
    _BYTES: ClassVar[tuple[str, ...]] = ("data",)

    data: bytes = b""


@dataclass(frozen=True)
class ErrorAnswer(AnswerMessage):
    """ERROR with a u16 code (an ErrorCode value)."""

    NAME: ClassVar[str] = "ERROR"
    RESPONSE: ClassVar[int] = Response.ERROR
    _LAYOUT: ClassVar[struct.Struct | None] = struct.Struct("<H")
    _RANGES: ClassVar[Mapping[str, tuple[int, int]]] = {"error_code": U16}

    error_code: int


@dataclass(frozen=True)
class InvalidAnswer(AnswerMessage):
    """INVALID (0xFF), no payload; the reference never sends it."""

    NAME: ClassVar[str] = "INVALID"
    RESPONSE: ClassVar[int] = Response.INVALID


@dataclass(frozen=True)
class EmptyAnswer(OkAnswer):
    """OK with no payload: the answer to SET_BASE_MOTOR, POLL_BASE_ANS_CMD, SEND_EVENT,
    HEALTH_CLR_ERROR and BASE_CMD."""


@dataclass(frozen=True)
class ConnectBaseAnswer(ConnectBaseAnswerFields, OkAnswer):
    """Base identity. `firmware_version_suffix` is None in the 28-byte (reference) form and text in
    the 39-byte form the vendor's 2020 SDK expects."""

    def _check(self) -> None:
        _check_text("ConnectBaseAnswer", "model", self.model, 12)
        if self.firmware_version_suffix is not None:
            _check_text("ConnectBaseAnswer", "firmware_version_suffix", self.firmware_version_suffix, 11)

    def _pack(self) -> bytes:
        model = _pack_text(self.model, 12)
        if self.firmware_version_suffix is None:
            return self._REFERENCE_FORM.pack(
                model, self.firmware_version, self.hardware_version, *self.serial
            )
        suffix = _pack_text(self.firmware_version_suffix, 11)
        return self._SDK_FORM.pack(model, self.firmware_version, self.hardware_version, *self.serial, suffix)

    @classmethod
    def _unpack(cls, data: bytes) -> Self:
        _check_length("CONNECT_BASE answer", data, 28, 39)
        suffix: str | None = None
        if len(data) == 39:
            model, firmware, hardware, s0, s1, s2, raw_suffix = cls._SDK_FORM.unpack(data)
            suffix = _unpack_text("ConnectBaseAnswer", "firmware_version_suffix", raw_suffix)
        else:
            model, firmware, hardware, s0, s1, s2 = cls._REFERENCE_FORM.unpack(data)
        return cls(
            _unpack_text("ConnectBaseAnswer", "model", model), firmware, hardware, (s0, s1, s2), suffix
        )

    @property
    def firmware_version_text(self) -> str:
        """ "major.minor" from (major << 8) | minor, e.g. 0x0114 -> "1.20"."""
        return f"{self.firmware_version >> 8}.{self.firmware_version & 0xFF}"


@dataclass(frozen=True)
class Position(PositionFields):
    """Where a sensor or bumper sits: mm Q8 from the robot centre (x forward, y left, z up),
    angle in degrees Q8, anticlockwise, 0..360."""

    def __post_init__(self) -> None:
        for name in ("x_mm_q8", "y_mm_q8", "z_mm_q8"):
            _check_int("Position", name, getattr(self, name), S32)
        _check_int("Position", "angle_deg_q8", self.angle_deg_q8, U32)

    @classmethod
    def from_si(cls, x_mm: float = 0.0, y_mm: float = 0.0, z_mm: float = 0.0, angle_deg: float = 0.0) -> Self:
        return cls(to_q8(x_mm), to_q8(y_mm), to_q8(z_mm), to_q8(angle_deg, signed=False))

    @property
    def x_mm(self) -> float:
        return from_q8(self.x_mm_q8)

    @property
    def y_mm(self) -> float:
        return from_q8(self.y_mm_q8)

    @property
    def z_mm(self) -> float:
        return from_q8(self.z_mm_q8)

    @property
    def angle_deg(self) -> float:
        return from_q8(self.angle_deg_q8)


_POSITION = struct.Struct("<iiiI")
_CONF_SLOTS = protocol_tables.CONF_SLOTS  # sensor and bumper positions in GET_BASE_CONF


@dataclass(frozen=True)
class GetBaseConfAnswer(GetBaseConfAnswerFields, OkAnswer):
    """Base configuration (264 bytes). Fewer than 8 positions may be given: the unused slots are
    filled with zero positions, as on the wire."""

    _HEAD: ClassVar[struct.Struct] = struct.Struct("<BIBB")
    _SIZE: ClassVar[int] = GetBaseConfAnswerFields._WIRE.size

    # the positions as this module's Position (their place in the field order stays)
    sensors: tuple[Position, ...]
    bumpers: tuple[Position, ...]

    def _check(self) -> None:
        for name in ("sensors", "bumpers"):
            value = getattr(self, name)
            if (
                isinstance(value, str | bytes)
                or not isinstance(value, Sequence)
                or len(value) > _CONF_SLOTS
                or not all(isinstance(item, Position) for item in value)
            ):
                raise MessageFormatError(f"GetBaseConfAnswer.{name} must be at most {_CONF_SLOTS} Positions")
            padded = tuple(value) + (Position(),) * (_CONF_SLOTS - len(value))
            object.__setattr__(self, name, padded)

    @classmethod
    def from_si(
        cls,
        *,
        base_type: int,
        base_radius_mm: float,
        motor_type: int = 0,
        sensors: Sequence[Position] = (),
        bumpers: Sequence[Position] = (),
    ) -> Self:
        """Configuration with `sensor_num` / `bumper_num` taken from the positions given."""
        return cls(
            base_type,
            to_q8(base_radius_mm, signed=False),
            motor_type,
            len(sensors),
            tuple(sensors),
            len(bumpers),
            tuple(bumpers),
        )

    @property
    def base_radius_mm(self) -> float:
        return from_q8(self.base_radius_mm_q8)

    def _pack(self) -> bytes:
        parts = [self._HEAD.pack(self.base_type, self.base_radius_mm_q8, self.motor_type, self.sensor_num)]
        parts += [_pack_position(position) for position in self.sensors]
        parts.append(bytes((self.bumper_num,)))
        parts += [_pack_position(position) for position in self.bumpers]
        return b"".join(parts)

    @classmethod
    def _unpack(cls, data: bytes) -> Self:
        _check_length("GET_BASE_CONF answer", data, cls._SIZE)
        base_type, radius, motor_type, sensor_num = cls._HEAD.unpack_from(data)
        at = cls._HEAD.size
        sensors = _unpack_positions(data, at)
        at += _POSITION.size * _CONF_SLOTS
        bumper_num = data[at]
        bumpers = _unpack_positions(data, at + 1)
        return cls(base_type, radius, motor_type, sensor_num, sensors, bumper_num, bumpers)


def _pack_position(position: Position) -> bytes:
    return _POSITION.pack(position.x_mm_q8, position.y_mm_q8, position.z_mm_q8, position.angle_deg_q8)


def _unpack_positions(data: bytes, at: int) -> tuple[Position, ...]:
    return tuple(
        Position(*_POSITION.unpack_from(data, at + _POSITION.size * slot)) for slot in range(_CONF_SLOTS)
    )


@dataclass(frozen=True)
class GetBaseConfAdvAnswer(GetBaseConfAdvAnswerFields, OkAnswer):
    """The binary configuration, carried as opaque bytes here (its tree codec lives elsewhere)."""


@dataclass(frozen=True)
class GetBaseStatusAnswer(GetBaseStatusAnswerFields, OkAnswer):
    """`power_status` bits: POWER_STATUS_BITS (ctrlbus.protocol_tables). A `battery_percent`
    above 100 is kept as sent (docs/protocol.md [status]: the conformance checker flags it)."""


@dataclass(frozen=True)
class GetBaseMotorDataAnswer(GetBaseMotorDataAnswerFields, OkAnswer):
    """Accumulated wheel travel; `status` bits: MOTOR_STATUS_BITS (ctrlbus.protocol_tables)."""


SENSOR_CHANNELS = protocol_tables.SENSOR_CHANNELS


@dataclass(frozen=True)
class GetBaseSensorDataAnswer(GetBaseSensorDataAnswerFields, OkAnswer):
    """Distance per sensor in mm Q16 (16 channels, index = position in the configuration)."""

    @classmethod
    def from_si(cls, distances_mm: Sequence[float]) -> Self:
        """Distances in mm; fewer than 16 are padded with 0 (no echo)."""
        if len(distances_mm) > SENSOR_CHANNELS:
            raise MessageFormatError(f"at most {SENSOR_CHANNELS} distances, got {len(distances_mm)}")
        raw = [to_q16(value, signed=False) for value in distances_mm]
        return cls(tuple(raw + [0] * (SENSOR_CHANNELS - len(raw))))

    @property
    def distances_mm(self) -> tuple[float, ...]:
        return tuple(from_q16(value) for value in self.distances_mm_q16)


@dataclass(frozen=True)
class GetBaseBumperDataAnswer(GetBaseBumperDataAnswerFields, OkAnswer):
    """Bumper and cliff bitmap, ACTIVE LOW (0 = triggered). `payload_size` is how many bytes were
    sent (4 now, 1 in the 2018 firmware); a short answer is zero-padded to 32 bits."""

    def _check(self) -> None:
        if self.bitmap >> (8 * self.payload_size):
            raise MessageFormatError(
                f"bumper bitmap 0x{self.bitmap:X} does not fit in {self.payload_size} bytes"
            )

    def _pack(self) -> bytes:
        return self.bitmap.to_bytes(self.payload_size, "little")

    @classmethod
    def _unpack(cls, data: bytes) -> Self:
        _check_length("GET_BASE_BUMPER_DATA answer", data, 1, 2, 3, 4)
        return cls(int.from_bytes(data, "little"), len(data))


@dataclass(frozen=True)
class GetChargerDataAnswer(GetChargerDataAnswerFields, OkAnswer):
    """Dock beacon data: one byte per probe (left, main, right), each a bitmap of the beacons it
    sees (CHARGER_PROBE_BITS of ctrlbus.protocol_tables)."""

    def _check(self) -> None:
        probes = self.probes
        if (
            isinstance(probes, str | bytes)
            or not isinstance(probes, Sequence)
            or len(probes) != self.probe_count
        ):
            raise MessageFormatError(
                f"GetChargerDataAnswer.probes must hold probe_count={self.probe_count} values"
            )
        for value in probes:
            _check_int("GetChargerDataAnswer", "probes", value, U8)
        object.__setattr__(self, "probes", tuple(probes))

    def _pack(self) -> bytes:
        return bytes((self.beacon_count, self.probe_count, *self.probes))

    @classmethod
    def _unpack(cls, data: bytes) -> Self:
        if len(data) < 2 or len(data) != 2 + data[1]:
            raise MessageFormatError(
                f"GET_CHARGER_DATA answer: {len(data)} bytes do not match its probe count"
            )
        return cls(data[0], data[1], tuple(data[2:]))


@dataclass(frozen=True)
class SetVAndGetDeadreckonAnswer(SetVAndGetDeadreckonAnswerFields, OkAnswer):
    """Motion since the previous call, Q16: dx, dy in mm, dtheta in DEGREES (anticlockwise).
    `timestamp_ms` is None in the 13-byte (reference) form, set in the 17-byte SDK form."""

    @classmethod
    def from_si(
        cls, dx_mm: float, dy_mm: float, dtheta_deg: float, status: int = 0, timestamp_ms: int | None = None
    ) -> Self:
        return cls(to_q16(dx_mm), to_q16(dy_mm), to_q16(dtheta_deg), status, timestamp_ms)

    @property
    def dx_mm(self) -> float:
        return from_q16(self.dx_mm_q16)

    @property
    def dy_mm(self) -> float:
        return from_q16(self.dy_mm_q16)

    @property
    def dtheta_deg(self) -> float:
        return from_q16(self.dtheta_deg_q16)


@dataclass(frozen=True)
class PollBaseCmdAnswer(OkAnswer):
    """Pending external command, or None. Forms on the wire: nothing pending = 0 bytes
    (payload_size 0) or FF + a don't-care byte (payload_size 2, `pad` = that byte); a pending
    command = its code + a don't-care byte (`pad`)."""

    _RANGES: ClassVar[Mapping[str, tuple[int, int]]] = {"pad": U8}

    command: int | None = None
    payload_size: int = 0
    pad: int = 0

    def _check(self) -> None:
        if self.command is not None:
            _check_int("PollBaseCmdAnswer", "command", self.command, (0, POLL_NOTHING_PENDING - 1))
        if self.payload_size not in (0, 2):
            raise MessageFormatError(
                f"PollBaseCmdAnswer.payload_size must be 0 or 2, got {self.payload_size!r}"
            )
        if self.payload_size == 0 and (self.command is not None or self.pad):
            raise MessageFormatError(
                "the empty POLL_BASE_CMD answer carries neither a command nor a pad byte"
            )

    @classmethod
    def pending(cls, command: int) -> Self:
        return cls(command, 2, 0)

    def _pack(self) -> bytes:
        if self.payload_size == 0:
            return b""
        first = POLL_NOTHING_PENDING if self.command is None else self.command
        return bytes((first, self.pad))

    @classmethod
    def _unpack(cls, data: bytes) -> Self:
        _check_length("POLL_BASE_CMD answer", data, 0, 2)
        if not data:
            return cls()
        command = None if data[0] == POLL_NOTHING_PENDING else data[0]
        return cls(command, 2, data[1])


@dataclass(frozen=True)
class HealthGetHealthAnswer(HealthGetHealthAnswerFields, OkAnswer):
    """`flags` bits: HEALTH_FLAGS_BITS (ctrlbus.protocol_tables)."""


HEALTH_MESSAGE_SIZE = protocol_tables.HEALTH_MESSAGE_LEN


@dataclass(frozen=True)
class HealthGetErrorAnswer(HealthGetErrorAnswerFields, OkAnswer):
    """One registered error: its u32 code and a text of at most 31 characters (NUL-terminated in
    32 bytes on the wire)."""

    def _check(self) -> None:
        _check_text("HealthGetErrorAnswer", "message", self.message, HEALTH_MESSAGE_SIZE - 1)

    def _pack(self) -> bytes:
        return self._WIRE.pack(self.error_code, _pack_text(self.message, HEALTH_MESSAGE_SIZE))

    @classmethod
    def _unpack(cls, data: bytes) -> Self:
        _check_length("HEALTH_GET_ERROR answer", data, cls._WIRE.size)
        code, raw = cls._WIRE.unpack(data)
        return cls(code, _unpack_text("HealthGetErrorAnswer", "message", raw, nul_required=True))


# --- registry ----------------------------------------------------------------------------------

REQUEST_CLASSES: Mapping[str, type[RequestMessage]] = {
    cls.NAME: cls
    for cls in (
        Sync,
        Echo,
        BaseCommand,
        ConnectBase,
        GetBaseConf,
        GetBaseConfAdv,
        GetBaseStatus,
        GetBaseMotorData,
        GetBaseSensorData,
        GetBaseBumperData,
        GetChargerData,
        GetAuxiliaryAnchor,
        SetBaseMotor,
        SetVAndGetDeadreckon,
        PollBaseCmd,
        PollBaseAnsCmd,
        SendEvent,
        HealthGetHealth,
        HealthGetError,
        HealthClrError,
    )
}

# The OK answer class for each request (GET_AUXILIARY_ANCHOR, SYNC and ECHO have none).
OK_ANSWER_CLASSES: Mapping[str, type[OkAnswer]] = {
    "BASE_CMD": EmptyAnswer,
    "CONNECT_BASE": ConnectBaseAnswer,
    "GET_BASE_CONF": GetBaseConfAnswer,
    "GET_BASE_CONF_ADV": GetBaseConfAdvAnswer,
    "GET_BASE_STATUS": GetBaseStatusAnswer,
    "GET_BASE_MOTOR_DATA": GetBaseMotorDataAnswer,
    "GET_BASE_SENSOR_DATA": GetBaseSensorDataAnswer,
    "GET_BASE_BUMPER_DATA": GetBaseBumperDataAnswer,
    "GET_CHARGER_DATA": GetChargerDataAnswer,
    "SET_BASE_MOTOR": EmptyAnswer,
    "SET_V_AND_GET_DEADRECKON": SetVAndGetDeadreckonAnswer,
    "POLL_BASE_CMD": PollBaseCmdAnswer,
    "POLL_BASE_ANS_CMD": EmptyAnswer,
    "SEND_EVENT": EmptyAnswer,
    "HEALTH_GET_HEALTH": HealthGetHealthAnswer,
    "HEALTH_GET_ERROR": HealthGetErrorAnswer,
    "HEALTH_CLR_ERROR": EmptyAnswer,
}

# Answers that do not depend on the request, by name and by CMD byte.
RESPONSE_ANSWER_CLASSES: Mapping[str, type[AnswerMessage]] = {
    cls.NAME: cls for cls in (SyncAnswer, EchoAnswer, ErrorAnswer, InvalidAnswer)
}
_ANSWER_BY_RESPONSE: Mapping[int, type[AnswerMessage]] = {
    cls.RESPONSE: cls for cls in RESPONSE_ANSWER_CLASSES.values()
}

_REQUEST_BY_CMD: Mapping[int, type[RequestMessage]] = {
    cls.CMD: cls for cls in REQUEST_CLASSES.values() if cls.CMD != Cmd.CTRL_BUS
}
_REQUEST_BY_CODE: Mapping[int, type[RequestMessage]] = {
    cls.CODE: cls for cls in REQUEST_CLASSES.values() if cls.CODE is not None and cls.SUB is None
}
_REQUEST_BY_SUB: Mapping[int, type[RequestMessage]] = {
    cls.SUB: cls for cls in REQUEST_CLASSES.values() if cls.SUB is not None
}


def request_class(name: str) -> type[RequestMessage]:
    """The request class of a contract name ("SET_V_AND_GET_DEADRECKON")."""
    try:
        return REQUEST_CLASSES[name]
    except KeyError:
        raise UnsupportedMessageError(f"unknown request {name!r}") from None


def answer_class(to: str, name: str) -> type[AnswerMessage]:
    """The answer class for answer `name` ("OK", "ERROR", "INVALID", "SYNC", "ECHO") to request `to`."""
    request_class(to)
    if name == "OK":
        try:
            return OK_ANSWER_CLASSES[to]
        except KeyError:
            raise UnsupportedMessageError(f"no OK answer is defined for {to}") from None
    try:
        return RESPONSE_ANSWER_CLASSES[name]
    except KeyError:
        raise UnsupportedMessageError(f"unknown answer {name!r}") from None


# --- codec -------------------------------------------------------------------------------------


def encode_request(msg: RequestMessage) -> tuple[int, bytes]:
    """(CMD byte, payload) of a request."""
    head = b""
    if msg.CODE is not None:
        head = bytes((msg.CODE,)) if msg.SUB is None else bytes((msg.CODE, msg.SUB))
    return msg.CMD, head + msg._pack()


def decode_request(cmd: int, payload: bytes) -> RequestMessage:
    """The request in a frame's (CMD, payload)."""
    if cmd != Cmd.CTRL_BUS:
        request = _REQUEST_BY_CMD.get(cmd)
        if request is None:
            raise UnsupportedMessageError(f"unknown command 0x{cmd:02X}")
        return request._unpack(payload)
    if not payload:
        raise MessageFormatError("CTRL_BUS frame without a request code")
    code = payload[0]
    if code == Request.HEALTH_MGMT:
        if len(payload) < 2:
            raise MessageFormatError("HEALTH_MGMT request without a sub-command")
        request = _REQUEST_BY_SUB.get(payload[1])
        if request is None:
            raise UnsupportedSubcommandError(f"unknown HEALTH_MGMT sub-command 0x{payload[1]:02X}")
        return request._unpack(payload[2:])
    request = _REQUEST_BY_CODE.get(code)
    if request is None:
        raise UnsupportedMessageError(f"unknown control-bus request 0x{code:02X}")
    return request._unpack(payload[1:])


def encode_answer(msg: AnswerMessage) -> tuple[int, bytes]:
    """(CMD byte, payload) of an answer."""
    return msg.RESPONSE, msg._pack()


def decode_answer(request: str | RequestMessage, cmd: int, payload: bytes) -> AnswerMessage:
    """The answer in a frame's (CMD, payload), read as an answer to `request` (its name or the
    request itself): an OK payload is read per that request; SYNC, ECHO, ERROR and INVALID are
    read the same whatever the request."""
    to = request if isinstance(request, str) else request.NAME
    request_class(to)
    if cmd == Response.OK:
        answer = OK_ANSWER_CLASSES.get(to)
        if answer is None:
            raise UnsupportedMessageError(f"no OK answer is defined for {to}")
        return answer._unpack(payload)
    answer_cls = _ANSWER_BY_RESPONSE.get(cmd)
    if answer_cls is None:
        raise UnsupportedMessageError(f"unknown response 0x{cmd:02X}")
    return answer_cls._unpack(payload)


def encode(msg: Message) -> tuple[int, bytes]:
    """(CMD byte, payload) of any message: `encode_request` or `encode_answer` by its kind."""
    if isinstance(msg, RequestMessage):
        return encode_request(msg)
    if isinstance(msg, AnswerMessage):
        return encode_answer(msg)
    raise UnsupportedMessageError(f"not a request or an answer: {type(msg).__name__}")


def decode(cmd: int, payload: bytes, *, answer_to: str | RequestMessage | None = None) -> Message:
    """The message in a frame's (CMD, payload): a request, or with `answer_to` (the request's name
    or the request) the answer to that request (`decode_request` / `decode_answer`)."""
    if answer_to is None:
        return decode_request(cmd, payload)
    return decode_answer(answer_to, cmd, payload)


def request_frame(msg: RequestMessage, *, long: bool | None = None) -> bytes:
    """The whole frame of a request (standard when it fits, unless `long` says otherwise)."""
    return encode_frame(*encode_request(msg), long=long)


def answer_frame(msg: AnswerMessage, *, long: bool | None = None) -> bytes:
    """The whole frame of an answer (standard when it fits, unless `long` says otherwise)."""
    return encode_frame(*encode_answer(msg), long=long)


# --- the contract's JSON form ------------------------------------------------------------------


def hex_text(data: bytes) -> str:
    """Bytes as the vectors write them: "AA 55"."""
    return data.hex(" ").upper()


def parse_hex(text: str) -> bytes:
    """Inverse of hex_text; spaces between bytes are optional."""
    if not isinstance(text, str):
        raise MessageFormatError(f"expected hex text, got {text!r}")
    try:
        return bytes.fromhex(text)
    except ValueError:
        raise MessageFormatError(f"not hex bytes: {text!r}") from None


def _to_json(value: object) -> Any:
    if isinstance(value, bytes):
        return hex_text(value)
    if isinstance(value, tuple):
        return [_to_json(item) for item in value]
    if isinstance(value, Position):
        return {item.name: getattr(value, item.name) for item in dataclass_fields(value)}
    return value


def fields(msg: Message) -> dict[str, Any]:
    """The message's fields in the contract's JSON form (bytes as hex text, lists, nested dicts)."""
    return {item.name: _to_json(getattr(msg, item.name)) for item in dataclass_fields(msg)}


_HINTS: dict[type[Message], dict[str, Any]] = {}


def _field_types(cls: type[Message]) -> dict[str, Any]:
    hints = _HINTS.get(cls)
    if hints is None:
        resolved = typing.get_type_hints(cls)
        hints = {item.name: resolved[item.name] for item in dataclass_fields(cls)}
        _HINTS[cls] = hints
    return hints


def _from_json(owner: str, name: str, hint: Any, value: Any) -> Any:
    if hint is bytes:
        return parse_hex(value)
    if typing.get_origin(hint) is tuple:
        if not isinstance(value, list | tuple):
            raise MessageFormatError(f"{owner}.{name} must be a list, got {value!r}")
        if typing.get_args(hint)[0] is Position:
            positions = []
            for item in value:
                if not isinstance(item, Mapping):
                    raise MessageFormatError(f"{owner}.{name} items must be objects, got {item!r}")
                positions.append(_build(Position, owner, item))
            return tuple(positions)
        return tuple(value)
    return value


def _build(cls: type[Any], owner: str, values: Mapping[str, Any]) -> Any:
    try:
        return cls(**values)
    except TypeError as exc:  # missing or unknown field names
        raise MessageFormatError(f"{owner}: {exc}") from None


def from_fields(name: str, values: Mapping[str, Any], *, to: str | None = None) -> Message:
    """Build a message from the contract's JSON form: a request by its name, or (with `to`, the
    request answered) an answer by its name ("OK", "ERROR", "INVALID", "SYNC", "ECHO")."""
    cls: type[Message] = request_class(name) if to is None else answer_class(to, name)
    hints = _field_types(cls)
    unknown = sorted(set(values) - set(hints))
    if unknown:
        raise MessageFormatError(f"{name}: unknown fields {', '.join(unknown)}")
    owner = cls.__name__
    converted = {key: _from_json(owner, key, hints[key], value) for key, value in values.items()}
    message: Message = _build(cls, owner, converted)
    return message
