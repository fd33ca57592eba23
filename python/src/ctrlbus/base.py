# SPDX-License-Identifier: MIT
"""The base side of the Control Bus: a sans-IO protocol stack and the application it serves.

A base maker writes the application (`Base`: what the robot reports and how it moves) and lets
`BaseStack` do the protocol: framing, dispatch, error answers, answer variants (profiles), the
motor watchdog, velocity limits, the external-command queue and the health registry.
docs/base-framework.md is the manual and holds the exact behaviour list, which the C base stack
mirrors.

    stack = BaseStack(MyBase(), BaseConfig())
    answer = stack.receive(data, now)     # bytes from the link in, answer bytes out
    answer += stack.tick(now)             # call often: watchdog, inter-byte timeout, app time

The stack never reads a clock, never sleeps and never touches a port: `now` (seconds, any origin,
non-decreasing) comes from the caller. `serve()` and `BaseRunner` connect a stack to a `Link` in
real time.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections import Counter, deque
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from dataclasses import fields as dataclass_fields
from types import TracebackType
from typing import TYPE_CHECKING, Any, TypeVar

from ctrlbus.constants import (
    COMPONENT_MOTION,
    COMPONENT_POWER,
    COMPONENT_SENSOR,
    COMPONENT_SYSTEM,
    COMPONENT_USER,
    HEALTH_ERROR,
    HEALTH_FATAL,
    HEALTH_WARNING,
    REFERENCE_LOW_BATTERY_CODE,
    REFERENCE_LOW_BATTERY_MESSAGE,
    WATCHDOG_TRIPPED_CODE,
    WATCHDOG_TRIPPED_MESSAGE,
    Profile,
    health_code,
    parse_profile,
)
from ctrlbus.errors import (
    CtrlbusError,
    MessageFormatError,
    UnsupportedMessageError,
    UsageError,
)
from ctrlbus.frame import FLAG_LONG, DecoderEvent, DecoderStats, EventKind, Frame, StreamDecoder
from ctrlbus.kinematics import wheel_speeds_from_velocity
from ctrlbus.link import Link
from ctrlbus.messages import (
    AnswerMessage,
    BaseCommand,
    BaseSubcommand,
    Cmd,
    ConnectBase,
    ConnectBaseAnswer,
    EmptyAnswer,
    ErrorAnswer,
    ErrorCode,
    ExternalCommand,
    GetAuxiliaryAnchor,
    GetBaseBumperData,
    GetBaseBumperDataAnswer,
    GetBaseConf,
    GetBaseConfAdv,
    GetBaseConfAdvAnswer,
    GetBaseConfAnswer,
    GetBaseMotorData,
    GetBaseMotorDataAnswer,
    GetBaseSensorData,
    GetBaseSensorDataAnswer,
    GetBaseStatus,
    GetBaseStatusAnswer,
    GetChargerData,
    GetChargerDataAnswer,
    HealthClrError,
    HealthGetError,
    HealthGetErrorAnswer,
    HealthGetHealth,
    HealthGetHealthAnswer,
    PollBaseAnsCmd,
    PollBaseCmd,
    PollBaseCmdAnswer,
    RequestMessage,
    SendEvent,
    SetBaseMotor,
    SetVAndGetDeadreckon,
    SetVAndGetDeadreckonAnswer,
    answer_frame,
    decode_request,
)
from ctrlbus.quirks import STARTUP_BATTERY_S, Quirks, ReferenceReceiver, parse_quirks

if TYPE_CHECKING:
    from typing_extensions import Self  # typing.Self from Python 3.11; annotations only

__all__ = [
    "COMPONENT_MOTION",
    "COMPONENT_POWER",
    "COMPONENT_SENSOR",
    "COMPONENT_SYSTEM",
    "COMPONENT_USER",
    "DEFAULT_FRAME_TIMEOUT_S",
    "DEFAULT_MAX_FRAME",
    "DEFAULT_POLL_S",
    "DEFAULT_WATCHDOG_S",
    "HEALTH_ERROR",
    "HEALTH_FATAL",
    "HEALTH_WARNING",
    "MAX_HEALTH_ERRORS",
    "MAX_PENDING_COMMANDS",
    "WATCHDOG_TRIPPED_CODE",
    "WATCHDOG_TRIPPED_MESSAGE",
    "Base",
    "BaseConfig",
    "BaseCounters",
    "BaseRunner",
    "BaseStack",
    "CallbackBase",
    "HealthEntry",
    "HealthRegistry",
    "Profile",
    "VelocityLimits",
    "health_code",
    "parse_profile",
    "serve",
]

_log = logging.getLogger(__name__)

DEFAULT_WATCHDOG_S = 1.0  # the reference's motor watchdog
# Largest request frame accepted, header and checksum included (protocol.md [frame-limits]: the
# reference's receive buffer size). Far below a long frame's 65539, so a bogus long length is
# refused (ERROR 0x0020) as soon as its header is in, instead of swallowing later frames.
DEFAULT_MAX_FRAME = 512
# Inter-byte timeout of a host program (protocol.md [dec-defaults]): a USB-serial adapter delivers
# bytes in bursts (16 ms latency timers plus scheduling).
DEFAULT_FRAME_TIMEOUT_S = 0.1
DEFAULT_POLL_S = 0.01  # how long the real-time runner waits for bytes before ticking
MAX_HEALTH_ERRORS = 16
MAX_PENDING_COMMANDS = 16


def _positive_or_none(owner: str, name: str, value: float | None) -> None:
    if value is None:
        return
    if (
        isinstance(value, bool)
        or not isinstance(value, int | float)
        or not (math.isfinite(value) and value > 0)
    ):
        raise UsageError(f"{owner}.{name} must be a finite number > 0 or None, got {value!r}")


@dataclass(frozen=True)
class VelocityLimits:
    """Optional limits on what the Core may command; None (or 0) means no limit.

    `max_wheel_mm_s` bounds each wheel of SET_BASE_MOTOR, and of SET_V_AND_GET_DEADRECKON too when
    `wheel_track_mm` is given (to turn (vx, omega) into wheel speeds); both wheels are scaled by the
    same factor, so the robot keeps its turning radius. `max_vx_mps` and `max_omega_radps` bound
    |vx| and |omega| of SET_V_AND_GET_DEADRECKON, each on its own.
    """

    max_wheel_mm_s: float | None = None
    max_vx_mps: float | None = None
    max_omega_radps: float | None = None
    wheel_track_mm: float | None = None

    def __post_init__(self) -> None:
        for name in ("max_wheel_mm_s", "max_vx_mps", "max_omega_radps", "wheel_track_mm"):
            value = getattr(self, name)
            if isinstance(value, int | float) and not isinstance(value, bool) and value == 0:
                object.__setattr__(self, name, None)  # 0 = no limit, as in the C configuration
                continue
            _positive_or_none("VelocityLimits", name, value)

    def limit_wheels(self, left_mm_s: float, right_mm_s: float) -> tuple[float, float, bool]:
        """(left, right, clamped): the wheel speeds scaled down together to the wheel limit."""
        limit = self.max_wheel_mm_s
        peak = max(abs(left_mm_s), abs(right_mm_s))
        if limit is None or peak <= limit:
            return left_mm_s, right_mm_s, False
        scale = limit / peak
        return left_mm_s * scale, right_mm_s * scale, True

    def limit_velocity(self, vx_mps: float, omega_radps: float) -> tuple[float, float, bool]:
        """(vx, omega, clamped): each axis clamped, then both scaled to the wheel limit if known."""
        clamped = False
        if self.max_vx_mps is not None and abs(vx_mps) > self.max_vx_mps:
            vx_mps = math.copysign(self.max_vx_mps, vx_mps)
            clamped = True
        if self.max_omega_radps is not None and abs(omega_radps) > self.max_omega_radps:
            omega_radps = math.copysign(self.max_omega_radps, omega_radps)
            clamped = True
        if self.max_wheel_mm_s is not None and self.wheel_track_mm is not None:
            left, right = wheel_speeds_from_velocity(vx_mps, omega_radps, self.wheel_track_mm)
            peak = max(abs(left), abs(right))
            if peak > self.max_wheel_mm_s:
                scale = self.max_wheel_mm_s / peak
                vx_mps *= scale
                omega_radps *= scale
                clamped = True
        return vx_mps, omega_radps, clamped


@dataclass(frozen=True)
class BaseConfig:
    """How the stack behaves. The defaults are the documented behaviour (docs/base-framework.md).

    - `profile`: which answer variants are sent (`Profile`, or its name).
    - `long_answers`: OK and ERROR answers as long (0x50) frames, as the reference sends them;
      False sends standard frames when the payload fits. The sdk2020 profile needs long answers.
    - `reference_checksum_code`: answer a checksum mismatch with the reference's 0x00C0 instead
      of 0x0040.
    - `watchdog_s`: the motor watchdog's silence limit; None switches it off (only for tests that
      need a base without one).
    - `max_frame`: the largest request frame accepted (header and checksum included); a longer
      one is answered ERROR 0x0020.
    - `frame_timeout_s`: inter-byte timeout of a frame in progress; 0 switches it off.
    - `limits`: optional velocity limits.
    - `quirks`: `Quirks.REFERENCE` imitates the reference firmware's receiver and start-up
      (ctrlbus.quirks, docs/simulator.md): combined error bits, requests dropped behind pending
      garbage reports, LEN = 0 re-running the previous request, no inter-byte timeout, 1.9 s of
      silence after power-on, 0 % battery and a low-battery error for the first 3 s.
    """

    profile: Profile = Profile.REFERENCE
    long_answers: bool = True
    reference_checksum_code: bool = False
    watchdog_s: float | None = DEFAULT_WATCHDOG_S
    max_frame: int = DEFAULT_MAX_FRAME
    frame_timeout_s: float = DEFAULT_FRAME_TIMEOUT_S
    limits: VelocityLimits = field(default_factory=VelocityLimits)
    quirks: Quirks = Quirks.NONE

    def __post_init__(self) -> None:
        object.__setattr__(self, "profile", parse_profile(self.profile))
        object.__setattr__(self, "quirks", parse_quirks(self.quirks))
        _positive_or_none("BaseConfig", "watchdog_s", self.watchdog_s)
        if isinstance(self.max_frame, bool) or not isinstance(self.max_frame, int) or self.max_frame < 5:
            raise UsageError(f"BaseConfig.max_frame must be an integer >= 5, got {self.max_frame!r}")
        timeout = self.frame_timeout_s
        if (
            isinstance(timeout, bool)
            or not isinstance(timeout, int | float)
            or not (math.isfinite(timeout) and timeout >= 0)
        ):
            raise UsageError(f"BaseConfig.frame_timeout_s must be a finite number >= 0, got {timeout!r}")
        if not isinstance(self.limits, VelocityLimits):
            raise UsageError(f"BaseConfig.limits must be a VelocityLimits, got {self.limits!r}")
        if self.profile is Profile.SDK2020 and not self.long_answers:
            raise UsageError("the sdk2020 profile needs long answers (its master checks for the 0x50 flag)")


# --- the application side ----------------------------------------------------------------------


class Base:
    """The application: what a robot reports and how it moves. Subclass it and override what your
    base supports; a method left as it is here answers ERROR 0x8000 (not supported), except the
    few with a default noted below.

    The stack calls these methods from `receive` / `tick` while holding `stack.lock`, with values
    already decoded, checked and limited. They should be quick (no waiting on hardware). Raising a
    CtrlbusError answers ERROR 0x8002 (operation error); any other exception does the same and is
    logged and counted as a handler error; NotImplementedError answers 0x8000.
    """

    _stack: BaseStack | None = None

    @property
    def stack(self) -> BaseStack:
        """The stack serving this base (set when the BaseStack is made)."""
        if self._stack is None:
            raise UsageError("this base is not attached to a BaseStack yet")
        return self._stack

    def attach(self, stack: BaseStack) -> None:
        """Called by BaseStack's constructor; a base serves one stack."""
        if self._stack is not None and self._stack is not stack:
            raise UsageError("this base is already attached to another BaseStack")
        self._stack = stack

    # Time. Default: nothing to do.
    def advance(self, now: float) -> None:
        """Time has reached `now` (the caller's seconds, non-decreasing); called before any
        request at that time is handled, and on every tick."""

    # Requests. Each returns the OK answer's message.
    def connect_info(self) -> ConnectBaseAnswer:
        """CONNECT_BASE (the stack has checked protocol version 1). The stack fits the answer to
        the profile: the suffix is dropped for reference, "" is added for sdk2020 if absent."""
        raise NotImplementedError

    def base_config(self) -> GetBaseConfAnswer:
        """GET_BASE_CONF."""
        raise NotImplementedError

    def binary_config(self) -> bytes:
        """GET_BASE_CONF_ADV: the binary configuration blob. Unimplemented: ERROR 0x8000, and the
        Core falls back to GET_BASE_CONF."""
        raise NotImplementedError

    def status(self) -> GetBaseStatusAnswer:
        """GET_BASE_STATUS."""
        raise NotImplementedError

    def motor_data(self) -> GetBaseMotorDataAnswer:
        """GET_BASE_MOTOR_DATA."""
        raise NotImplementedError

    def sensor_data(self) -> GetBaseSensorDataAnswer:
        """GET_BASE_SENSOR_DATA."""
        raise NotImplementedError

    def bumper_data(self) -> GetBaseBumperDataAnswer:
        """GET_BASE_BUMPER_DATA (ACTIVE LOW bitmap). sdk2020 widens a short answer to 4 bytes."""
        raise NotImplementedError

    def charger_data(self) -> GetChargerDataAnswer:
        """GET_CHARGER_DATA beacon data (the stack answers 0x8000 to other data types itself)."""
        raise NotImplementedError

    def set_wheel_speeds(self, left_mm_s: float, right_mm_s: float) -> None:
        """SET_BASE_MOTOR: wheel speeds in mm/s (after the limits)."""
        raise NotImplementedError

    def set_velocity(self, vx_mps: float, vy_mps: float, omega_radps: float) -> SetVAndGetDeadreckonAnswer:
        """SET_V_AND_GET_DEADRECKON: apply the velocity (after the limits) and return the motion
        since the previous call. `timestamp_ms` may be left None: with sdk2020 the stack fills in
        the milliseconds since the stack started; with reference it is dropped."""
        raise NotImplementedError

    def stop_motors(self) -> None:
        """The motor watchdog tripped. Default: set_wheel_speeds(0, 0)."""
        self.set_wheel_speeds(0.0, 0.0)

    def on_event(self, event: int) -> None:
        """SEND_EVENT (any code, known or not, is answered OK). Default: ignore it."""

    def on_reboot(self) -> None:
        """BASE_CMD REBOOT: reset the base. The stack answers OK and calls this only after that
        answer was handed over: at the start of the next receive()/tick(). Not overridden:
        ERROR 0x8000."""
        raise NotImplementedError

    def on_enter_dfu(self) -> None:
        """BASE_CMD ENTER_DFU: start the firmware update mode; called like on_reboot, after the
        OK answer. Not overridden: ERROR 0x8000."""
        raise NotImplementedError

    def implements(self, name: str) -> bool:
        """Whether the application provides the method `name` (the stack asks this for the
        BASE_CMD hooks, whose answer must be decided before they run)."""
        return getattr(type(self), name, None) is not getattr(Base, name, None)


