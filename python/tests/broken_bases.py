# SPDX-License-Identifier: MIT
"""Deliberately broken bases for test_checker.py: each breaks exactly one rule of
docs/protocol.md, and names the conformance check that must catch it.

Every one is the real base framework (ctrlbus.base.BaseStack serving the simulated robot,
ctrlbus.sim.base.SimulatedBase) with one small change, made in one of four ways:

- a SimulatedBase subclass whose application answers one request wrongly;
- a RewritingStack: a BaseStack that may change the bytes it receives before its own decoder
  sees them, or the answer bytes it returns (it watches the request frames with a decoder of its
  own to know what it is answering);
- a BaseConfig (the stack without a watchdog);
- a link wrapper that delays every answer (DelayedLink).

Not a test module itself.
"""

from __future__ import annotations

import math
import struct
import threading
import time
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

from ctrlbus import binconf
from ctrlbus.base import BaseConfig, BaseStack
from ctrlbus.frame import Frame, StreamDecoder, checksum, encode
from ctrlbus.link import Link
from ctrlbus.messages import (
    Cmd,
    ConnectBaseAnswer,
    Event,
    ExternalCommand,
    GetBaseConfAnswer,
    GetBaseStatusAnswer,
    Position,
    Request,
    Response,
    SetVAndGetDeadreckonAnswer,
    to_q16,
)
from ctrlbus.sim.base import SimulatedBase
from ctrlbus.sim.world import World

SEED = 7  # the simulated robot's noise seed: every run sees the same world


def simulated_base() -> SimulatedBase:
    return SimulatedBase(World(seed=SEED))


def frames_of(data: bytes) -> list[Frame]:
    """The frames of a whole-frame byte string (a stack's answer bytes)."""
    return StreamDecoder(timeout=0).feed(data)


def error_code(frame: Frame) -> int | None:
    if frame.cmd == Response.ERROR and len(frame.payload) == 2:
        return int.from_bytes(frame.payload, "little")
    return None


def error_frame(code: int) -> bytes:
    return encode(Response.ERROR, code.to_bytes(2, "little"), long=True)


# --- the ways of breaking a base ---------------------------------------------------------------


class RewritingStack(BaseStack):
    """A BaseStack whose input and output pass through `change_input` / `change_output`, which
    see the request frames of the input chunk (as the stack's own decoder would find them)."""

    def __init__(self, app: SimulatedBase, config: BaseConfig | None = None) -> None:
        super().__init__(app, config)
        self._spy = StreamDecoder(timeout=0.1)

    def receive(self, data: bytes | bytearray | memoryview, now: float) -> bytes:
        data = bytes(data)
        requests = self._spy.feed(data, now)
        answer = super().receive(self.change_input(data, requests, now), now)
        return self.change_output(answer, requests, now)

    def change_input(self, data: bytes, requests: list[Frame], now: float) -> bytes:
        return data

    def change_output(self, answer: bytes, requests: list[Frame], now: float) -> bytes:
        return answer


class CorruptChecksums(RewritingStack):
    """Every answer frame goes out with its checksum inverted."""

    def change_output(self, answer: bytes, requests: list[Frame], now: float) -> bytes:
        return b"".join(frame.raw[:-1] + bytes((frame.raw[-1] ^ 0xFF,)) for frame in frames_of(answer))


class GarbageAfterAnswers(RewritingStack):
    """Two stray bytes follow every answer."""

    def change_output(self, answer: bytes, requests: list[Frame], now: float) -> bytes:
        return answer + b"\xaa\x55" if answer else answer


class RewriteErrorCode(RewritingStack):
    """ERROR `old` answers become ERROR `new` (or vanish, when `new` is None), in the answers to
    input chunks that `applies` to."""

    def __init__(
        self, old: int, new: int | None, applies: Callable[[list[Frame]], bool] = lambda requests: True
    ) -> None:
        super().__init__(simulated_base())
        self.old, self.new, self.applies = old, new, applies

    def change_output(self, answer: bytes, requests: list[Frame], now: float) -> bytes:
        if not self.applies(requests):
            return answer
        out = b""
        for frame in frames_of(answer):
            if error_code(frame) != self.old:
                out += frame.raw
            elif self.new is not None:
                out += error_frame(self.new)
        return out


