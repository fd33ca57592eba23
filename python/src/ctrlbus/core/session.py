# SPDX-License-Identifier: MIT
"""The Core emulator as a sans-IO session: bytes and time in, request frames out.

`CoreSession` behaves as docs/protocol.md §11 describes: it repeats CONNECT_BASE until the base
answers (with a flushing SYNC after each unanswered attempt), reads the configuration
(GET_BASE_CONF_ADV, falling back to GET_BASE_CONF), sends SEND_EVENT SYSTEM_UP_OK, and then polls
on its schedule, one request outstanding at a time, with timeouts, retries, disconnect detection
and reconnection. It integrates the deadreckon deltas into a pose, acts on the base's external
commands (POLL_BASE_CMD) and runs actions (drive, turn, go home).

It never reads a clock or a port:

    request = session.poll(now)          # the next request frame to send, or None
    session.receive(answer_bytes, now)   # bytes from the link
    session.next_poll_time()             # when poll() may next have something to do

What it learns about the base is a typed model (`telemetry`, ctrlbus.core.telemetry), what it did
is an event log (ctrlbus.core.events); the dashboard's JSON is made from both in ctrlbus.web.snapshot.
The session holds no lock: it is driven from one thread at a time. A program that drives it from
one thread and reads or commands it from another holds the lock of the runner that owns the
thread (`CoreRunner.lock`) around each call.
"""

from __future__ import annotations

import enum
import logging
import math
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from ctrlbus import binconf
from ctrlbus.constants import LINE_FAULT_LIMIT
from ctrlbus.constants import WATCHDOG_TRIPPED_CODE as WATCHDOG_HEALTH_CODE
from ctrlbus.core.actions import Action, DriveDistance, TurnAngle
from ctrlbus.core.config import CoreConfig
from ctrlbus.core.docking import GoHome
from ctrlbus.core.events import CoreEvent, EventLog, command_name, describe_request
from ctrlbus.core.geometry import (
    SOURCE_CONF_ADV,
    BaseGeometry,
    compare_geometries,
    geometry_from_conf,
    geometry_from_tree,
)
from ctrlbus.core.stats import LinkStats
from ctrlbus.core.telemetry import (
    BaseIdentity,
    BaseTelemetry,
    CommandState,
    ConnectionState,
    HealthError,
    HealthState,
    LinkTelemetry,
)
from ctrlbus.errors import BinaryConfigError, MessageError, UsageError
from ctrlbus.frame import Frame, StreamDecoder
from ctrlbus.kinematics import DeadreckonDelta, Pose
from ctrlbus.messages import (
    AnswerMessage,
    Cmd,
    ConnectBase,
    ConnectBaseAnswer,
    ErrorAnswer,
    ErrorCode,
    Event,
    ExternalCommand,
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
    InvalidAnswer,
    PollBaseAnsCmd,
    PollBaseCmd,
    PollBaseCmdAnswer,
    RequestMessage,
    Response,
    SendEvent,
    SetVAndGetDeadreckon,
    SetVAndGetDeadreckonAnswer,
    Sync,
    decode_answer,
    request_frame,
)

# The session's own names, and the model's that its API returns (kept importable from here).
__all__ = [
    "FLUSH_FILLER",
    "BaseIdentity",
    "CommandState",
    "ConnectionState",
    "CoreEvent",
    "CoreSession",
    "HealthError",
    "HealthState",
    "describe_request",
]

log = logging.getLogger("ctrlbus.core")

# §11.1: the flushing SYNC is a long frame of exactly 512 bytes: 4 header bytes, 507 filler, checksum.
FLUSH_FILLER = bytes(507)


class _Purpose(enum.Enum):
    CONNECT = "connect"
    FLUSH = "flush"
    CONFIG_ADV = "config_adv"
    CONFIG = "config"
    SYSTEM_UP = "system_up"
    POLL = "poll"
    NOTICE = "notice"  # CORE_DISCONNECT after a lost connection: one attempt, best effort
    STOP = "stop"  # CORE_DISCONNECT when stopped on purpose


class _Step(enum.Enum):
    CONNECT = "connect"
    CONFIG_ADV = "config_adv"
    CONFIG = "config"
    SYSTEM_UP = "system_up"
    POLLING = "polling"
    NOTICE = "notice"
    STOPPED = "stopped"


@dataclass
class _Outstanding:
    message: RequestMessage
    frame: bytes
    purpose: _Purpose
    max_attempts: int
    attempts: int = 0
    sent_at: float = 0.0
    deadline: float = 0.0
    resend: bool = False  # a failed attempt: send again at the next poll()
    transport_error: str | None = None  # a line-fault ERROR seen; the real answer may still follow
    schedule_name: str | None = None


# (name, request, rate attribute of PollRates) in the order §11.4 sends them when several are due.
_SCHEDULE: tuple[tuple[str, RequestMessage | None, str], ...] = (
    ("set_v", None, "set_v_hz"),  # built at send time from the current velocity command
    ("bumper", GetBaseBumperData(), "bumper_hz"),
    ("sensor", GetBaseSensorData(), "sensor_hz"),
    ("status", GetBaseStatus(), "status_hz"),
    ("motor", GetBaseMotorData(), "motor_hz"),
    ("poll_cmd", PollBaseCmd(), "poll_cmd_hz"),
    ("health", HealthGetHealth(), "health_hz"),
    ("charger", GetChargerData(0), "charger_hz"),
)
_DOCKING_ONLY = frozenset({"charger"})
# Requests whose fate is accounted (answered, superseded, abandoned at a disconnect, or lost).
_TRACKED_PURPOSES = frozenset({_Purpose.CONFIG_ADV, _Purpose.CONFIG, _Purpose.SYSTEM_UP, _Purpose.POLL})