_HANDLER_NAMES = (
    "advance",
    "connect_info",
    "base_config",
    "binary_config",
    "status",
    "motor_data",
    "sensor_data",
    "bumper_data",
    "charger_data",
    "set_wheel_speeds",
    "set_velocity",
    "stop_motors",
    "on_event",
    "on_reboot",
    "on_enter_dfu",
)


class CallbackBase(Base):
    """A Base configured with callables instead of a subclass:

        CallbackBase(status=lambda: GetBaseStatusAnswer(80, 0), set_wheel_speeds=motors.set)

    Each keyword names a `Base` method and gives the callable that implements it (same
    arguments, same return value). Methods not given behave as in `Base`.
    """

    def __init__(self, **handlers: Callable[..., Any]) -> None:
        unknown = sorted(set(handlers) - set(_HANDLER_NAMES))
        if unknown:
            known = ", ".join(_HANDLER_NAMES)
            raise UsageError(f"unknown base handler(s): {', '.join(unknown)} (known: {known})")
        for name, handler in handlers.items():
            if not callable(handler):
                raise UsageError(f"base handler {name} must be callable, got {handler!r}")
        self._handlers = dict(handlers)

    def implements(self, name: str) -> bool:
        if name in self._handlers:
            return True
        return getattr(type(self), name, None) is not getattr(CallbackBase, name, None)

    def _call(self, name: str, *args: Any) -> Any:
        handler = self._handlers.get(name)
        if handler is None:
            return getattr(Base, name)(self, *args)
        return handler(*args)

    def advance(self, now: float) -> None:
        self._call("advance", now)

    def connect_info(self) -> ConnectBaseAnswer:
        result: ConnectBaseAnswer = self._call("connect_info")
        return result

    def base_config(self) -> GetBaseConfAnswer:
        result: GetBaseConfAnswer = self._call("base_config")
        return result

    def binary_config(self) -> bytes:
        result: bytes = self._call("binary_config")
        return result

    def status(self) -> GetBaseStatusAnswer:
        result: GetBaseStatusAnswer = self._call("status")
        return result

    def motor_data(self) -> GetBaseMotorDataAnswer:
        result: GetBaseMotorDataAnswer = self._call("motor_data")
        return result

    def sensor_data(self) -> GetBaseSensorDataAnswer:
        result: GetBaseSensorDataAnswer = self._call("sensor_data")
        return result

    def bumper_data(self) -> GetBaseBumperDataAnswer:
        result: GetBaseBumperDataAnswer = self._call("bumper_data")
        return result

    def charger_data(self) -> GetChargerDataAnswer:
        result: GetChargerDataAnswer = self._call("charger_data")
        return result

    def set_wheel_speeds(self, left_mm_s: float, right_mm_s: float) -> None:
        self._call("set_wheel_speeds", left_mm_s, right_mm_s)

    def set_velocity(self, vx_mps: float, vy_mps: float, omega_radps: float) -> SetVAndGetDeadreckonAnswer:
        result: SetVAndGetDeadreckonAnswer = self._call("set_velocity", vx_mps, vy_mps, omega_radps)
        return result

    def stop_motors(self) -> None:
        self._call("stop_motors")

    def on_event(self, event: int) -> None:
        self._call("on_event", event)

    def on_reboot(self) -> None:
        self._call("on_reboot")

    def on_enter_dfu(self) -> None:
        self._call("on_enter_dfu")