def _any(requests: Sequence[Frame], test: Callable[[Frame], bool]) -> bool:
    return any(test(frame) for frame in requests)


def _unknown_cmd(frame: Frame) -> bool:
    return frame.cmd not in tuple(Cmd)


def _unknown_request(frame: Frame) -> bool:
    return frame.cmd == Cmd.CTRL_BUS and bool(frame.payload) and frame.payload[0] not in tuple(Request)


def _unknown_health_sub(frame: Frame) -> bool:
    payload = frame.payload
    return (
        frame.cmd == Cmd.CTRL_BUS and payload[:1] == bytes((Request.HEALTH_MGMT,)) and payload[1:2] > b"\x03"
    )


class IgnoreLongRequests(RewritingStack):
    """Long (0x50) CTRL_BUS frames are dropped unread (SYNC and ECHO still work in both types)."""

    def change_input(self, data: bytes, requests: list[Frame], now: float) -> bytes:
        for frame in requests:
            if frame.long and frame.cmd == Cmd.CTRL_BUS:
                data = data.replace(frame.raw, b"", 1)
        return data


class SyncWithoutFiller(RewritingStack):
    """SYNC is answered with an empty SYNC, whatever filler the request carried."""

    def change_output(self, answer: bytes, requests: list[Frame], now: float) -> bytes:
        return b"".join(
            encode(Cmd.SYNC, b"") if frame.cmd == Cmd.SYNC else frame.raw for frame in frames_of(answer)
        )


class EchoInStandardFrames(RewritingStack):
    """ECHO is answered with the same data, but in a standard frame whenever it fits (the answer
    is rebuilt instead of copied, so a long request loses its flag)."""

    def change_output(self, answer: bytes, requests: list[Frame], now: float) -> bytes:
        return b"".join(
            encode(Cmd.ECHO, frame.payload) if frame.cmd == Cmd.ECHO else frame.raw
            for frame in frames_of(answer)
        )


class AcceptsAnyConnectVersion(RewritingStack):
    """CONNECT_BASE is answered OK whatever protocol version it asks for."""

    def change_input(self, data: bytes, requests: list[Frame], now: float) -> bytes:
        for frame in requests:
            payload = frame.payload
            if frame.cmd == Cmd.CTRL_BUS and len(payload) == 2 and payload[0] == Request.CONNECT_BASE:
                data = data.replace(
                    frame.raw, encode(Cmd.CTRL_BUS, payload[:1] + b"\x01", long=frame.long), 1
                )
        return data


class DeafAfterGarbage(RewritingStack):
    """After reporting garbage (ERROR 0x0010) it ignores all input for DEAF_S seconds: a naive
    "resynchronise by waiting" that loses the requests behind the garbage."""

    DEAF_S = 3.0

    def __init__(self) -> None:
        super().__init__(simulated_base())
        self._deaf_until = -1.0

    def change_input(self, data: bytes, requests: list[Frame], now: float) -> bytes:
        return b"" if now < self._deaf_until else data

    def change_output(self, answer: bytes, requests: list[Frame], now: float) -> bytes:
        if any(error_code(frame) == 0x0010 for frame in frames_of(answer)):
            self._deaf_until = now + self.DEAF_S
        return answer


class DropsBehindGarbage(RewritingStack):
    """A request that arrives right behind garbage is dropped without a word: the garbage is
    reported (ERROR 0x0010), the request is neither answered nor reported dropped; sent again, it
    is answered. The reference does this too after some garbage lengths (3-6, 10-13, 16 bytes in
    one write: protocol.md §8.5): a Core finds out at its request timeout and resends (a warning)."""

    def change_input(self, data: bytes, requests: list[Frame], now: float) -> bytes:
        at = data.find(requests[0].raw) if requests else -1
        return data[:at] if at > 0 else data  # garbage in front of a request: the garbage only


class IgnoresTheResendAfterGarbage(DropsBehindGarbage):
    """As DropsBehindGarbage, and the next `resends` requests after such a drop are dropped too:
    a Core's resend is never answered (a failure; the reference answers it)."""

    def __init__(self, app: SimulatedBase, resends: int = 3) -> None:
        super().__init__(app)
        self.resends = resends
        self._to_drop = 0

    def change_input(self, data: bytes, requests: list[Frame], now: float) -> bytes:
        kept = super().change_input(data, requests, now)
        if kept != data:
            self._to_drop = self.resends
            return kept
        if requests and self._to_drop > 0:
            self._to_drop -= 1
            return b""
        return data