def _check_finite(**values: float) -> None:
    for name, value in values.items():
        if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
            raise UsageError(f"{name} must be a finite number, got {value!r}")


class CoreSession:
    """The Core emulator's protocol state machine (sans-IO, one thread at a time)."""

    def __init__(self, config: CoreConfig | None = None, *, port: str = "") -> None:
        self.config = config if config is not None else CoreConfig()
        self.port = port
        self._decoder = StreamDecoder(max_frame=self.config.max_frame, timeout=self.config.decoder_timeout_s)
        self._stats = LinkStats()
        self._subscribers: list[Callable[[str], None]] = []
        self._changed: set[str] = set()
        # Time: the first `now` seen is the session's zero.
        self._t0: float | None = None
        self._now = 0.0
        # Protocol state.
        self._step = _Step.CONNECT
        self._state = ConnectionState.CONNECTING
        self._state_since = 0.0
        self._state_reason: str | None = None
        self._outstanding: _Outstanding | None = None
        self._next_connect_at: float | None = None
        self._last_connect_at: float | None = None
        self._connect_attempts = 0  # since the last successful connection
        self._stop_requested = False
        self._followups: deque[RequestMessage] = deque()
        self._next_due: dict[str, float] = {}
        self._last_ctrl_sent: float | None = None
        self._offered_command: int | None = None
        self._health_collect: list[HealthError | None] | None = None
        self._health_flags_pending: int | None = None
        self._last_error_logged: dict[str, int] = {}
        self._silent_streak = 0  # silent attempts in a row, whatever the request (any frame resets it)
        self._failed_streak = 0  # failed attempts in a row, whatever the request (an answer resets it)
        # §11.6 [core-flush]: after a silent attempt, a flushing SYNC goes before the next request,
        # and the request waits (held) until the flush is over.
        self._flush_pending = False
        self._held: _Outstanding | None = None
        self._telemetry = BaseTelemetry()
        # Commands.
        self._vx = 0.0
        self._omega = 0.0
        self._estop = False
        self._action: Action | None = None
        self._last_outcome: str | None = None
        self._events = EventLog()

    # ===================================================================== sans-IO interface

    def poll(self, now: float) -> bytes | None:
        """The next request frame to send at time `now` (seconds), or None if nothing is due."""
        self._advance(now)
        # A false frame start can hold a real answer behind it until the line has been idle
        # for the inter-byte timeout; apply it now rather than only when more bytes come.
        if self._decoder.buffered:
            for frame_in in self._decoder.feed(b"", now):
                self._on_frame(frame_in, now)
        frame = self._next_request(now)
        self._notify()
        return frame

    def receive(self, data: bytes, now: float) -> None:
        """Bytes read from the link at time `now`."""
        self._advance(now)
        self._expire(now)
        for frame in self._decoder.feed(data, now):
            self._on_frame(frame, now)
        self._notify()

    def next_poll_time(self) -> float | None:
        """The earliest time at which poll() may return a frame or time something out, if no
        bytes arrive first; None when only arriving bytes (or a command) can change anything."""
        decoder_due = self._decoder.timeout_due
        due = self._next_due_time()
        if decoder_due is None:
            return due
        return decoder_due if due is None else min(due, decoder_due)

    def _next_due_time(self) -> float | None:
        outstanding = self._outstanding
        if outstanding is not None:
            return self._now if outstanding.resend else outstanding.deadline
        step = self._step
        if step is _Step.STOPPED:
            return None
        if self._stop_requested:
            return self._now
        if step is _Step.CONNECT:
            return self._next_connect_at if self._next_connect_at is not None else self._now
        if step is not _Step.POLLING or self._followups:
            return self._now
        dues = [due for name, due in self._next_due.items() if self._rate(name) > 0]
        return min(dues) if dues else None

    def request_stop(self) -> None:
        """Stop on purpose: once the request in flight is settled, send SEND_EVENT CORE_DISCONNECT
        (if connected), then stop. `stopped` tells when it is done."""
        if self._step is _Step.STOPPED or self._stop_requested:
            return
        self._stop_requested = True
        self._cancel_action("the Core is stopping")
        self._vx = self._omega = 0.0
        if not self._connected_to_base():
            self._finish_stop()
        self._notify()

    @property
    def stopped(self) -> bool:
        return self._step is _Step.STOPPED

    def link_failed(self, reason: str, now: float) -> None:
        """The runner could not read or write the link: the connection is gone."""
        self._advance(now)
        self._abandon_outstanding()
        if self._step is _Step.STOPPED:
            pass
        elif self._stop_requested:
            self._finish_stop()
        elif self._state is not ConnectionState.DISCONNECTED or self._state_reason != reason:
            self._log("core", f"link failed: {reason}")
            self._drop_connection(reason, now, notify_base=False)
        self._notify()

    # ============================================================================== controls

    def limits(self) -> tuple[float, float]:
        """(max |vx| m/s, max |omega| rad/s): the configured limits once the base's configuration
        is known, (0, 0) before."""
        if not self._telemetry.configured:
            return 0.0, 0.0
        return self.config.max_vx_mps, self.config.max_omega_radps

    def set_velocity(self, vx_mps: float, omega_radps: float) -> None:
        """Command a body velocity (clamped to limits()); cancels a running action; ignored while
        the emergency stop is latched."""
        _check_finite(vx_mps=vx_mps, omega_radps=omega_radps)
        if self._estop:
            return
        max_vx, max_omega = self.limits()
        self._cancel_action("cancelled by a velocity command")
        self._vx = max(-max_vx, min(max_vx, float(vx_mps)))
        self._omega = max(-max_omega, min(max_omega, float(omega_radps)))
        self._changed.add("command")
        self._notify()

    def emergency_stop(self) -> None:
        """Zero velocity at once, cancel any action, latch until release_stop()."""
        self._cancel_action("cancelled by the emergency stop")
        self._vx = self._omega = 0.0
        if not self._estop:
            self._estop = True
            self._log("core", "emergency stop")
        self._changed.add("command")
        self._notify()

    def release_stop(self) -> None:
        """Unlatch the emergency stop; the velocity stays zero until commanded again."""
        if self._estop:
            self._estop = False
            self._log("core", "emergency stop released")
        self._vx = self._omega = 0.0
        self._changed.add("command")
        self._notify()

    def go_home(self) -> None:
        """Start docking on the charger using its beacons (ignored while the stop is latched)."""
        self._start_action(GoHome(self.config.docking), "requested")
        self._notify()

    def drive(self, distance_m: float, speed_mps: float | None = None) -> None:
        """Drive straight `distance_m` (negative: backwards), as MOVE_FORWARD/BACKWARD do."""
        speed = self.config.move_speed_mps if speed_mps is None else speed_mps
        _check_finite(distance_m=distance_m, speed_mps=speed)
        if speed <= 0:
            raise UsageError(f"speed_mps must be positive, got {speed!r}")
        self._start_action(DriveDistance(distance_m, min(speed, self.config.max_vx_mps)), "requested")
        self._notify()

    def turn(self, angle_deg: float, rate_radps: float | None = None) -> None:
        """Turn in place by `angle_deg` (positive: left), as TURN_LEFT/RIGHT do."""
        rate = self.config.turn_rate_radps if rate_radps is None else rate_radps
        _check_finite(angle_deg=angle_deg, rate_radps=rate)
        if rate <= 0:
            raise UsageError(f"rate_radps must be positive, got {rate!r}")
        self._start_action(TurnAngle(angle_deg, min(rate, self.config.max_omega_radps)), "requested")
        self._notify()

    def cancel_action(self) -> None:
        """Stop whatever action runs, as CANCEL_ACTION does."""
        self._cancel_action("cancelled")
        self._vx = self._omega = 0.0
        self._changed.add("command")
        self._notify()

    def subscribe(self, callback: Callable[[str], None]) -> Callable[[], None]:
        """Call `callback(topic)` after each change; returns a function that unsubscribes.

        Topics: connection, base, pose, command, battery, motion, bumpers, sensors, charger,
        health, events. Callbacks run in the thread that called poll/receive (or the control),
        under whatever lock that thread holds (a runner's); they must be quick and must not wait
        for another thread. An exception in one is logged and does not reach the session.
        """
        self._subscribers.append(callback)

        def unsubscribe() -> None:
            if callback in self._subscribers:
                self._subscribers.remove(callback)

        return unsubscribe

    # ============================================================================= telemetry

    @property
    def state(self) -> ConnectionState:
        return self._state

    @property
    def connected(self) -> bool:
        return self.state is ConnectionState.CONNECTED

    @property
    def connects(self) -> int:
        """Successful connections so far."""
        return self._stats.connects

    @property
    def time_s(self) -> float:
        """Seconds since the session's first poll/receive."""
        return self._elapsed(self._now)

    @property
    def pose(self) -> Pose:
        """The dead-reckoned pose, in the frame of the robot when the Core started."""
        return self._telemetry.pose

    @property
    def identity(self) -> BaseIdentity | None:
        return self._telemetry.identity

    @property
    def geometry(self) -> BaseGeometry | None:
        return self._telemetry.geometry

    @property
    def battery_percent(self) -> int | None:
        return self._telemetry.battery_percent

    @property
    def power_status(self) -> int | None:
        return self._telemetry.power_status

    @property
    def bumper_bitmap(self) -> int | None:
        return self._telemetry.bumper_bitmap

    @property
    def bumpers_pressed(self) -> tuple[bool, ...]:
        """One flag per configured bumper (the bitmap is active low)."""
        return self._telemetry.bumpers_pressed

    @property
    def distances_mm(self) -> tuple[float, ...] | None:
        """The 16 distances of the last GET_BASE_SENSOR_DATA (None before the first)."""
        return self._telemetry.distances_mm

    @property
    def charger_probes(self) -> tuple[int, ...] | None:
        return self._telemetry.charger_probes

    @property
    def motion_status(self) -> int | None:
        return self._telemetry.motion_status

    @property
    def motor_totals_mm(self) -> tuple[int, int] | None:
        return self._telemetry.motor_totals_mm

    @property
    def health(self) -> HealthState:
        return self._telemetry.health

    @property
    def command(self) -> CommandState:
        return self._command_state()

    @property
    def last_outcome(self) -> str | None:
        """How the last action ended."""
        return self._last_outcome

    @property
    def offered_command(self) -> int | None:
        """The external command the base offered last (None before any)."""
        return self._offered_command

    @property
    def telemetry(self) -> BaseTelemetry:
        """The model of the base (ctrlbus.core.telemetry), live: read it, never change it."""
        return self._telemetry

    def events(self, since_seq: int = 0) -> list[CoreEvent]:
        """Logged events with seq > since_seq, oldest first (the last MAX_EVENTS of ctrlbus.core.events)."""
        return self._events.since(since_seq)

    def link_telemetry(self) -> LinkTelemetry:
        """The connection and the link's counters."""
        since = self._t0 if self._t0 is not None else self._now
        return LinkTelemetry(
            state=self._state,
            port=self.port,
            since_s=self._elapsed(self._state_since),
            reason=self._state_reason,
            requests_per_s=self._stats.requests_per_s(self._now, since),
            stats=self._stats,
            decoder=self._decoder.stats,
        )

    def link_stats(self) -> dict[str, Any]:
        """Link statistics as plain values (a superset of the dashboard snapshot's `link` part)."""
        return self.link_telemetry().as_dict()

    # ====================================================================== the state machine

    def _advance(self, now: float) -> None:
        if not math.isfinite(now):
            raise UsageError(f"time must be a finite number of seconds, got {now!r}")
        if self._t0 is None:
            self._t0 = self._now = self._state_since = now
            self._next_connect_at = now
        elif now > self._now:
            self._now = now

    def _elapsed(self, now: float) -> float:
        return 0.0 if self._t0 is None else now - self._t0

    def _rate(self, name: str) -> float:
        rates = self.config.rates
        docking = isinstance(self._action, GoHome)
        if name in _DOCKING_ONLY:
            return rates.charger_hz if docking else 0.0
        rate: float = getattr(rates, f"{name}_hz")
        if name == "status" and docking:
            return max(rate, rates.charger_hz)  # see the on-dock bit promptly while docking
        return rate

    def _next_request(self, now: float) -> bytes | None:
        self._expire(now)
        outstanding = self._outstanding
        if self._flush_pending and (outstanding is None or outstanding.resend) and self._connected_to_base():
            # A reference base has no inter-byte timeout: a false frame start in noise may be
            # swallowing every request; 512 bytes complete whatever it waits for (§11.6).
            self._flush_pending = False
            self._held = outstanding
            return self._start(Sync(FLUSH_FILLER), _Purpose.FLUSH, now, attempts=1, quiet=True)
        if outstanding is not None:
            if outstanding.resend:
                return self._send(outstanding, now)
            return None
        step = self._step
        if step is _Step.STOPPED:
            return None
        if self._stop_requested:
            if self._connected_to_base():
                return self._start(SendEvent(Event.CORE_DISCONNECT), _Purpose.STOP, now, attempts=1)
            self._finish_stop()
            return None
        if step is _Step.NOTICE:
            return self._start(SendEvent(Event.CORE_DISCONNECT), _Purpose.NOTICE, now, attempts=1)
        if step is _Step.CONNECT:
            if self._next_connect_at is not None and now < self._next_connect_at:
                return None
            self._last_connect_at = now
            self._connect_attempts += 1
            self._stats.connect_attempts += 1
            attempt = self._connect_attempts
            # Log the first attempts, then every tenth: a base that is off must not flood the log.
            quiet = attempt > 3 and attempt % 10 != 0
            if not quiet and attempt > 1:
                self._log("core", f"CONNECT_BASE v1 (attempt {attempt}, no answer yet)")
            return self._start(ConnectBase(1), _Purpose.CONNECT, now, attempts=1, quiet=quiet or attempt > 1)
        if step is _Step.CONFIG_ADV:
            return self._start(GetBaseConfAdv(), _Purpose.CONFIG_ADV, now)
        if step is _Step.CONFIG:
            return self._start(GetBaseConf(), _Purpose.CONFIG, now)
        if step is _Step.SYSTEM_UP:
            return self._start(SendEvent(Event.SYSTEM_UP_OK), _Purpose.SYSTEM_UP, now)
        # Polling: follow-ups first (POLL_BASE_ANS_CMD, HEALTH_GET_ERROR), then the schedule.
        if self._followups:
            return self._start(self._followups.popleft(), _Purpose.POLL, now)
        for name, message, _ in _SCHEDULE:
            rate = self._rate(name)
            if rate <= 0:
                continue
            due = self._next_due.setdefault(name, now)
            if due > now:
                continue
            period = 1.0 / rate
            due += period
            self._next_due[name] = due if due > now else now + period
            if message is None:
                message = self._velocity_request(now)
            return self._start(message, _Purpose.POLL, now, schedule_name=name)
        return None

    def _velocity_request(self, now: float) -> RequestMessage:
        action = self._action
        if action is not None:
            vx, omega = action.command(now)
            max_vx, max_omega = self.config.max_vx_mps, self.config.max_omega_radps
            self._vx = max(-max_vx, min(max_vx, vx))
            self._omega = max(-max_omega, min(max_omega, omega))
            if action.finished:
                self._end_action(action)
            self._changed.add("command")
        if self._estop:
            self._vx = self._omega = 0.0
        return SetVAndGetDeadreckon.from_si(self._vx, 0.0, self._omega)

    def _start(
        self,
        message: RequestMessage,
        purpose: _Purpose,
        now: float,
        *,
        attempts: int | None = None,
        schedule_name: str | None = None,
        quiet: bool = False,
    ) -> bytes:
        outstanding = self._prepare(message, purpose, attempts=attempts, schedule_name=schedule_name)
        if schedule_name is None and not quiet:
            self._log("core", describe_request(message))
        return self._send(outstanding, now)

    def _prepare(
        self,
        message: RequestMessage,
        purpose: _Purpose,
        *,
        attempts: int | None = None,
        schedule_name: str | None = None,
    ) -> _Outstanding:
        """Make `message` the request in flight, to be sent by the next poll()."""
        long = True if self.config.long_frames or isinstance(message, Sync) else None
        outstanding = _Outstanding(
            message=message,
            frame=request_frame(message, long=long),
            purpose=purpose,
            max_attempts=attempts if attempts is not None else 1 + self.config.retries,
            schedule_name=schedule_name,
            resend=True,
        )
        self._outstanding = outstanding
        if purpose in _TRACKED_PURPOSES:
            self._stats.tracked_requests += 1
        return outstanding

    def _send(self, outstanding: _Outstanding, now: float) -> bytes:
        if outstanding.attempts:
            self._stats.retries += 1
        outstanding.attempts += 1
        outstanding.resend = False
        outstanding.transport_error = None
        outstanding.sent_at = now
        wire_time = len(outstanding.frame) * self.config.byte_time_s
        outstanding.deadline = now + wire_time + self.config.request_timeout_s
        self._stats.count_request(now)
        if outstanding.message.CMD == Cmd.CTRL_BUS and self._state is ConnectionState.CONNECTED:
            last = self._last_ctrl_sent
            if last is not None and now - last > self.config.watchdog_s:
                self._stats.watchdog_trips += 1
                self._log("core", f"no CTRL_BUS request for {now - last:.2f} s: the base's watchdog tripped")
            self._last_ctrl_sent = now
        return outstanding.frame

    def _expire(self, now: float) -> None:
        """Time out the request in flight if its deadline has passed."""
        outstanding = self._outstanding
        if outstanding is None or outstanding.resend or now <= outstanding.deadline:
            return
        purpose = outstanding.purpose
        if purpose is _Purpose.FLUSH:
            self._end_flush(now)
            return
        if purpose is _Purpose.CONNECT:
            self._outstanding = None
            if self.config.flush_sync:
                self._prepare(Sync(FLUSH_FILLER), _Purpose.FLUSH, attempts=1)
            else:
                self._schedule_next_connect(now)
            return
        if outstanding.transport_error is not None:
            self._failed_attempt(outstanding, outstanding.transport_error, now, silent=False)
            return
        self._stats.timeouts += 1
        self._failed_attempt(
            outstanding, f"no answer to {describe_request(outstanding.message)}", now, silent=True
        )

    def _end_flush(self, now: float) -> None:
        """The flushing SYNC's window is over: go on with the held request, or the connect loop."""
        self._outstanding = None
        if self._step is _Step.CONNECT:
            self._schedule_next_connect(now)
        else:
            self._outstanding, self._held = self._held, None

    def _failed_attempt(self, outstanding: _Outstanding, reason: str, now: float, *, silent: bool) -> None:
        """An attempt failed: `silent` (a timeout) or answered by a line fault, INVALID or a
        malformed answer (§11.6 [core-resend]). A request that matters is resent until answered; a
        periodic one whose next period has come is superseded by it instead; the base counts as
        disconnected after `1 + retries` silent attempts in a row, or `line_fault_attempts` failed
        attempts in a row without an answer. CONNECT_BASE, CORE_DISCONNECT and the flush have
        their own attempt limits (§11.1, §11.7)."""
        if silent:
            self._silent_streak += 1
            self._flush_pending = self.config.flush_sync
        purpose = outstanding.purpose
        if purpose in _TRACKED_PURPOSES:
            self._failed_streak += 1
            too_silent = self._silent_streak >= 1 + self.config.retries
            too_faulty = self._failed_streak >= self.config.line_fault_attempts
            if not too_silent and not too_faulty:
                name = outstanding.schedule_name
                if name is not None and self._next_due.get(name, now) <= now:
                    self._outstanding = None
                    self._stats.superseded += 1  # its next period is due: the fresh one goes instead
                    return
                outstanding.resend = True
                self._log("core", f"{reason} (attempt {outstanding.attempts}): sending again")
                return
            self._outstanding = None
            self._stats.disconnects += 1
            self._stats.abandoned_at_disconnect += 1
            what = (
                f"{self._silent_streak} attempts in a row unanswered"
                if too_silent
                else (f"{self._failed_streak} attempts in a row failed (line faults, no answer)")
            )
            self._log("core", f"{reason}: {what}, base disconnected")
            self._drop_connection(reason, now, notify_base=True)
            return
        if outstanding.attempts < outstanding.max_attempts:
            outstanding.resend = True
            attempt = f"attempt {outstanding.attempts}/{outstanding.max_attempts}"
            self._log("core", f"{reason} ({attempt}): sending again")
            return
        self._outstanding = None
        if purpose is _Purpose.STOP or self._stop_requested:
            self._finish_stop()
        elif purpose is _Purpose.NOTICE:
            self._enter_connect_loop(now)
        elif purpose is _Purpose.CONNECT:
            self._schedule_next_connect(now)
        else:
            # A request that matters given up while the base still counts as connected.
            self._stats.lost_requests += 1
            self._log("core", f"{reason}: {describe_request(outstanding.message)} given up (lost)")

    def _drop_connection(self, reason: str, now: float, *, notify_base: bool) -> None:
        self._abandon_outstanding()
        self._silent_streak = self._failed_streak = 0
        self._set_state(ConnectionState.DISCONNECTED, now, reason)
        self._cancel_action("cancelled: the base is disconnected")
        self._vx = self._omega = 0.0
        self._followups.clear()
        self._health_collect = None
        self._last_ctrl_sent = None
        self._telemetry.configured = False
        if notify_base:
            self._step = _Step.NOTICE
        else:
            self._enter_connect_loop(now)

    def _enter_connect_loop(self, now: float) -> None:
        self._step = _Step.CONNECT
        self._next_connect_at = now

    def _schedule_next_connect(self, now: float) -> None:
        """§11.1: CONNECT_BASE every connect_interval_s, and never before `now`."""
        last = self._last_connect_at if self._last_connect_at is not None else now
        self._next_connect_at = max(now, last + self.config.connect_interval_s)

    def _connected_to_base(self) -> bool:
        return self._state in (ConnectionState.CONNECTED, ConnectionState.CONFIGURING)

    def _abandon_outstanding(self) -> None:
        """The connection ends with a request in flight (the link failed, or the Core stops)."""
        for outstanding in (self._outstanding, self._held):
            if outstanding is not None and outstanding.purpose in _TRACKED_PURPOSES:
                self._stats.abandoned_at_disconnect += 1
        self._outstanding = self._held = None
        self._flush_pending = False

    def _finish_stop(self) -> None:
        self._abandon_outstanding()
        self._step = _Step.STOPPED
        self._set_state(ConnectionState.DISCONNECTED, self._now, "stopped")
        self._log("core", "stopped")

    def _set_state(self, state: ConnectionState, now: float, reason: str | None = None) -> None:
        if state is not self._state:
            self._state = state
            self._state_since = now
            self._changed.add("connection")
        self._state_reason = reason

    # ============================================================================== answers

    def _on_frame(self, frame: Frame, now: float) -> None:
        outstanding = self._outstanding
        if outstanding is None or outstanding.resend:
            self._stats.stray_answers += 1
            return
        if outstanding.purpose is _Purpose.FLUSH:
            self._stats.flushed_frames += 1
            self._silent_streak = 0  # the base is there: it says something about the flush
            if self._step is not _Step.CONNECT:
                if frame.cmd == Response.SYNC and frame.raw == outstanding.frame:
                    self._end_flush(now)  # the base copied the flush back: nothing more is coming
                else:
                    # The base answers in stream order: what it says about the flush (or the
                    # frame the flush completed) comes now, the rest follows within the grace.
                    grace = now + self.config.transport_error_grace_s
                    outstanding.deadline = min(outstanding.deadline, grace)
            return
        request = outstanding.message
        if request.CMD == Cmd.CTRL_BUS and frame.cmd in (Response.SYNC, Response.ECHO):
            self._stats.stray_answers += 1  # a copy of an earlier SYNC or ECHO, not this answer
            return
        self._silent_streak = 0  # whatever it is, the base is there
        try:
            answer = decode_answer(request, frame.cmd, frame.payload)
        except MessageError as exc:
            self._stats.malformed_answers += 1
            self._stats.count_answer(now - outstanding.sent_at)
            self._log("base", f"malformed answer to {request.NAME}: {exc}")
            self._failed_attempt(outstanding, f"malformed answer to {request.NAME}", now, silent=False)
            return
        if isinstance(answer, ErrorAnswer):
            code = answer.error_code
            self._stats.errors_by_code[code] += 1
            if code < LINE_FAULT_LIMIT:
                self._stats.count_line_fault(code)
            if code == ErrorCode.NOT_SYNCED:
                self._stats.not_synced_reports += 1  # about stray bytes; the answer may follow
                return
            if code < LINE_FAULT_LIMIT:
                # A line fault (§11.6 [line-faults]): the request, or a false frame start in noise
                # just before it, did not arrive intact. The base answers in stream order, so an
                # intact request's answer would follow at once: wait a moment for it, then send
                # again (resending at once would put every later answer one step out of order).
                self._log_error(request, code)
                outstanding.transport_error = f"ERROR 0x{code:04X} to {request.NAME}"
                outstanding.deadline = min(outstanding.deadline, now + self.config.transport_error_grace_s)
                return
            self._stats.count_answer(now - outstanding.sent_at)
        elif isinstance(answer, InvalidAnswer):
            self._stats.invalid_answers += 1
            self._stats.count_answer(now - outstanding.sent_at)
            self._log("base", f"INVALID to {request.NAME}")
            self._failed_attempt(outstanding, f"INVALID to {request.NAME}", now, silent=False)
            return
        else:
            self._stats.count_answer(now - outstanding.sent_at)
        self._outstanding = None
        if outstanding.purpose in _TRACKED_PURPOSES:
            self._stats.answered_requests += 1
            self._failed_streak = 0
        self._on_answer(outstanding, answer, now)

    def _log_error(self, request: RequestMessage, code: int) -> None:
        """Log an ERROR answer, but not the same one to the same request over and over."""
        if self._last_error_logged.get(request.NAME) != code:
            self._last_error_logged[request.NAME] = code
            self._log("base", f"ERROR 0x{code:04X} to {request.NAME}")

    def _on_answer(self, outstanding: _Outstanding, answer: AnswerMessage, now: float) -> None:
        purpose = outstanding.purpose
        request = outstanding.message
        error = answer.error_code if isinstance(answer, ErrorAnswer) else None
        if error is not None:
            self._log_error(request, error)
        else:
            self._last_error_logged.pop(request.NAME, None)
        if purpose is _Purpose.CONNECT:
            if isinstance(answer, ConnectBaseAnswer):
                self._on_connected(answer, now)
            else:
                self._schedule_next_connect(now)
        elif purpose is _Purpose.CONFIG_ADV:
            self._on_config_adv(answer)
        elif purpose is _Purpose.CONFIG:
            if isinstance(answer, GetBaseConfAnswer) and self._telemetry.configured:
                self._note_second_view(geometry_from_conf(answer))  # asked besides a usable blob
            elif isinstance(answer, GetBaseConfAnswer):
                self._use_geometry(geometry_from_conf(answer))
            elif self._telemetry.configured:
                pass  # no GET_BASE_CONF besides the blob: only one view
            else:
                self._log("core", "no configuration from the base: going on without its geometry")
                self._use_geometry(None)
            self._step = _Step.SYSTEM_UP
        elif purpose is _Purpose.SYSTEM_UP:
            self._on_system_up(now)
        elif purpose is _Purpose.NOTICE:
            self._enter_connect_loop(now)
        elif purpose is _Purpose.STOP:
            self._finish_stop()
        elif purpose is _Purpose.POLL:
            self._on_poll_answer(request, answer, now)

    def _on_connected(self, answer: ConnectBaseAnswer, now: float) -> None:
        identity = BaseIdentity.from_answer(answer)
        self._telemetry.identity = identity
        self._stats.connects += 1
        self._connect_attempts = 0
        suffix = f" {identity.firmware_version_suffix}" if identity.firmware_version_suffix else ""
        self._log(
            "base",
            f"CONNECT_BASE answered: {identity.model!r}, firmware {identity.firmware_version}{suffix}, "
            f"hardware {identity.hardware_version}, serial {identity.serial}",
        )
        self._set_state(ConnectionState.CONFIGURING, now)
        self._step = _Step.CONFIG_ADV
        self._changed.add("base")

    def _on_config_adv(self, answer: AnswerMessage) -> None:
        if isinstance(answer, GetBaseConfAdvAnswer):
            try:
                tree = binconf.decode(answer.blob)
            except BinaryConfigError as exc:
                self._log("core", f"binary configuration does not decode ({exc}): asking GET_BASE_CONF")
                self._step = _Step.CONFIG
                return
            geometry = geometry_from_tree(tree)
            if geometry is None:
                self._log("core", "binary configuration has no `base` object: asking GET_BASE_CONF")
                self._step = _Step.CONFIG
                return
            self._log("base", f"binary configuration: {len(answer.blob)} bytes")
            self._use_geometry(geometry)
            self._step = _Step.CONFIG if self.config.read_both_configs else _Step.SYSTEM_UP
            return
        self._step = _Step.CONFIG  # ERROR 0x8000 (no blob), or any other refusal

    def _note_second_view(self, conf: BaseGeometry) -> None:
        self._telemetry.views[conf.source] = conf
        adv = self._telemetry.views.get(SOURCE_CONF_ADV)
        if adv is not None:
            for problem in compare_geometries(adv, conf):
                self._log("core", f"the two configurations disagree: {problem}")
        self._changed.add("base")

    def _use_geometry(self, geometry: BaseGeometry | None) -> None:
        self._telemetry.use_geometry(geometry)
        self._changed.add("base")

    def _on_system_up(self, now: float) -> None:
        self._step = _Step.POLLING
        self._next_due = {}
        self._followups.clear()
        self._last_ctrl_sent = now
        self._set_state(ConnectionState.CONNECTED, now)
        self._log("core", "polling")

    def _on_poll_answer(self, request: RequestMessage, answer: AnswerMessage, now: float) -> None:
        if isinstance(answer, ErrorAnswer):
            if isinstance(request, GetChargerData) and self._action is not None:
                self._action.on_charger_error(f"ERROR 0x{answer.error_code:04X}")
                self._check_action()
            elif isinstance(request, HealthGetError):
                self._health_error_answer(request.index, None)
            elif isinstance(request, PollBaseAnsCmd):
                self._log("core", "the base refused POLL_BASE_ANS_CMD: the command stays pending")
            return
        action = self._action
        if isinstance(answer, SetVAndGetDeadreckonAnswer):
            delta = DeadreckonDelta(answer.dx_mm, answer.dy_mm, answer.dtheta_deg)
            self._telemetry.move(delta)
            self._telemetry.motion_status = answer.status
            self._telemetry.deadreckon_timestamp_ms = answer.timestamp_ms
            if action is not None:
                action.on_motion(delta)
            self._changed.update(("pose", "motion"))
        elif isinstance(answer, GetBaseBumperDataAnswer):
            self._telemetry.bumper_bitmap = answer.bitmap
            if action is not None:
                action.on_bumpers(any(self._telemetry.bumpers_pressed), now)
            self._changed.add("bumpers")
        elif isinstance(answer, GetBaseSensorDataAnswer):
            self._telemetry.distances_mm = answer.distances_mm
            self._changed.add("sensors")
        elif isinstance(answer, GetBaseStatusAnswer):
            self._telemetry.battery_percent = answer.battery_percent
            self._telemetry.power_status = answer.power_status
            if action is not None:
                action.on_status(answer.power_status, now)
            self._changed.add("battery")
        elif isinstance(answer, GetBaseMotorDataAnswer):
            self._telemetry.motor_totals_mm = (answer.left_distance_mm, answer.right_distance_mm)
            self._telemetry.motion_status = answer.status
            self._changed.add("motion")
        elif isinstance(answer, GetChargerDataAnswer):
            self._telemetry.charger = answer
            if action is not None:
                action.on_charger(answer.probes, now)
            self._changed.add("charger")
        elif isinstance(answer, PollBaseCmdAnswer):
            if answer.command is not None:
                self._offered_command = answer.command
                self._log("base", f"base offers {command_name(answer.command)} (0x{answer.command:02X})")
                self._followups.appendleft(PollBaseAnsCmd())
        elif isinstance(answer, HealthGetHealthAnswer):
            self._on_health(answer)
        elif isinstance(answer, HealthGetErrorAnswer) and isinstance(request, HealthGetError):
            self._health_error_answer(request.index, HealthError(answer.error_code, answer.message))
        elif isinstance(request, PollBaseAnsCmd) and self._offered_command is not None:
            self._act_on(self._offered_command)
        self._check_action()

    # ============================================================================== health

    def _on_health(self, answer: HealthGetHealthAnswer) -> None:
        if answer.error_count == 0 or self._health_collect is not None:
            if answer.error_count == 0:
                self._set_health(answer.flags, ())
            return
        self._health_flags_pending = answer.flags
        self._health_collect = [None] * answer.error_count
        for index in range(answer.error_count):
            self._followups.append(HealthGetError(index))

    def _health_error_answer(self, index: int, error: HealthError | None) -> None:
        collect = self._health_collect
        if collect is None or index >= len(collect):
            return
        collect[index] = error
        if index == len(collect) - 1:
            self._health_collect = None
            self._set_health(self._health_flags_pending, tuple(item for item in collect if item is not None))

    def _set_health(self, flags: int | None, errors: tuple[HealthError, ...]) -> None:
        previous = {error.code for error in self._telemetry.health.errors}
        for error in errors:
            if error.code not in previous:
                self._log("base", f"health: 0x{error.code:08X} {error.message}")
                if error.code == WATCHDOG_HEALTH_CODE:
                    self._stats.watchdog_reported += 1
        current = {error.code for error in errors}
        for code in sorted(previous - current):
            self._log("base", f"health: 0x{code:08X} cleared")
        if self._telemetry.health != HealthState(flags, errors):
            self._telemetry.health = HealthState(flags, errors)
            self._changed.add("health")

    # ============================================================================== actions

    def _act_on(self, code: int) -> None:
        """What the Core does with an external command it has acknowledged (§11.5)."""
        config = self.config
        name = command_name(code)
        if code == ExternalCommand.CANCEL_ACTION:
            self._cancel_action("cancelled by CANCEL_ACTION")
            self._vx = self._omega = 0.0
            self._changed.add("command")
            return
        action: Action
        if code == ExternalCommand.MOVE_FORWARD:
            action = DriveDistance(config.move_distance_m, config.move_speed_mps)
        elif code == ExternalCommand.MOVE_BACKWARD:
            action = DriveDistance(-config.move_distance_m, config.move_speed_mps)
        elif code == ExternalCommand.TURN_LEFT:
            action = TurnAngle(config.turn_angle_deg, config.turn_rate_radps)
        elif code == ExternalCommand.TURN_RIGHT:
            action = TurnAngle(-config.turn_angle_deg, config.turn_rate_radps)
        elif code == ExternalCommand.GO_HOME:
            action = GoHome(config.docking)
        else:
            self._log("core", f"{name} (0x{code:02X}) noted; the Core emulator has nothing to do for it")
            return
        self._start_action(action, f"external command {name}")

    def _start_action(self, action: Action, why: str) -> None:
        if self._estop:
            self._log("core", f"{action.description} refused: the emergency stop is latched")
            return
        if self._state is not ConnectionState.CONNECTED:
            self._log("core", f"{action.description} refused: the base is not connected")
            return
        self._cancel_action(f"replaced by {action.description}")
        self._action = action
        if isinstance(action, GoHome):
            self._next_due.pop("status", None)  # polled faster while docking: from now on
        self._vx = self._omega = 0.0
        self._log("core", f"{action.description}: started ({why})")
        self._changed.add("command")

    def _cancel_action(self, why: str) -> None:
        action = self._action
        if action is not None:
            self._action = None
            action.finish(f"{action.description}: {why}", failed=True)
            self._last_outcome = action.outcome
            self._log("core", action.outcome or why)
            self._changed.add("command")

    def _check_action(self) -> None:
        action = self._action
        if action is not None and action.finished:
            self._end_action(action)

    def _end_action(self, action: Action) -> None:
        if self._action is action:
            self._action = None
            self._vx = self._omega = 0.0
            self._last_outcome = action.outcome
            self._log("core", action.outcome or f"{action.description}: done")
            self._changed.add("command")

    def _command_state(self) -> CommandState:
        action = self._action
        if self._estop:
            mode = "estop"
        elif action is not None:
            mode = action.mode
        elif self._vx or self._omega:
            mode = "teleop"
        else:
            mode = "idle"
        return CommandState(
            self._vx, self._omega, self._estop, mode, None if action is None else action.activity
        )

    # ====================================================================== events, notify

    def _log(self, direction: str, text: str) -> None:
        event = self._events.add(self._elapsed(self._now), direction, text)
        self._changed.add("events")
        log.debug("%s %.3f %s", direction, event.t_s, text)

    def _notify(self) -> None:
        if not self._changed:
            return
        topics = sorted(self._changed)
        self._changed.clear()
        subscribers = list(self._subscribers)
        for topic in topics:
            for callback in subscribers:
                try:
                    callback(topic)
                except Exception:  # a subscriber's bug must not stop the Core
                    log.exception("a Core subscriber failed on %r", topic)