# --- health ------------------------------------------------------------------------------------


@dataclass(frozen=True)
class HealthEntry:
    """One registered health error: its u32 code and a message of at most 31 ASCII characters."""

    code: int
    message: str


class HealthRegistry:
    """The errors HEALTH_MGMT reports, in the order they were added (GET_ERROR's index order).

    At most MAX_HEALTH_ERRORS entries; one entry per code (registering a code already in the
    list changes nothing, protocol.md [health-list]). GET_HEALTH's flags are the OR of the level
    bytes' bits 0-2 (warning, error, fatal). Thread-safe (it shares the stack's lock).
    """

    def __init__(self, lock: threading.RLock) -> None:
        self._lock = lock
        self._entries: list[HealthEntry] = []

    def add(self, code: int, message: str = "") -> bool:
        """Register an error; returns False if its code was registered already (nothing changes
        then). UsageError for a code that is not u32, a message that does not fit (31 ASCII
        characters, no NUL), or a full registry."""
        try:
            HealthGetErrorAnswer(code, message)  # the wire's checks on both fields
        except MessageFormatError as exc:
            raise UsageError(f"cannot register health error: {exc}") from None
        with self._lock:
            if any(existing.code == code for existing in self._entries):
                return False
            if len(self._entries) >= MAX_HEALTH_ERRORS:
                raise UsageError(f"the health registry is full ({MAX_HEALTH_ERRORS} errors)")
            self._entries.append(HealthEntry(code, message))
            return True

    def clear(self, code: int) -> bool:
        """Remove the error with this code; False if there was none."""
        with self._lock:
            for index, existing in enumerate(self._entries):
                if existing.code == code:
                    del self._entries[index]
                    return True
            return False

    def clear_all(self) -> None:
        with self._lock:
            self._entries.clear()

    def __contains__(self, code: object) -> bool:
        with self._lock:
            return any(entry.code == code for entry in self._entries)

    def __len__(self) -> int:
        with self._lock:
            return len(self._entries)

    @property
    def entries(self) -> tuple[HealthEntry, ...]:
        with self._lock:
            return tuple(self._entries)

    @property
    def flags(self) -> int:
        """GET_HEALTH flags: bit0 warning, bit1 error, bit2 fatal."""
        with self._lock:
            flags = 0
            for entry in self._entries:
                flags |= (entry.code >> 24) & (HEALTH_WARNING | HEALTH_ERROR | HEALTH_FATAL)
            return flags