class LineFaultsAfterChecksumErrors(RewritingStack):
    """The first `times` requests after a checksum-error report are not executed but answered
    ERROR 0x0090 (not synchronised + a frame was ready): what the reference does to a request
    that arrives while its report is still being sent. A Core resends such a request; a base
    that answers it when sent again works with a Core (a warning), one that never does fails."""

    def __init__(self, times: int) -> None:
        super().__init__(simulated_base())
        self.times = times
        self._to_refuse = 0
        self._refusing = False

    def change_input(self, data: bytes, requests: list[Frame], now: float) -> bytes:
        self._refusing = bool(requests) and self._to_refuse > 0
        return b"" if self._refusing else data

    def change_output(self, answer: bytes, requests: list[Frame], now: float) -> bytes:
        if self._refusing:
            self._to_refuse -= 1
            return error_frame(0x0090)
        if any(error_code(frame) in (0x0040, 0x00C0) for frame in frames_of(answer)):
            self._to_refuse = self.times
        return answer


def complete_blob(robot_size_m: float) -> bytes:
    """The example blob with the simulated base's two IR channels listed too (as plain-string
    type "ir"), so that it describes every distance sensor: only `robot_size_m` can disagree."""
    tree = binconf.example_config()
    base = tree["base"]
    assert isinstance(base, dict) and isinstance(base["sensors"], list)
    base["robot_size"] = robot_size_m
    for channel, y, yaw in ((3, 0.16, math.pi / 2), (4, -0.16, -math.pi / 2)):
        pose: dict[str, binconf.JsonValue] = {"x": 0.0, "y": y, "z": 0.06, "yaw": yaw}
        base["sensors"].append({"type": "ir", "id": {"u8": channel}, "installation_pose": pose})
    return binconf.encode(tree)


class BlobRobotSizeIsTheRadius(SimulatedBase):
    """Serves a 0x21 blob whose robot_size is the radius (0.17), not the diameter: a Core that
    reads the blob believes the robot is half its size (§12.4 [conf-units])."""

    def __init__(self) -> None:
        super().__init__(World(seed=SEED), binary_config=complete_blob(0.17))


class UnlistedDistanceChannels(SimulatedBase):
    """GET_BASE_CONF lists only the first two distance sensors while all six report readings:
    a Core has no position for channels 2-5 and ignores them (§12.4 [conf-sensor-list])."""

    def base_config(self) -> GetBaseConfAnswer:
        conf = super().base_config()
        sensors = tuple(position if slot < 2 else Position() for slot, position in enumerate(conf.sensors))
        return replace(conf, sensor_num=2, sensors=sensors)


class ExecutesBadChecksums(RewritingStack):
    """Motion commands are carried out as soon as their bytes are in, before the checksum is
    looked at: a SET_BASE_MOTOR or SET_V_AND_GET_DEADRECKON that fails its checksum still moves
    the wheels (and is still answered ERROR 0x0040)."""

    MOTION_HEADERS = (bytes.fromhex("10 12 F8 40"), bytes.fromhex("10 0E F8 41"))

    def change_input(self, data: bytes, requests: list[Frame], now: float) -> bytes:
        for header in self.MOTION_HEADERS:
            start = data.find(header)
            size = 2 + header[1] + 1  # flag and LEN, then LEN bytes (CMD and payload), checksum
            if start < 0 or len(data) < start + size:
                continue
            frame = data[start : start + size]
            if checksum(frame[:-1]) == frame[-1]:
                continue  # a valid frame: the stack executes it anyway
            with self.lock:
                if header[3] == Request.SET_BASE_MOTOR:
                    left, right, _, _ = struct.unpack_from("<4i", frame, 4)  # after flag, LEN, CMD, code
                    self.app.set_wheel_speeds(float(left), float(right))
                else:
                    vx, vy, omega = struct.unpack_from("<3i", frame, 4)
                    self.app.set_velocity(vx / 65536, vy / 65536, omega / 65536)
        return data


