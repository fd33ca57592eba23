# SPDX-License-Identifier: MIT
"""A scriptable sans-IO base for the Core emulator's tests (not a test module).

`FakeBase` answers every request with the message codec, and has a knob for each answer variant
a master must accept and each fault the Core must survive: 28/39-byte CONNECT, a blob or ERROR
0x8000 for GET_BASE_CONF_ADV, 13/17-byte deadreckon, 1..4-byte bumpers, the empty / 0xFF / pending
POLL forms, ERROR answers per request, silence. It records every request it decoded, with its
time. It moves an ideal robot from the velocity commands (no noise), so the Core's pose can be
compared with it.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field

from ctrlbus.frame import StreamDecoder, encode
from ctrlbus.kinematics import (
    DeadreckonDelta,
    Pose,
    deadreckon_from_wheel_travel,
    integrate_pose,
    relative_pose,
)
from ctrlbus.messages import (
    AnswerMessage,
    Cmd,
    ConnectBase,
    ConnectBaseAnswer,
    EmptyAnswer,
    ErrorAnswer,
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
    HealthGetError,
    HealthGetErrorAnswer,
    HealthGetHealth,
    HealthGetHealthAnswer,
    PollBaseAnsCmd,
    PollBaseCmd,
    PollBaseCmdAnswer,
    Position,
    RequestMessage,
    SendEvent,
    SetVAndGetDeadreckon,
    SetVAndGetDeadreckonAnswer,
    answer_frame,
    decode_request,
    from_q16,
)

WHEEL_TRACK_MM = 236.0


def default_conf() -> GetBaseConfAnswer:
    return GetBaseConfAnswer.from_si(
        base_type=0,
        base_radius_mm=170.0,
        sensors=[Position.from_si(165, 0, 120, 0), Position.from_si(113, 113, 120, 45)],
        bumpers=[Position.from_si(120, 120, 40, 45), Position.from_si(120, -120, 40, 315)],
    )


@dataclass
class FakeBase:
    connect_suffix: str | None = None  # None: the 28-byte CONNECT answer; text: the 39-byte one
    blob: bytes | None = None  # None: GET_BASE_CONF_ADV answered ERROR 0x8000
    conf: GetBaseConfAnswer = field(default_factory=default_conf)
    deadreckon_timestamp: bool = False  # 17-byte deadreckon answers
    bumper_size: int = 4
    bumper_bitmap: int = 0xFFFFFFFF
    poll_nothing_form: str = "empty"  # "empty" or "ff"
    battery_percent: int = 80
    power_status: int = 0
    health: list[tuple[int, str]] = field(default_factory=list)
    probes: tuple[int, ...] = (0, 0, 0)
    distances_mm: tuple[float, ...] = (1000.0, 2000.0)
    long_answers: bool = True
    errors: dict[str, int] = field(default_factory=dict)  # request name -> ERROR code to answer
    error_once: dict[str, int] = field(default_factory=dict)  # the same, for the next one only
    prefix_once: dict[str, bytes] = field(default_factory=dict)  # bytes sent before the next answer
    raw_ok: dict[str, bytes] = field(default_factory=dict)  # request name -> OK payload sent as is
    silent: bool = False  # hear everything, answer nothing
    # Filled in as it runs:
    requests: list[tuple[float, RequestMessage]] = field(default_factory=list)
    syncs: list[tuple[float, int]] = field(default_factory=list)  # (time, whole frame size)
    commands: deque[int] = field(default_factory=deque)
    pose: Pose = field(default_factory=lambda: Pose(0.0, 0.0, 0.0))
    velocity: tuple[float, float] = (0.0, 0.0)
    ticks: int = 0

    def __post_init__(self) -> None:
        self._decoder = StreamDecoder(max_frame=512, timeout=0.01)
        self._last_time: float | None = None
        self._reported = Pose(0.0, 0.0, 0.0)
        self._first_deadreckon = True

    # -- sans-IO ------------------------------------------------------------------------------

    def receive(self, data: bytes, now: float) -> bytes:
        self._move(now)
        out = bytearray()
        for frame in self._decoder.feed(data, now):
            if frame.cmd in (Cmd.SYNC, Cmd.ECHO):
                self.syncs.append((now, frame.size))
                if not self.silent:
                    out += frame.raw
                continue
            request = decode_request(frame.cmd, frame.payload)
            self.requests.append((now, request))
            if self.silent:
                continue
            out += self.prefix_once.pop(request.NAME, b"")
            long = True if self.long_answers else None
            if request.NAME in self.raw_ok:
                out += encode(0x02, self.raw_ok[request.NAME], long=long)
                continue
            code = self.error_once.pop(request.NAME, None)
            if code is None:
                code = self.errors.get(request.NAME)
            answer: AnswerMessage = ErrorAnswer(code) if code is not None else self._answer(request)
            out += answer_frame(answer, long=long)
        return bytes(out)

    def tick(self, now: float) -> bytes:
        self.ticks += 1
        self._move(now)
        return b""

    # -- helpers for the tests ----------------------------------------------------------------

    def names(self) -> list[str]:
        return [describe(request) for _, request in self.requests]

    def requests_named(self, name: str) -> list[RequestMessage]:
        return [request for _, request in self.requests if name == request.NAME]

    # -- the robot ----------------------------------------------------------------------------

    def _move(self, now: float) -> None:
        if self._last_time is not None and now > self._last_time:
            dt = now - self._last_time
            vx, omega = self.velocity
            left = (vx * 1000.0 - omega * WHEEL_TRACK_MM / 2) * dt
            right = (vx * 1000.0 + omega * WHEEL_TRACK_MM / 2) * dt
            self.pose = integrate_pose(self.pose, deadreckon_from_wheel_travel(left, right, WHEEL_TRACK_MM))
        self._last_time = now if self._last_time is None else max(self._last_time, now)

    def _answer(self, request: RequestMessage) -> AnswerMessage:
        if isinstance(request, ConnectBase):
            return ConnectBaseAnswer("fake base", 0x0114, 3, (1, 2, 3), self.connect_suffix)
        if isinstance(request, GetBaseConfAdv):
            if self.blob is None:
                return ErrorAnswer(0x8000)
            return GetBaseConfAdvAnswer(self.blob)
        if isinstance(request, GetBaseConf):
            return self.conf
        if isinstance(request, GetBaseStatus):
            return GetBaseStatusAnswer(self.battery_percent, self.power_status)
        if isinstance(request, GetBaseMotorData):
            return GetBaseMotorDataAnswer(0, 0, 0)
        if isinstance(request, GetBaseSensorData):
            return GetBaseSensorDataAnswer.from_si(list(self.distances_mm))
        if isinstance(request, GetBaseBumperData):
            return GetBaseBumperDataAnswer(
                self.bumper_bitmap & ((1 << 8 * self.bumper_size) - 1), self.bumper_size
            )
        if isinstance(request, GetChargerData):
            return GetChargerDataAnswer(3, len(self.probes), self.probes)
        if isinstance(request, SetVAndGetDeadreckon):
            return self._deadreckon(request)
        if isinstance(request, PollBaseCmd):
            if self.commands:
                return PollBaseCmdAnswer.pending(self.commands[0])
            if self.poll_nothing_form == "ff":
                return PollBaseCmdAnswer(None, 2, 0x5A)
            return PollBaseCmdAnswer()
        if isinstance(request, PollBaseAnsCmd):
            if self.commands:
                self.commands.popleft()
            return EmptyAnswer()
        if isinstance(request, HealthGetHealth):
            flags = 0
            for code, _ in self.health:
                flags |= {1: 1, 2: 2, 4: 4}.get(code >> 24, 0)
            return HealthGetHealthAnswer(flags, len(self.health))
        if isinstance(request, HealthGetError):
            if request.index >= len(self.health):
                return ErrorAnswer(0x8002)
            code, message = self.health[request.index]
            return HealthGetErrorAnswer(code, message)
        if isinstance(request, SendEvent):
            return EmptyAnswer()
        return ErrorAnswer(0x8000)

    def _deadreckon(self, request: SetVAndGetDeadreckon) -> SetVAndGetDeadreckonAnswer:
        timestamp = int((self._last_time or 0.0) * 1000) if self.deadreckon_timestamp else None
        if self._first_deadreckon:
            self._first_deadreckon = False
            self._reported = self.pose
            answer = SetVAndGetDeadreckonAnswer(0, 0, 0, 0, timestamp)
        else:
            delta = relative_pose(self._reported, self.pose)
            answer = SetVAndGetDeadreckonAnswer.from_si(
                delta.dx_mm, delta.dy_mm, delta.dtheta_deg, 0, timestamp
            )
            self._reported = integrate_pose(
                self._reported,
                DeadreckonDelta(from_q16(answer.dx_mm_q16), from_q16(answer.dy_mm_q16), answer.dtheta_deg),
            )
        self.velocity = (request.vx_mps, request.omega_radps)
        return answer


def describe(request: RequestMessage) -> str:
    """Short names for sequence checks: CONNECT_BASE, SEND_EVENT:0x63, SYNC:512, ..."""
    if isinstance(request, SendEvent):
        return f"SEND_EVENT:0x{request.event:02X}"
    return request.NAME


def sync_flush_frame() -> bytes:
    return encode(0x00, bytes(507), long=True)