# --- counters ----------------------------------------------------------------------------------


@dataclass(frozen=True)
class BaseCounters:
    """What the stack has seen and done since it was made (a snapshot).

    `requests` counts decoded requests by name (SYNC, ECHO, BASE_CMD, CONNECT_BASE, ...);
    `errors_sent` counts ERROR answers by code; `handler_errors` counts application exceptions
    other than NotImplementedError and CtrlbusError (bugs: they are logged); `decoder` holds the
    stream decoder's counters.
    """

    bytes_received: int = 0
    bytes_sent: int = 0
    answers: int = 0
    requests: Mapping[str, int] = field(default_factory=dict)
    errors_sent: Mapping[int, int] = field(default_factory=dict)
    watchdog_trips: int = 0
    clamped_commands: int = 0
    handler_errors: int = 0
    external_commands_queued: int = 0
    external_commands_taken: int = 0
    reboots: int = 0
    decoder: DecoderStats = field(default_factory=DecoderStats)

    def as_dict(self) -> dict[str, Any]:
        """Plain JSON values; error codes as "0x8000" keys."""
        return {
            "bytes_received": self.bytes_received,
            "bytes_sent": self.bytes_sent,
            "answers": self.answers,
            "requests": dict(self.requests),
            "errors_sent": {f"0x{code:04X}": count for code, count in sorted(self.errors_sent.items())},
            "watchdog_trips": self.watchdog_trips,
            "clamped_commands": self.clamped_commands,
            "handler_errors": self.handler_errors,
            "external_commands_queued": self.external_commands_queued,
            "external_commands_taken": self.external_commands_taken,
            "reboots": self.reboots,
            "decoder": {
                "frames": self.decoder.frames,
                "bytes_discarded": self.decoder.bytes_discarded,
                "checksum_errors": self.decoder.checksum_errors,
                "oversize": self.decoder.oversize,
                "timeouts": self.decoder.timeouts,
                "empty_frames": self.decoder.empty_frames,
                "resyncs": self.decoder.resyncs,
            },
        }