class AckKeepsCommand(BaseStack):
    """POLL_BASE_ANS_CMD answers OK but the command stays pending (it is queued again)."""

    def receive(self, data: bytes | bytearray | memoryview, now: float) -> bytes:
        before = self.pending_commands
        answer = super().receive(data, now)
        taken = len(before) - len(self.pending_commands)
        for code in before[: max(0, taken)]:
            self.queue_external_command(code)
        return answer


class _ConnectAnswerTooLong(ConnectBaseAnswer):
    def _pack(self) -> bytes:
        return super()._pack() + b"\0\0"  # 30 bytes: neither the 28- nor the 39-byte form


class LongConnectAnswer(SimulatedBase):
    def connect_info(self) -> ConnectBaseAnswer:
        info = super().connect_info()
        return _ConnectAnswerTooLong(info.model, info.firmware_version, info.hardware_version, info.serial)


class NegativeSensorAngle(SimulatedBase):
    """Sensor 2 faces -40° instead of 320° (a signed angle where 0..360 is required)."""

    def base_config(self) -> GetBaseConfAnswer:
        conf = super().base_config()
        sensors = list(conf.sensors)
        sensors[2] = replace(sensors[2], angle_deg_q8=(-40 * 256) & 0xFFFF_FFFF)
        return replace(conf, sensors=tuple(sensors))


class DeadreckonFromCommand(SimulatedBase):
    """Reports the commanded turn as its deadreckon (omega times the time since the last call)
    instead of what the wheels did: after the watchdog stops the wheels, the Core's pose keeps
    turning (§9.1)."""

    def __init__(self) -> None:
        super().__init__(World(seed=SEED))
        self._omega_radps = 0.0
        self._since_s: float | None = None

    def set_velocity(self, vx_mps: float, vy_mps: float, omega_radps: float) -> SetVAndGetDeadreckonAnswer:
        measured = super().set_velocity(vx_mps, vy_mps, omega_radps)
        now = self.world.time_s
        elapsed = 0.0 if self._since_s is None else now - self._since_s
        self._since_s, commanded, self._omega_radps = now, self._omega_radps, omega_radps
        return replace(measured, dtheta_deg_q16=to_q16(math.degrees(commanded * elapsed)))


class _StatusWithExtraByte(GetBaseStatusAnswer):
    def _pack(self) -> bytes:
        return super()._pack() + b"\0"  # 3 bytes where the layout has 2


class StatusTooLong(SimulatedBase):
    def status(self) -> GetBaseStatusAnswer:
        status = super().status()
        return _StatusWithExtraByte(status.battery_percent, status.power_status)


class RefusesUnknownEvents(SimulatedBase):
    """SEND_EVENT with an event code it does not know is answered ERROR 0x8000 (it must be OK)."""

    def on_event(self, event: int) -> None:
        if event not in tuple(Event):
            raise NotImplementedError
        super().on_event(event)


# Payload sizes (request code included) of the control-bus requests with a fixed layout; HEALTH
# sub-commands by (0x90, sub).
_REQUEST_SIZES: dict[int | tuple[int, int], int] = {
    **{code: 1 for code in (0x20, 0x21, 0x30, 0x31, 0x32, 0x33, 0x35, 0x50, 0x5F)},
    0x10: 2,
    0x34: 2,
    0x40: 17,
    0x41: 13,
    0x60: 2,
    (0x90, 0x01): 2,
    (0x90, 0x02): 3,
    (0x90, 0x03): 6,
}


class ReadsAnyLength(RewritingStack):
    """Like the reference, it never checks a request's length: a request that is too long is cut,
    one that is too short is filled with zeros (the reference would use stale buffer bytes), and
    executed. Not broken: the checker warns (§8.2 [length-check])."""

    def change_input(self, data: bytes, requests: list[Frame], now: float) -> bytes:
        for frame in requests:
            payload = frame.payload
            if frame.cmd != Cmd.CTRL_BUS or not payload:
                continue
            code = payload[0]
            key = (code, payload[1]) if code == Request.HEALTH_MGMT and len(payload) > 1 else code
            size = _REQUEST_SIZES.get(key)
            if size is not None and len(payload) != size:
                fixed = encode(Cmd.CTRL_BUS, payload[:size].ljust(size, b"\0"), long=frame.long)
                data = data.replace(frame.raw, fixed, 1)
        return data