# --- the stack ---------------------------------------------------------------------------------


class _Refuse(Exception):
    """Answer this request with ERROR `code` (internal control flow of the dispatcher)."""

    def __init__(self, code: int) -> None:
        super().__init__(code)
        self.code = code


_A = TypeVar("_A")

_EVENT_ERRORS: Mapping[EventKind, int | None] = {
    EventKind.GARBAGE: ErrorCode.NOT_SYNCED,
    EventKind.CHECKSUM_ERROR: ErrorCode.CHECKSUM,
    EventKind.OVERSIZE: ErrorCode.TOO_LONG,
    EventKind.EMPTY_FRAME: ErrorCode.FORMAT,
    EventKind.TIMEOUT: None,  # a cut frame is not answered: the Core's own timeout covers it
}
_BASE_CMD_HOOKS: Mapping[int, str] = {
    BaseSubcommand.REBOOT: "on_reboot",
    BaseSubcommand.ENTER_DFU: "on_enter_dfu",
}
_VALID_EXTERNAL_COMMANDS = frozenset(int(code) for code in ExternalCommand)


class BaseStack:
    """The protocol side of a base, sans-IO: bytes and time in, answer bytes out.

    Thread-safety: every public method takes `lock` (a re-entrant lock), so a dashboard thread may
    queue commands or read counters while a runner thread feeds bytes. Cost: `receive` is linear
    in the bytes given (see StreamDecoder) plus one application call per request.
    """

    def __init__(
        self,
        app: Base,
        config: BaseConfig | None = None,
        *,
        on_command_line: Callable[[bool], None] | None = None,
    ) -> None:
        """`on_command_line(asserted)` mirrors the nCMD line: called with True when a command
        becomes pending (line pulled low), False when the queue empties."""
        if not isinstance(app, Base):
            raise UsageError(f"the application must be a ctrlbus.base.Base, got {app!r}")
        self.config = config if config is not None else BaseConfig()
        self.app = app
        self.lock = threading.RLock()
        self.health = HealthRegistry(self.lock)
        self._on_command_line = on_command_line
        self._decoder = StreamDecoder(max_frame=self.config.max_frame, timeout=self.config.frame_timeout_s)
        self._long: bool | None = True if self.config.long_answers else None
        self._pending: deque[int] = deque()
        self._now: float | None = None
        self._epoch: float | None = None  # time of power-up (the first time seen, or the last reboot)
        self._last_feed: float | None = None  # last CTRL_BUS frame (or power-up)
        self._watchdog_expired = False  # the current silence has already been acted on
        self._motion_commanded = False  # the last motion command passed on was not zero
        # BASE_CMD hooks to run once their OK answer has been handed over (next receive/tick).
        self._deferred: list[int] = []
        self._resetting = False  # a REBOOT was answered: the rest of this input is not heard
        self._decoder_before_reboots = DecoderStats()
        self._reboots = 0
        self._bytes_received = 0
        self._bytes_sent = 0
        self._answers = 0
        self._requests: Counter[str] = Counter()
        self._errors_sent: Counter[int] = Counter()
        self._watchdog_trips = 0
        self._clamped = 0
        self._handler_errors = 0
        self._queued = 0
        self._taken = 0
        self.last_handler_error: str | None = None
        self._reference_rx = ReferenceReceiver() if self.config.quirks is Quirks.REFERENCE else None
        self._startup_battery_reported = False
        app.attach(self)

    # -- input --------------------------------------------------------------------------------

    def receive(self, data: bytes | bytearray | memoryview, now: float) -> bytes:
        """Take bytes that arrived at time `now`; return the answer bytes to write, in stream
        order (possibly several answers, possibly none). Also does what `tick` does."""
        with self.lock:
            now = self._checked_time(now)
            self._run_deferred(now)
            self._advance(now)
            self._bytes_received += len(data)
            if self._reference_rx is not None:
                return self._receive_as_reference(self._reference_rx, bytes(data), now)
            return self._handle(self._decoder.feed_items(data, now), now)

    def reset_line(self) -> None:
        """A new line: the link has a new peer (a new TCP connection, a re-plugged cable), so the
        half-received frame of the old one is forgotten (its decoder counts are kept). Nothing
        else of the session changes. `serve` calls it when a link's `connections` count grows."""
        with self.lock:
            self._fresh_decoder()

    def _fresh_decoder(self) -> None:
        """A new decoder (nothing buffered); the old one's counts are kept for counters()."""
        self._decoder_before_reboots = _add_stats(self._decoder_before_reboots, self._decoder.stats)
        self._decoder = StreamDecoder(max_frame=self.config.max_frame, timeout=self.config.frame_timeout_s)

    def tick(self, now: float) -> bytes:
        """Let time pass without bytes: application time, motor watchdog, inter-byte timeout.
        Returns answer bytes (a timeout can complete frames buffered behind a false start)."""
        return self.receive(b"", now)

    # -- external commands (POLL_BASE_CMD / POLL_BASE_ANS_CMD) --------------------------------

    def queue_external_command(self, code: int) -> None:
        """Offer `code` (an ExternalCommand) to the Core: POLL_BASE_CMD answers the oldest queued
        command until POLL_BASE_ANS_CMD takes it. UsageError for an unknown code or a full queue
        (MAX_PENDING_COMMANDS)."""
        if isinstance(code, bool) or not isinstance(code, int) or code not in _VALID_EXTERNAL_COMMANDS:
            raise UsageError(f"not an external command code: {code!r} (reference §5, 0x50)")
        with self.lock:
            if len(self._pending) >= MAX_PENDING_COMMANDS:
                raise UsageError(f"the external command queue is full ({MAX_PENDING_COMMANDS} commands)")
            self._pending.append(code)
            self._queued += 1
            if len(self._pending) == 1:
                self._command_line(True)

    @property
    def pending_commands(self) -> tuple[int, ...]:
        """Queued external commands, oldest (the one POLL_BASE_CMD offers) first."""
        with self.lock:
            return tuple(self._pending)

    def clear_external_commands(self) -> None:
        with self.lock:
            if self._pending:
                self._pending.clear()
                self._command_line(False)

    # -- observation --------------------------------------------------------------------------

    def counters(self) -> BaseCounters:
        with self.lock:
            return BaseCounters(
                bytes_received=self._bytes_received,
                bytes_sent=self._bytes_sent,
                answers=self._answers,
                requests=dict(self._requests),
                errors_sent=dict(self._errors_sent),
                watchdog_trips=self._watchdog_trips,
                clamped_commands=self._clamped,
                handler_errors=self._handler_errors,
                external_commands_queued=self._queued,
                external_commands_taken=self._taken,
                decoder=_add_stats(self._decoder_before_reboots, self._decoder.stats),
                reboots=self._reboots,
            )

    @property
    def uptime_s(self) -> float:
        """Seconds since power-up (the first time given) or the last reboot; 0 before any."""
        with self.lock:
            if self._now is None or self._epoch is None:
                return 0.0
            return self._now - self._epoch

    # -- machinery ----------------------------------------------------------------------------

    def _checked_time(self, now: float) -> float:
        if isinstance(now, bool) or not isinstance(now, int | float) or not math.isfinite(now):
            raise UsageError(f"time must be a finite number of seconds, got {now!r}")
        if self._now is None:
            self._epoch = self._last_feed = now
        elif now < self._now:
            now = self._now  # time never runs backwards for the stack
        self._now = now
        return now

    def _run_deferred(self, now: float) -> None:
        """BASE_CMD hooks whose OK answer the caller has had since the previous call."""
        actions, self._deferred = self._deferred, []
        for subcommand in actions:
            if subcommand == BaseSubcommand.REBOOT:
                # What a rebooted base forgets: pending commands, health, the watchdog's state,
                # its uptime. The counters belong to whoever observes the base and survive.
                self.clear_external_commands()
                self.health.clear_all()
                self._motion_commanded = self._watchdog_expired = False
                self._epoch = self._last_feed = now
                self._reboots += 1
                self._call_app(self.app.on_reboot)
            else:
                self._call_app(self.app.on_enter_dfu)

    def _advance(self, now: float) -> None:
        """Bring the watchdog and the application to `now`."""
        watchdog = self.config.watchdog_s
        if watchdog is not None and not self._watchdog_expired and self._last_feed is not None:
            deadline = self._last_feed + watchdog
            if now > deadline:
                # Act at the deadline itself, not at whenever the caller ticked.
                self._call_app(self.app.advance, deadline)
                self._expire_watchdog()
        self._call_app(self.app.advance, now)

    def _expire_watchdog(self) -> None:
        """No CTRL_BUS frame for too long: stop the motors, once per silence; if they were
        commanded to move, it is a trip (counted, and a health warning for the Core)."""
        self._watchdog_expired = True
        moving = self._motion_commanded
        self._motion_commanded = False
        self._call_app(self.app.stop_motors)
        if moving:
            self._watchdog_trips += 1
            try:
                self.health.add(WATCHDOG_TRIPPED_CODE, WATCHDOG_TRIPPED_MESSAGE)
            except UsageError as exc:  # a registry the application filled up: still stopped
                _log.warning("motor watchdog tripped, but it cannot be registered: %s", exc)

    def _call_app(self, method: Callable[..., object], *args: Any) -> bool:
        """Call the application outside any request (time, watchdog): failures are logged and
        counted, never raised. Returns whether it succeeded."""
        try:
            method(*args)
        except NotImplementedError:
            return False
        except Exception as exc:
            self._note_handler_error(getattr(method, "__name__", repr(method)), exc)
            return False
        return True

    def _note_handler_error(self, name: str, exc: BaseException) -> None:
        self.last_handler_error = f"{name}: {type(exc).__name__}: {exc}"
        if not isinstance(exc, CtrlbusError):
            self._handler_errors += 1
            _log.error("base handler %s failed", name, exc_info=exc)

    def _command_line(self, asserted: bool) -> None:
        if self._on_command_line is not None:
            self._call_app(self._on_command_line, asserted)

    def _handle(self, items: list[Frame | DecoderEvent], now: float) -> bytes:
        out = bytearray()
        for item in items:
            if isinstance(item, Frame):
                self._handle_frame(item, now, out)
                if self._resetting:
                    break  # a REBOOT was answered: a resetting base hears nothing more of this input
            else:
                code = _EVENT_ERRORS[item.kind]
                if code == ErrorCode.CHECKSUM and self.config.reference_checksum_code:
                    code = ErrorCode.REFERENCE_CHECKSUM
                if code is not None:
                    self._send_error(code, out)
        if self._resetting:
            # Nothing buffered survives the reset either: a fresh decoder (its counts are kept).
            self._resetting = False
            self._fresh_decoder()
        self._bytes_sent += len(out)
        return bytes(out)

    def _receive_as_reference(self, receiver: ReferenceReceiver, data: bytes, now: float) -> bytes:
        """Quirks mode: the reference's receiver decides what is executed and reported."""
        startup = self._epoch is not None and now - self._epoch < STARTUP_BATTERY_S
        if startup and REFERENCE_LOW_BATTERY_CODE not in self.health:
            self.health.add(REFERENCE_LOW_BATTERY_CODE, REFERENCE_LOW_BATTERY_MESSAGE)
        elif not startup and self._startup_battery_reported:
            self.health.clear(REFERENCE_LOW_BATTERY_CODE)
        self._startup_battery_reported = startup

        def serve(item: Frame | int | bytes) -> bytes:
            answer = bytearray()
            if isinstance(item, int):
                self._send_error(item, answer)
            elif isinstance(item, bytes):  # SYNC/ECHO, sent back from the receiver's buffer
                self._requests["SYNC" if item[2 + (item[0] == FLAG_LONG)] == Cmd.SYNC else "ECHO"] += 1
                self._send(item, answer)
            else:
                self._handle_frame(item, now, answer)
            return bytes(answer)

        out = receiver.feed(data, now, serve)
        if self._resetting:  # a REBOOT was answered: the receiver starts over, silent again
            self._resetting = False
            receiver.power_on(now)
        self._bytes_sent += len(out)
        return out

    def _send(self, frame_bytes: bytes, out: bytearray) -> None:
        out += frame_bytes
        self._answers += 1

    def _send_error(self, code: int, out: bytearray) -> None:
        code = int(code)
        self._errors_sent[code] += 1
        self._send(answer_frame(ErrorAnswer(code), long=self._long), out)

    def _handle_frame(self, frame: Frame, now: float, out: bytearray) -> None:
        if frame.cmd in (Cmd.SYNC, Cmd.ECHO):
            # Verbatim copy of the request; it does not feed the motor watchdog.
            self._requests["SYNC" if frame.cmd == Cmd.SYNC else "ECHO"] += 1
            self._send(frame.raw, out)
            return
        if frame.cmd == Cmd.CTRL_BUS:
            # Any CTRL_BUS frame that passed its checksum shows that the Core is alive.
            self._last_feed = now
            self._watchdog_expired = False
        try:
            request = decode_request(frame.cmd, frame.payload)
        except (MessageFormatError, UnsupportedMessageError) as exc:
            self._send_error(exc.error_code, out)
            return
        self._requests[request.NAME] += 1
        try:
            answer = self._dispatch(request, now)
            encoded = answer_frame(answer, long=self._long)
        except _Refuse as refusal:
            self._send_error(refusal.code, out)
            return
        except NotImplementedError:
            self._send_error(ErrorCode.UNSUPPORTED, out)
            return
        except Exception as exc:
            self._note_handler_error(request.NAME, exc)
            self._send_error(ErrorCode.OPERATION, out)
            return
        self._send(encoded, out)

    def _dispatch(self, request: RequestMessage, now: float) -> AnswerMessage:
        app = self.app
        profile = self.config.profile
        match request:
            case ConnectBase():
                # A protocol version other than 1 never gets here: the codec refuses it (0x8000).
                info = _expect(app.connect_info(), ConnectBaseAnswer)
                if profile is Profile.SDK2020:
                    if info.firmware_version_suffix is None:
                        info = replace(info, firmware_version_suffix="")
                elif info.firmware_version_suffix is not None:
                    info = replace(info, firmware_version_suffix=None)
                return info
            case GetBaseConf():
                return _expect(app.base_config(), GetBaseConfAnswer)
            case GetBaseConfAdv():
                return GetBaseConfAdvAnswer(_expect(app.binary_config(), bytes))
            case GetBaseStatus():
                status = _expect(app.status(), GetBaseStatusAnswer)
                if self._startup_battery_reported:
                    status = replace(status, battery_percent=0)  # quirks: no battery reading yet
                return status
            case GetBaseMotorData():
                return _expect(app.motor_data(), GetBaseMotorDataAnswer)
            case GetBaseSensorData():
                return _expect(app.sensor_data(), GetBaseSensorDataAnswer)
            case GetBaseBumperData():
                bumpers = _expect(app.bumper_data(), GetBaseBumperDataAnswer)
                if profile is Profile.SDK2020 and bumpers.payload_size != 4:
                    bumpers = replace(bumpers, payload_size=4)  # same value: the Core zero-pads
                return bumpers
            case GetChargerData():
                # Only data type 0 (beacons) gets here: the codec refuses the others (0x8000).
                return _expect(app.charger_data(), GetChargerDataAnswer)
            case GetAuxiliaryAnchor():
                raise _Refuse(ErrorCode.UNSUPPORTED)  # no layout is published (reference §5)
            case SetBaseMotor():
                left, right, clamped = self.config.limits.limit_wheels(request.left_mm_s, request.right_mm_s)
                self._note_motion(clamped, left != 0 or right != 0)
                app.set_wheel_speeds(left, right)
                return EmptyAnswer()
            case SetVAndGetDeadreckon():
                vx, omega, clamped = self.config.limits.limit_velocity(request.vx_mps, request.omega_radps)
                vy = request.vy_mps
                self._note_motion(clamped, vx != 0 or vy != 0 or omega != 0)
                motion = _expect(app.set_velocity(vx, vy, omega), SetVAndGetDeadreckonAnswer)
                if profile is Profile.REFERENCE:
                    return replace(motion, timestamp_ms=None)
                if motion.timestamp_ms is None:
                    uptime_ms = int((now - (self._epoch or 0.0)) * 1000.0) & 0xFFFF_FFFF
                    motion = replace(motion, timestamp_ms=uptime_ms)
                return motion
            case PollBaseCmd():
                if self._pending:
                    return PollBaseCmdAnswer.pending(self._pending[0])
                if profile is Profile.SDK2020:
                    return PollBaseCmdAnswer(None, 2, 0)  # FF 00: SDP Mini's "nothing pending"
                return PollBaseCmdAnswer()  # OK 0, as base_ref v4
            case PollBaseAnsCmd():
                if self._pending:
                    self._pending.popleft()
                    self._taken += 1
                    if not self._pending:
                        self._command_line(False)
                return EmptyAnswer()
            case SendEvent(event=event):
                app.on_event(event)
                return EmptyAnswer()
            case HealthGetHealth():
                return HealthGetHealthAnswer(self.health.flags, len(self.health))
            case HealthGetError(index=index):
                entries = self.health.entries
                if index >= len(entries):
                    raise _Refuse(ErrorCode.OPERATION)
                return HealthGetErrorAnswer(entries[index].code, entries[index].message)
            case HealthClrError(error_code=code):
                if not self.health.clear(code):
                    raise _Refuse(ErrorCode.OPERATION)
                return EmptyAnswer()
            case BaseCommand(subcommand=subcommand):
                hook = _BASE_CMD_HOOKS.get(subcommand)
                if hook is None or not app.implements(hook):
                    raise _Refuse(ErrorCode.UNSUPPORTED)
                # The hook runs after the answer has left (next receive/tick), as on a real base.
                self._deferred.append(subcommand)
                self._resetting = subcommand == BaseSubcommand.REBOOT
                return EmptyAnswer()
        raise _Refuse(ErrorCode.UNSUPPORTED)  # a request class the dispatcher does not know

    def _note_motion(self, clamped: bool, moving: bool) -> None:
        if clamped:
            self._clamped += 1
        self._motion_commanded = moving