class DelayedLink:
    """A base's link whose writes reach the other end `delay_s` later (in order)."""

    def __init__(self, link: Link, delay_s: float) -> None:
        self._link = link
        self._delay_s = delay_s
        self._queue: deque[tuple[float, bytes]] = deque()
        self._ready = threading.Condition()
        self._closed = False
        self._thread = threading.Thread(target=self._deliver, name="delayed-link", daemon=True)
        self._thread.start()

    @property
    def name(self) -> str:
        return f"{self._link.name} (answers delayed {self._delay_s * 1000:.0f} ms)"

    def read(self, timeout: float) -> bytes:
        return self._link.read(timeout)

    def write(self, data: bytes) -> None:
        with self._ready:
            self._queue.append((time.monotonic() + self._delay_s, data))
            self._ready.notify()

    def _deliver(self) -> None:
        while True:
            with self._ready:
                while not self._queue and not self._closed:
                    self._ready.wait()
                if self._closed:
                    return
                due, data = self._queue[0]
                wait = due - time.monotonic()
                if wait > 0:
                    self._ready.wait(wait)
                    continue
                self._queue.popleft()
            try:
                self._link.write(data)
            except Exception:
                return  # the other end is gone; nothing to deliver to

    def close(self) -> None:
        with self._ready:
            self._closed = True
            self._ready.notify()
        self._thread.join(5)
        self._link.close()


# --- the catalogue -----------------------------------------------------------------------------


@dataclass(frozen=True)
class BrokenBase:
    """`make` builds the stack; `check` is the name of the check that must fail; `only` the
    checks to run (None: every check that needs no more than round trips); `delay_s` delays
    every answer; `profile` is the checker's --profile; `queue_command` is offered to the Core
    before the run."""

    name: str
    breaks: str
    check: str
    make: Callable[[], BaseStack]
    only: str | None = None
    delay_s: float = 0.0
    profile: str = "any"
    queue_command: int | None = None
    unreadable: bool = False  # no answer can be read at all: every later check is skipped


def _sim_stack(app: SimulatedBase | None = None, **config: object) -> BaseStack:
    return BaseStack(app or simulated_base(), BaseConfig(**config))  # type: ignore[arg-type]