def _add_stats(first: DecoderStats, second: DecoderStats) -> DecoderStats:
    return DecoderStats(
        *(getattr(first, item.name) + getattr(second, item.name) for item in dataclass_fields(DecoderStats))
    )


def _expect(value: object, kind: type[_A]) -> _A:
    if not isinstance(value, kind):
        raise TypeError(f"the base returned {type(value).__name__}, expected {kind.__name__}")
    return value


# --- the real-time runner ----------------------------------------------------------------------


def serve(
    stack: BaseStack,
    link: Link,
    *,
    clock: Callable[[], float] = time.monotonic,
    stop_event: threading.Event | None = None,
    poll_s: float = DEFAULT_POLL_S,
) -> None:
    """Serve `stack` on `link` in real time until `stop_event` is set (forever without one).

    Reads with a `poll_s` timeout, passes the bytes (or a tick) with `clock()` to the stack, and
    writes the answers. A LinkError from the link ends it (raised to the caller). The link is
    not closed here: its owner closes it.
    """
    if not (math.isfinite(poll_s) and poll_s > 0):
        raise UsageError(f"poll_s must be a finite number > 0, got {poll_s!r}")
    # A link that counts its peers (a TCP listener) starts a new line with each new one.
    connections = getattr(link, "connections", None)
    while stop_event is None or not stop_event.is_set():
        data = link.read(poll_s)
        if connections is not None and link.connections != connections:  # type: ignore[attr-defined]
            connections = link.connections  # type: ignore[attr-defined]
            stack.reset_line()
        answer = stack.receive(data, clock())
        if answer:
            link.write(answer)


class BaseRunner:
    """`serve` in a daemon thread: start(), stop(), and `failure` if the link failed.

    with BaseRunner(stack, link) as runner:
        ...  # the base answers until the block ends
    """

    def __init__(
        self,
        stack: BaseStack,
        link: Link,
        *,
        clock: Callable[[], float] = time.monotonic,
        poll_s: float = DEFAULT_POLL_S,
        name: str = "ctrlbus-base",
    ) -> None:
        self.stack = stack
        self.link = link
        self._clock = clock
        self._poll_s = poll_s
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)
        self.failure: BaseException | None = None

    def _run(self) -> None:
        try:
            serve(self.stack, self.link, clock=self._clock, stop_event=self._stop, poll_s=self._poll_s)
        except Exception as exc:  # reported through `failure`, never lost in a thread
            self.failure = exc
            if not isinstance(exc, CtrlbusError):
                _log.error("base runner on %s failed", self.link.name, exc_info=exc)

    def start(self) -> Self:
        self._thread.start()
        return self

    @property
    def running(self) -> bool:
        return self._thread.is_alive()

    def stop(self, timeout: float = 5.0) -> None:
        """Ask the thread to stop and wait for it (at most `timeout` s; it stops within about
        one poll period). Idempotent. The link stays open."""
        self._stop.set()
        if self._thread.is_alive() and self._thread is not threading.current_thread():
            self._thread.join(timeout)

    def wait(self, timeout: float | None = None) -> bool:
        """Wait until the runner ends (stopped or failed); returns whether it has."""
        self._thread.join(timeout)
        return not self._thread.is_alive()

    def __enter__(self) -> Self:
        return self.start()

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.stop()