BROKEN_BASES: tuple[BrokenBase, ...] = (
    BrokenBase(
        "wrong-checksum-in-answers",
        "every answer's checksum is wrong (§3.2)",
        "link",
        lambda: CorruptChecksums(simulated_base()),
        unreadable=True,
    ),
    BrokenBase(
        "garbage-in-answers",
        "two stray bytes after every answer (§8.4)",
        "link",
        lambda: GarbageAfterAnswers(simulated_base()),
    ),
    BrokenBase(
        "connect-answer-30-bytes",
        "CONNECT_BASE answered with 30 bytes (§5.1: 28 or 39)",
        "connect",
        lambda: _sim_stack(LongConnectAnswer(World(seed=SEED))),
    ),
    BrokenBase(
        "negative-sensor-angle",
        "a sensor angle of -40° (§5.2: 0..360)",
        "configuration",
        lambda: _sim_stack(NegativeSensorAngle(World(seed=SEED))),
    ),
    BrokenBase(
        "wrong-payload-length-in-answer",
        "GET_BASE_STATUS answered with 3 bytes (§5.4: 2)",
        "telemetry",
        lambda: _sim_stack(StatusTooLong(World(seed=SEED))),
    ),
    BrokenBase(
        "unknown-event-refused",
        "SEND_EVENT of an unknown event answered ERROR 0x8000 (§5.14: OK)",
        "motion-commands",
        lambda: _sim_stack(RefusesUnknownEvents(World(seed=SEED))),
    ),
    BrokenBase(
        "ack-keeps-command",
        "POLL_BASE_ANS_CMD does not clear the pending command (§5.13)",
        "poll",
        lambda: AckKeepsCommand(simulated_base(), BaseConfig()),
        queue_command=ExternalCommand.MOVE_FORWARD,
    ),
    BrokenBase(
        "unknown-health-sub-0x8000",
        "an unknown HEALTH sub-command answered 0x8000 (§5.15: 0x8002)",
        "health",
        lambda: RewriteErrorCode(0x8002, 0x8000, lambda requests: _any(requests, _unknown_health_sub)),
    ),
    BrokenBase(
        "long-requests-ignored",
        "long (0x50) control-bus requests are not read (§3.4)",
        "frame-flags",
        lambda: IgnoreLongRequests(simulated_base()),
    ),
    BrokenBase(
        "sync-without-filler",
        "SYNC answered without its filler (§4.2)",
        "sync",
        lambda: SyncWithoutFiller(simulated_base()),
    ),
    BrokenBase(
        "echo-not-verbatim",
        "ECHO of a long frame answered in a standard frame (§4.2)",
        "echo",
        lambda: EchoInStandardFrames(simulated_base()),
    ),
    BrokenBase(
        "checksum-error-unanswered",
        "a checksum mismatch gets no ERROR answer (§8.1)",
        "checksum-error",
        lambda: RewriteErrorCode(0x0040, None),
    ),
    BrokenBase(
        "unknown-cmd-0x8001",
        "an unknown CMD answered 0x8001 (§4.1: 0x8000)",
        "unknown-cmd",
        lambda: RewriteErrorCode(0x8000, 0x8001, lambda requests: _any(requests, _unknown_cmd)),
    ),
    BrokenBase(
        "unknown-request-0x8002",
        "an unknown control-bus request answered 0x8002 (§5.16: 0x8000)",
        "unknown-request",
        lambda: RewriteErrorCode(0x8000, 0x8002, lambda requests: _any(requests, _unknown_request)),
    ),
    BrokenBase(
        "any-connect-version",
        "CONNECT_BASE accepted with protocol version 0 or 2 (§5.1: 0x8000)",
        "unsupported-argument",
        lambda: AcceptsAnyConnectVersion(simulated_base()),
    ),
    BrokenBase(
        "wrong-length-0x8000",
        "wrong payload lengths answered 0x8000 (§8.2: 0x8001)",
        "length",
        lambda: RewriteErrorCode(0x8001, 0x8000),
    ),
    BrokenBase(
        "oversize-unanswered",
        "an oversize frame gets no ERROR 0x0020 (§8.1)",
        "oversize",
        lambda: RewriteErrorCode(0x0020, None),
    ),
    BrokenBase(
        "deaf-after-garbage",
        "after garbage it ignores the line for 3 s (§7, §8.1)",
        "garbage",
        DeafAfterGarbage,
        only="1,17",  # it stays deaf for a while after the check: later checks are not independent
    ),
    BrokenBase(
        "ignores-the-resend-after-garbage",
        "a request right behind garbage is dropped, and so is its resend (§11.6 [line-faults])",
        "garbage",
        lambda: IgnoresTheResendAfterGarbage(simulated_base()),
        only="1,17",  # it drops requests after the check's failure too: later checks are not independent
    ),
    BrokenBase(
        "blob-robot-size-is-the-radius",
        "the 0x21 blob's robot_size is the radius, not the diameter (§12.4 [conf-units])",
        "config-agreement",
        lambda: _sim_stack(BlobRobotSizeIsTheRadius()),
    ),
    BrokenBase(
        "unlisted-distance-channels",
        "distance channels with readings that no configuration lists (§12.4 [conf-sensor-list])",
        "sensor-list",
        lambda: _sim_stack(UnlistedDistanceChannels(World(seed=SEED))),
    ),
    BrokenBase(
        "executes-bad-checksum",
        "motion commands that fail their checksum are executed (§8.1 [base-no-exec])",
        "not-executed",
        lambda: ExecutesBadChecksums(simulated_base()),
        only="11,18",
    ),
    BrokenBase(
        "no-watchdog",
        "no motor watchdog (§9.1)",
        "watchdog",
        lambda: _sim_stack(watchdog_s=None),
        only="19",
    ),
    BrokenBase(
        "deadreckon-from-command",
        "the deadreckon integrates the commanded turn, which goes on after the watchdog (§9.1)",
        "watchdog",
        lambda: _sim_stack(DeadreckonFromCommand()),
        only="19",
    ),
    BrokenBase(
        "slow-answers",
        "every answer 300 ms late (§11.6: the Core waits 200 ms)",
        "latency",
        lambda: _sim_stack(),
        only="2,20",
        delay_s=0.3,
    ),
    BrokenBase(
        "reference-profile-checked-as-sdk2020",
        "answers the reference profile's sizes where sdk2020's are required (§6.2)",
        "profile",
        lambda: _sim_stack(),
        profile="sdk2020",
    ),
)
